"""Object search: scan, colour attention, locate, approach, verify (the object-search report, working).

The vision-language object-search report searches with a state machine IDLE -> MOVING_TO_SCAN ->
SCANNING -> APPROACHING -> VERIFYING -> DONE. Here each state is a leaf a tree composes:

- :class:`ScanRotate`: a full turn in steps with a pause and a fresh camera frame (a look) at each;
  the angle is integrated from the heading's change, so it really turns 360 degrees.
- :class:`ColourAttention`: the report's HSV colour mapper (the target's colour -> HSV class of
  :mod:`missiontree.perception.colour`, present when >= 1 % of the pixels match, the mask's
  centroid -> left / centre / right); with ``wait`` it stays RUNNING until the colour shows, so it
  can interrupt a scan (a Parallel).
- :class:`Locate`: a candidate of the target from what is known — the live semantic map that
  ``BuildSceneGraph`` fuses every frame into (a candidate seen once is not forgotten when the robot
  turns away) or a loaded scene graph — else exploration (the ``Explore`` leaf's frontiers) ordered
  by where the target is likely (:mod:`missiontree.reasoning.search_priors`: a cup -> kitchen first)
  and by the frontiers' gain, then going to look at the reachable floor the camera has not seen
  (:mod:`~missiontree.behaviours.search_coverage`), until a candidate appears. FAILURE "not found"
  when the reachable space is explored and looked at and no candidate is left.
- :class:`Approach`: to a standoff pose facing the candidate (the intent leaf's standoff search on
  the learned map), then a look that measures the object's place from the depth image; when it is
  elsewhere than believed, another step (bounded attempts). ``mode: box_area`` is the report's
  approach: fixed steps toward the detection's bearing, distance from the box's area
  (d = 3.0 * (1 - A_box / A_frame)).
- :class:`Verify`: the vision-language model confirms label and attributes on a close frame (the
  detection where the candidate is, the rest of the frame painted out); the offline stand-in
  measures colour in HSV. A wrong candidate is marked (``search_rejected`` and doubtful in the
  semantic map) and the leaf fails, so the tree goes on searching. ``mode: frame`` is the report's
  verification: the whole frame asked about.

The leaves live in modules of one concept each: :mod:`~missiontree.behaviours.search_scan`
(ScanRotate, ColourAttention), :mod:`~missiontree.behaviours.search_locate` (ResumeExplore, Locate;
what the camera looked at in :mod:`~missiontree.behaviours.search_coverage`),
:mod:`~missiontree.behaviours.search_approach` (Approach), this module (Verify) and
:mod:`~missiontree.behaviours.search_common` (what they share: the target, frames, rejected
candidates). All are importable from here.

Tick-log events: ``scan_look``, ``colour_attention``, ``search_candidate``, ``search_explored``,
``search_view_goal``, ``search_view_given_up``, ``search_covered``, ``search_frontiers_again``,
``explore_retry``, ``approach_step``, ``object_found``, ``candidate_rejected``.
"""

from __future__ import annotations

import math
from typing import Annotated, Any, Literal

from pydantic import BaseModel, Field

from missiontree.behaviours.search_approach import Approach
from missiontree.behaviours.search_common import await_frame, mark_rejected, read_target
from missiontree.behaviours.search_locate import Locate, PriorPlanner, ResumeExplore
from missiontree.behaviours.search_scan import ColourAttention, ScanRotate
from missiontree.engine.leaf import Leaf, Status
from missiontree.engine.ports import Input, Output
from missiontree.perception.detectors import detection_job
from missiontree.reasoning.calls import CallStatus, ModelCall, model_caller
from missiontree.reasoning.intent import look_crop, match_detection
from missiontree.reasoning.prompts import crop_match_prompt
from missiontree.reasoning.schemas import CropMatch
from missiontree.reasoning.search_priors import Target
from missiontree.types import Detection, RGBDFrame

__all__ = ["Approach", "ColourAttention", "Locate", "PriorPlanner", "ResumeExplore", "ScanRotate", "Verify"]


class Verify(Leaf):
    """The vision-language model confirms the target's class and attributes on a close frame.

    ``mode: crop`` (ours): the detector must see the class where the candidate is (bearing and
    depth), and the model is shown that detection with the rest of the frame painted out, asked
    whether it is the target ("red backpack"); up to ``frames`` frames. ``mode: frame`` (the
    report's verification): the whole frame is asked about. SUCCESS: ``object_found``. A wrong
    candidate is rejected (``search_rejected``, doubtful in the semantic map) and the leaf fails.
    """

    class Params(BaseModel):
        target: str = Field(description="What must be confirmed ('red backpack').")
        mode: Literal["crop", "frame"] = Field(
            "crop",
            description="crop: the detection where the candidate is; frame: the whole frame (the report).",
        )
        frames: int = Field(3, ge=1, le=10, description="Frames to look at before rejecting.")
        min_score: float = Field(0.5, ge=0, le=1, description="Detector confidence for the look.")
        grow: float = Field(
            1.0, ge=0, description="crop: share of the box shown around the detection, a side."
        )
        max_distance: float = Field(
            0.0,
            ge=0,
            description="Reject when the robot ends farther than this from the object (m); 0: no limit.",
        )
        candidate: Annotated[str, Input("the candidate to verify", type="dict")] = "search_candidate"
        rejected: Annotated[str, Output("candidates rejected so far", type="list")] = "search_rejected"
        found: Annotated[str, Output("the object found: id, label, x, y", type="dict")] = "search_found"

    params: Params

    def __init__(self, name: str, params: BaseModel | None = None) -> None:
        super().__init__(name, params)
        self.goal: Target | None = None
        self.cand: dict[str, Any] | None = None
        self.call: ModelCall | None = None
        self.frame: RGBDFrame | None = None
        self.stage = "frame"
        self.looks = 0
        self.started = 0.0
        self.why = ""

    def on_setup(self) -> None:
        """Read the target against the detector's classes."""
        if self.ctx is not None:
            self.goal = read_target(self.ctx, self.params.target)

    def initialise(self) -> None:
        """Take the candidate; wait for a frame newer than now."""
        value = self.read("candidate") if self.params.mode == "crop" else None
        self.cand = dict(value) if isinstance(value, dict) else None
        self.call = None
        self.stage = "frame"
        self.looks = 0
        self.why = ""
        self.started = self.context.robot.now()

    def update(self) -> Status:
        """Frame -> detector -> vision-language model, up to ``frames`` looks."""
        if self.goal is None:
            return self.fail("no target to verify")
        if self.params.mode == "crop" and self.cand is None:
            return self.fail("no candidate to verify (run Locate and Approach first)")
        if self.stage == "frame":
            return self._framed()
        assert self.call is not None
        status = self.call.status()
        if not status.done:
            return self.running(f"{'detecting' if self.stage == 'detect' else 'asking the model'}")
        call, self.call = self.call, None
        if status is not CallStatus.SUCCEEDED:
            return self._again(
                f"the {'detector' if self.stage == 'detect' else 'model'} failed: {call.error()}"
            )
        if self.stage == "detect":
            return self._ask(call.result())
        verdict: CropMatch = call.result().value
        if not verdict.matches:
            return self._again(
                f"the vision-language model does not see a {self.goal.wanted}: {verdict.reason}"
            )
        return self._confirmed(verdict)

    def terminate(self, new_status: Status) -> None:
        """Cancel the call in flight."""
        if self.call is not None:
            self.call.cancel()
            self.call = None

    def _framed(self) -> Status:
        frame, late = await_frame(self.context.robot, self.started)
        if frame is None:
            return self.fail(late) if late else self.running("waiting for a fresh frame")
        self.frame = frame
        self.looks += 1
        if self.params.mode == "frame":
            return self._ask(None)
        self.call = model_caller(self.context).submit(
            "detector",
            detection_job(self.context.model("detector"), frame),
            node=self.name,
            log_success=False,
        )
        self.stage = "detect"
        return self.running("detecting")

    def _ask(self, detections: list[Detection] | None) -> Status:
        assert self.frame is not None and self.goal is not None
        image = self.frame.color
        if detections is not None:
            assert self.cand is not None
            found, why = match_detection(
                detections,
                self.goal.label,
                self.frame,
                (self.cand["x"], self.cand["y"]),
                min_score=self.params.min_score,
            )
            if found is None:
                return self._again(why)
            image = look_crop(self.frame.color, found.box, grow=self.params.grow)
        self.call = model_caller(self.context).ask(
            "vlm", [image], crop_match_prompt(self.goal.wanted), CropMatch, node=self.name
        )
        self.stage = "ask"
        return self.running(f"asking the vision-language model: is it a {self.goal.wanted}?")

    def _again(self, why: str) -> Status:
        self.why = why
        if self.looks < self.params.frames:
            assert self.frame is not None
            self.started = self.frame.stamp
            self.stage = "frame"
            return self.running(f"look {self.looks + 1} of {self.params.frames} ({why})")
        reason = f"{why} (in {self.looks} frames)"
        if self.cand is not None:
            mark_rejected(self, self.cand, reason)
        return self.fail(f"not the {self.goal.text if self.goal else 'target'}: {reason}")

    def _confirmed(self, verdict: CropMatch) -> Status:
        assert self.goal is not None
        robot = self.context.robot
        stamped = robot.pose()
        cand = self.cand or {}
        distance = bearing = math.nan
        if stamped is not None and "x" in cand:
            distance = math.hypot(cand["x"] - stamped.pose.x, cand["y"] - stamped.pose.y)
            bearing = stamped.pose.bearing_to(cand["x"], cand["y"])
        if self.params.max_distance and distance > self.params.max_distance:
            self.looks = self.params.frames
            return self._again(
                f"confirmed, but {distance:.2f} m away (more than {self.params.max_distance:g} m)"
            )
        found = {
            "id": cand.get("id", ""),
            "label": self.goal.label,
            "x": cand.get("x"),
            "y": cand.get("y"),
            "distance": round(distance, 3) if math.isfinite(distance) else None,
            "bearing_deg": round(math.degrees(bearing), 1) if math.isfinite(bearing) else None,
        }
        self.write("found", found)
        self.emit(
            "object_found",
            target=self.goal.text,
            reason=verdict.reason,
            confidence=verdict.confidence,
            **found,
        )
        where = f" at {distance:.2f} m" if math.isfinite(distance) else ""
        return self.succeed(f"found the {self.goal.text}{where}: {verdict.reason}")
