"""The looks at a candidate as steps a tree sequences: place it by depth, look for it, confirm it.

- :class:`PlaceByDepth`: at the standoff pose the detector finds the candidate's class where it is
  believed and the depth image places it; a candidate more than ``refine_distance`` from its belief
  (or one the robot stands beyond ``reach`` of) asks the approach for another step.
- :class:`LookFor`: a fresh frame, the detector on it, the detection of the target's class where the
  candidate is (bearing and depth); the region around it (``grow`` of the box a side, the rest painted
  out) is written to ``sighting``. With ``check_view``, a candidate no look can confirm (a class the
  detector does not know, or above the camera's view) is passed on unconfirmed when the candidate
  allows it (its ``unchecked`` is empty) and rejected otherwise, with why.
- :class:`ConfirmTarget`: the vision-language model is asked whether the sighting is the target ("red
  backpack"); yes: ``object_found`` and the ``found`` key (``confirmed`` true). An unconfirmable
  sighting is written to ``found`` with ``confirmed`` false and why.

The target is the ``target`` phrase, or when it is empty the candidate's own ``label`` and ``wanted``
(what a look must see: "grey backpack"), as the intent's candidates carry them.

``LookFor`` and ``ConfirmTarget`` share the blackboard list ``looks`` (the subtree empties it first):
one entry per look that did not confirm (the frame's ``stamp`` and ``why``). The next look waits for a
frame newer than the last; after ``frames`` looks the candidate is rejected (``wrong``, doubtful in the
semantic map) -- or, while ``viewpoints`` are left, the place looked from is added to the approach's
``tries`` as not good to look from (``looked``) and the looks end, so that the subtree approaches
another place and looks again. An entry with ``stop`` (no camera frame) ends the looks whatever the
``Retry`` has left; a rejection also ends the approach (``stop`` in ``tries``).

Tick-log events: ``object_found``, ``object_unverifiable``, ``candidate_rejected``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Annotated, Any

from pydantic import BaseModel, Field

from missiontree.behaviours.approach_steps import ApproachStep
from missiontree.behaviours.search_common import await_frame, mark_rejected, read_target
from missiontree.engine.leaf import Leaf, Status
from missiontree.engine.ports import Input, Output
from missiontree.perception.detectors import detection_job
from missiontree.perception.projection import project
from missiontree.reasoning.calls import CallStatus, ModelCall, model_caller
from missiontree.reasoning.intent import look_crop, match_detection
from missiontree.reasoning.phrases import fold_label
from missiontree.reasoning.prompts import crop_match_prompt
from missiontree.reasoning.schemas import CropMatch
from missiontree.reasoning.search_priors import Target
from missiontree.types import Detection, RGBDFrame


def unverifiable(detector: Any, frame: RGBDFrame, cand: dict[str, Any]) -> str:
    """Why no look from here can confirm ``cand`` ("" when one can): an unknown class, or above the view."""
    label = str(cand.get("label", ""))
    known = [fold_label(str(x)) for x in (getattr(detector, "labels", None) or [])]
    if known and fold_label(label) not in known:
        return f"the detector knows no {label}"
    z = float(cand.get("z", 0.0) or 0.0)
    cam = frame.camera_pose
    distance = math.hypot(cand["x"] - cam.x, cand["y"] - cam.y)
    top = frame.camera_height + distance * frame.intrinsics.cy / frame.intrinsics.fy
    if z > top:
        return f"the {label} is {z:.2f} m up, above what the camera sees from {distance:.1f} m ({top:.2f} m)"
    return ""


def detect(leaf: Leaf, frame: RGBDFrame) -> ModelCall:
    """The detector on ``frame``, on the model workers (a success is not logged: one a frame)."""
    return model_caller(leaf.context).submit(
        "detector", detection_job(leaf.context.model("detector"), frame), node=leaf.name, log_success=False
    )


def frame_or_wait(leaf: Leaf, after: float, key: str, entries: Callable[[], list[Any]]) -> RGBDFrame | Status:
    """A camera frame newer than ``after``, or what the step returns while there is none.

    RUNNING while one may still come; FAILURE once it is late, the stop appended to ``entries()``
    and written under the leaf's ``key`` (its tries or its looks), so the next step fails too.
    """
    frame, late = await_frame(leaf.context.robot, after)
    if frame is not None:
        return frame
    if not late:
        return leaf.running("waiting for a fresh frame")
    leaf.write(key, [*entries(), {"stop": late}])
    return leaf.fail(late)


class PlaceByDepth(ApproachStep):
    """The depth image places the candidate; far from its belief, another approach step is asked for.

    FAILURE (another step) while attempts are left and the object stands more than
    ``refine_distance`` from the belief or the robot beyond ``reach`` of it; SUCCESS otherwise (also
    when the detector does not see it here: the confirmation decides).
    """

    class Params(ApproachStep.Params):
        refine_distance: float = Field(
            0.35, gt=0,
            description="Step again when the depth image puts the object this far from the belief (m).")
        reach: float = Field(1.0, gt=0, description="Step again when the robot stands farther than this (m).")
        min_score: float = Field(0.5, ge=0, le=1, description="Detector confidence filter.")
        refine: bool = Field(
            True, description="Place the candidate by the depth image; false: its place is taken as it is "
            "(a scene graph's object) and this step only says so.")
        candidate: Annotated[str, Output("the candidate, its place refined by depth", type="dict")] = (
            "search_candidate")

    params: Params

    def __init__(self, name: str, params: BaseModel | None = None) -> None:
        super().__init__(name, params)
        self.call: ModelCall | None = None
        self.frame: RGBDFrame | None = None
        self.started = 0.0

    def initialise(self) -> None:
        """Wait for a frame newer than now."""
        super().initialise()
        self.call = None
        self.frame = None
        self.started = self.context.robot.now()

    def update(self) -> Status:
        """Frame -> detector -> depth."""
        if self.cand is None:
            return self.fail("no candidate to place (run Locate first)")
        if self.stopped():
            return self.fail(self.stopped())
        if not self.params.refine:
            return self.succeed(f"facing {self.cand['id']} (its place taken as it is: refine is off)")
        if self.call is None:
            frame = frame_or_wait(self, self.started, "tries", self.tries)
            if isinstance(frame, Status):
                return frame
            self.frame = frame
            self.call = detect(self, frame)
        status = self.call.status()
        if not status.done:
            return self.running("looking with the detector")
        call, self.call = self.call, None
        detections: list[Detection] = call.result() if status is CallStatus.SUCCEEDED else []
        return self._placed(detections)

    def _placed(self, detections: list[Detection]) -> Status:
        assert self.cand is not None and self.frame is not None
        c = self.cand
        found, why = match_detection(detections, str(c["label"]), self.frame, (c["x"], c["y"]),
                                     min_score=self.params.min_score)
        where = project(self.frame, found, method="robust") if found is not None else None
        if where is None:
            return self.succeed(f"facing {c['id']} at its standoff pose (not placed by depth: "
                                f"{why or 'no depth in its box'})")
        moved = math.hypot(where.xy[0] - c["x"], where.xy[1] - c["y"])
        c.update(x=round(where.xy[0], 3), y=round(where.xy[1], 3), z=round(where.position[2], 3))
        self.write("candidate", dict(c))
        if len(self.tries()) < self.params.max_attempts:
            if moved > self.params.refine_distance:
                return self.fail(f"the depth image puts it {moved:.2f} m from the belief: another step")
            stamped = self.context.robot.pose()
            away = math.hypot(stamped.pose.x - c["x"], stamped.pose.y - c["y"]) if stamped else math.inf
            if away > self.params.reach:
                return self.fail(f"beyond reach ({self.params.reach:g} m) of it: another step")
        return self.succeed(f"facing {c['id']} at {where.range:.2f} m (depth image)")

    def terminate(self, new_status: Status) -> None:
        """Cancel the detector call in flight."""
        if self.call is not None:
            self.call.cancel()
            self.call = None


class LookStep(Leaf):
    """What the looks share: the target read against the detector, the candidate, the looks so far."""

    class Params(BaseModel):
        target: str = Field("", description="What must be confirmed ('red backpack'); empty: the "
                            "candidate's `wanted` (or `label`).")
        frames: int = Field(3, ge=1, le=10, description="Looks (frames) before the candidate is rejected.")
        viewpoints: int = Field(1, ge=1, le=5, description="Places looked from before the candidate is "
                                "rejected (the subtree approaches another after each).")
        candidate: Annotated[str, Input("the candidate looked at: id, label, x, y (wanted, unchecked)",
                                        type="dict")] = "search_candidate"
        standoff: Annotated[str, Input("the standoff pose looked from", type="dict")] = "standoff"
        looks: Annotated[str, Output("this candidate's looks that did not confirm it (the subtree empties "
                                     "it first)", type="list[dict]")] = "looks"
        tries: Annotated[str, Output("the approach's standoff poses (a place looked from is added)",
                                     type="list[dict]")] = "approach_tries"
        rejected: Annotated[str, Output("candidates rejected so far", type="list")] = "search_rejected"

    params: Params

    def __init__(self, name: str, params: BaseModel | None = None) -> None:
        super().__init__(name, params)
        self.given: Target | None = None
        self.goal: Target | None = None
        self.wanted = ""
        self.cand: dict[str, Any] | None = None
        self.call: ModelCall | None = None

    def on_setup(self) -> None:
        """Read the target against the detector's classes."""
        if self.ctx is not None and self.params.target:
            self.given = read_target(self.ctx, self.params.target)

    def initialise(self) -> None:
        """Take the candidate, and the target from it when none is given."""
        value = self.read("candidate")
        self.cand = dict(value) if isinstance(value, dict) else None
        self.call = None
        self.goal, self.wanted = self.given, self.given.wanted if self.given is not None else ""
        if self.given is None and self.cand is not None and self.cand.get("label"):
            label = str(self.cand["label"])
            self.wanted = str(self.cand.get("wanted") or label)
            self.goal = Target(text=self.wanted, label=label)

    def looks(self) -> list[dict[str, Any]]:
        """The looks at this candidate that did not confirm it."""
        return self.read_entries("looks")

    def early_exit(self) -> Status | None:
        """FAILURE when there is nothing (more) to look at."""
        if self.goal is None:
            return self.fail("no target to verify")
        if self.cand is None:
            return self.fail("no candidate to verify (run Locate and Approach first)")
        looks = self.looks()
        if looks and looks[-1].get("stop"):
            return self.fail(str(looks[-1]["stop"]))
        return None

    def again(self, why: str, stamp: float, last: bool = False) -> Status:
        """A look that did not confirm it: another look, another place after the last one, or a rejection.

        ``last``: rejected now, whatever looks and places are left.
        """
        looks = [*self.looks(), {"stamp": stamp, "why": why}]
        if len(looks) < self.params.frames and not last:
            self.write("looks", looks)
            return self.fail(f"look {len(looks)} of {self.params.frames}: {why}")
        reason = f"{why} (in {len(looks)} frames)"
        tries = self.read_entries("tries")
        looked = [t for t in tries if t.get("looked")]
        standoff = self.read("standoff")
        if len(looked) + 1 < self.params.viewpoints and not last and isinstance(standoff, dict):
            place = {k: standoff[k] for k in ("x", "y", "yaw")}
            self.write("tries", [*tries, {**place, "reached": False, "why": reason, "looked": True}])
            self.write("looks", [*looks, {"stop": reason}])
            return self.fail(f"not confirmed from here: {reason}; looking from another place")
        if looked:
            reason = f"{looked[0]['why']}; again from a second place: {reason}"
        assert self.cand is not None
        mark_rejected(self, self.cand, reason)
        why = f"not the {self.goal.text if self.goal else 'target'}: {reason}"
        self.write("looks", [*looks, {"stop": why}])
        self.write("tries", [*tries, {"stop": why}])
        return self.fail(why)

    def terminate(self, new_status: Status) -> None:
        """Cancel the call in flight."""
        if self.call is not None:
            self.call.cancel()
            self.call = None


class LookFor(LookStep):
    """A fresh frame, the detector, the target's class where the candidate is: its region to ``sighting``."""

    class Params(LookStep.Params):
        min_score: float = Field(0.5, ge=0, le=1, description="Detector confidence for the look.")
        check_view: bool = Field(
            False, description="Check first that a look can confirm the candidate (the detector knows its "
            "class, it is within the camera's view); when not, pass it on unconfirmed if its `unchecked` is "
            "empty, else reject it saying why.")
        grow: float = Field(1.0, ge=0, description="Share of the box shown around the detection, a side.")
        sighting: Annotated[str, Output("the detection looked at: id, box, stamp and the region around it",
                                        type="dict")] = "sighting"

    params: Params

    def __init__(self, name: str, params: BaseModel | None = None) -> None:
        super().__init__(name, params)
        self.frame: RGBDFrame | None = None
        self.after = 0.0

    def initialise(self) -> None:
        """Wait for a frame newer than the last look's (now, at the first look)."""
        super().initialise()
        self.frame = None
        looks = self.looks()
        self.after = float(looks[-1].get("stamp", 0.0)) if looks else self.context.robot.now()

    def update(self) -> Status:
        """Frame -> detector -> the detection where the candidate is."""
        early = self.early_exit()
        if early is not None:
            return early
        if self.call is None:
            frame = frame_or_wait(self, self.after, "looks", self.looks)
            if isinstance(frame, Status):
                return frame
            self.frame = frame
            unseen = self._unverifiable(frame)
            if unseen:
                return unseen
            self.call = detect(self, frame)
        status = self.call.status()
        if not status.done:
            return self.running("looking with the detector")
        call, self.call = self.call, None
        assert self.frame is not None and self.goal is not None and self.cand is not None
        if status is not CallStatus.SUCCEEDED:
            return self.again(f"the detector failed: {call.error()}", self.frame.stamp)
        found, why = match_detection(call.result(), self.goal.label, self.frame,
                                     (self.cand["x"], self.cand["y"]), min_score=self.params.min_score)
        if found is None:
            return self.again(why, self.frame.stamp)
        crop = look_crop(self.frame.color, found.box, grow=self.params.grow)
        self.write("sighting", {"id": self.cand.get("id"), "label": found.label, "score": found.score,
                                "box": list(found.box), "stamp": self.frame.stamp, "region": crop})
        return self.succeed(f"a {found.label} where {self.cand.get('id')} is (score {found.score:.2f})")

    def _unverifiable(self, frame: RGBDFrame) -> Status | None:
        """With ``check_view``: passed on unconfirmed, or rejected, when no look can confirm it."""
        assert self.cand is not None
        if not self.params.check_view:
            return None
        unseen = unverifiable(self.context.model("detector"), frame, self.cand)
        if not unseen:
            return None
        refused = str(self.cand.get("unchecked", "") or "")
        if refused:
            return self.again(f"{unseen}, and {refused}", frame.stamp, last=True)
        self.write("sighting", {"id": self.cand.get("id"), "label": self.cand.get("label"),
                                "stamp": frame.stamp, "unverifiable": unseen})
        self.emit("object_unverifiable", object=self.cand.get("id"), reason=unseen,
                  **({"command": self.cand["command"]} if "command" in self.cand else {}))
        return self.succeed(f"nothing here can confirm {self.cand.get('id')}: {unseen}")


class ConfirmTarget(LookStep):
    """The vision-language model confirms the target on the sighting's region; SUCCESS: ``object_found``."""

    class Params(LookStep.Params):
        max_distance: float = Field(
            0.0, ge=0,
            description="Reject when the robot ends farther than this from the object (m); 0: no limit.")
        sighting: Annotated[str, Input("the detection to confirm (LookFor)", type="dict")] = "sighting"
        found: Annotated[str, Output("the object found: id, label, x, y", type="dict")] = "search_found"

    params: Params

    def __init__(self, name: str, params: BaseModel | None = None) -> None:
        super().__init__(name, params)
        self.stamp = 0.0

    def update(self) -> Status:
        """Ask, then read the verdict."""
        early = self.early_exit()
        if early is not None:
            return early
        assert self.goal is not None
        if self.call is None:
            sighting = self.read("sighting")
            if isinstance(sighting, dict) and sighting.get("unverifiable"):
                return self._found(None, f"not confirmed: {sighting['unverifiable']}")
            if not isinstance(sighting, dict) or sighting.get("region") is None:
                return self.fail("nothing to confirm (run LookFor first)")
            self.stamp = float(sighting.get("stamp", 0.0))
            self.call = model_caller(self.context).ask(
                "vlm", [sighting["region"]], crop_match_prompt(self.wanted), CropMatch, node=self.name)
        status = self.call.status()
        if not status.done:
            return self.running(f"asking the vision-language model: is it a {self.wanted}?")
        call, self.call = self.call, None
        if status is not CallStatus.SUCCEEDED:
            return self.again(f"the model failed: {call.error()}", self.stamp)
        verdict: CropMatch = call.result().value
        if not verdict.matches:
            return self.again(f"the vision-language model does not see a {self.wanted}: {verdict.reason}",
                              self.stamp)
        return self._found(verdict, f"a {self.wanted} seen ({verdict.reason})")

    def _found(self, verdict: CropMatch | None, note: str) -> Status:
        assert self.goal is not None and self.cand is not None
        stamped = self.context.robot.pose()
        cand = self.cand
        distance = bearing = math.nan
        if stamped is not None and "x" in cand:
            distance = math.hypot(cand["x"] - stamped.pose.x, cand["y"] - stamped.pose.y)
            bearing = stamped.pose.bearing_to(cand["x"], cand["y"])
        if self.params.max_distance and distance > self.params.max_distance:
            limit = self.params.max_distance
            why = f"confirmed, but {distance:.2f} m away (more than {limit:g} m)"
            return self.again(why, self.stamp, last=True)
        found = {
            "id": cand.get("id", ""),
            "label": self.goal.label,
            "x": cand.get("x"),
            "y": cand.get("y"),
            "distance": round(distance, 3) if math.isfinite(distance) else None,
            "bearing_deg": round(math.degrees(bearing), 1) if math.isfinite(bearing) else None,
            "confirmed": verdict is not None,
            "note": note,
        }
        self.write("found", found)
        where = f" at {distance:.2f} m" if math.isfinite(distance) else ""
        if verdict is None:
            return self.succeed(f"at {found['id']}{where}, {note}")
        self.emit("object_found", target=self.goal.text, reason=verdict.reason, confidence=verdict.confidence,
                  **found)
        return self.succeed(f"found the {self.goal.text}{where}: {verdict.reason}")
