"""What the search leaves share: the target read against the detector, fresh frames, rejected candidates.

The leaves of the object search (:mod:`missiontree.behaviours.search`) hand a candidate on through the
blackboard (``search_candidate``) and keep the candidates ruled out in ``search_rejected``: a list of
``{id, label, x, y, reason, kind}``. ``kind`` says why:

- ``wrong``: looked at and not the target (Verify); its class is ruled out within
  :data:`REJECT_RADIUS` of it for the rest of the mission, and the instance is marked doubtful in
  the semantic map.
- ``unreached``: no standoff pose of it could be reached (Approach). It says nothing about the
  object, so ``Locate`` offers it once more when the map has grown (nothing left to explore, or the
  map around it changed); the instance is not doubted.
"""

from __future__ import annotations

from typing import Any, Literal

from missiontree.engine.leaf import Leaf
from missiontree.reasoning.search_priors import Target, parse_target
from missiontree.types import RGBDFrame

#: A rejected candidate rules out instances of its class this close to where it was (m).
REJECT_RADIUS = 0.5
#: Seconds to wait for a camera frame newer than the moment a look began.
FRAME_TIMEOUT = 10.0

RejectKind = Literal["wrong", "unreached"]


def read_target(ctx: Any, text: str) -> Target:
    """The target phrase read against the detector's classes (any class when it lists none)."""
    labels = list(getattr(ctx.model("detector"), "labels", None) or []) if ctx is not None else []
    if not labels:
        words = text.split()
        return Target(text=text, label=words[-1] if words else text)
    return parse_target(text, labels)


def fresh_frame(robot: Any, after: float) -> RGBDFrame | None:
    """The robot's newest camera frame when it is newer than ``after``, else None."""
    frame = robot.rgbd()
    return frame if frame is not None and frame.stamp > after else None


def await_frame(robot: Any, after: float) -> tuple[RGBDFrame | None, str]:
    """A frame newer than ``after``, or None and why not yet: "" (wait on) or a reason to fail."""
    frame = fresh_frame(robot, after)
    if frame is None and robot.now() - after > FRAME_TIMEOUT:
        return None, f"no camera frame within {FRAME_TIMEOUT:g} s"
    return frame, ""


def rejected_entries(entries: Any) -> list[dict[str, Any]]:
    """The well-formed entries of a ``search_rejected`` value (anything else: none)."""
    return [e for e in entries if isinstance(e, dict)] if isinstance(entries, list) else []


def mark_rejected(leaf: Leaf, cand: dict[str, Any], reason: str, kind: RejectKind = "wrong") -> None:
    """Add a candidate to ``search_rejected``; a wrong one is also marked doubtful in the semantic map.

    ``leaf`` declares the ``rejected`` output port.
    """
    try:
        entries = rejected_entries(leaf.bb.get(leaf.params.rejected))  # type: ignore[attr-defined]
    except KeyError:
        entries = []
    entry = {
        "id": cand.get("id"),
        "label": cand.get("label"),
        "x": cand.get("x"),
        "y": cand.get("y"),
        "reason": reason,
        "kind": kind,
    }
    leaf.write("rejected", [*entries, entry])
    ctx = leaf.ctx
    instances = ctx.scene.map if ctx is not None and ctx.scene is not None else None
    # the Scene protocol's map is its reading side; the live semantic map also writes (update)
    update = getattr(instances, "update", None)
    oid = str(cand.get("id"))
    known = instances is not None and oid in instances
    if kind == "wrong" and ctx is not None and update is not None and known:
        update(oid, ctx.robot.now(), announce=True, reason=reason, doubtful=True)
    leaf.emit(
        "candidate_rejected",
        object=oid,
        label=cand.get("label"),
        x=cand.get("x"),
        y=cand.get("y"),
        reason=reason,
        kind=kind,
    )
