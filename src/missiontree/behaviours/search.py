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
- The approach and the confirmation: the shared subtree ``trees/subtrees/approach_confirm.yaml``,
  one node a step (:mod:`~missiontree.behaviours.approach_steps`: PlanStandoff, DriveToStandoff,
  FaceTarget; :mod:`~missiontree.behaviours.confirm_steps`: PlaceByDepth, LookFor, ConfirmTarget): a
  standoff pose facing the candidate, placed by the depth image, the detection where it is shown to
  the vision-language model (the rest of the frame painted out). A wrong candidate is marked
  (``search_rejected`` and doubtful in the semantic map) and the subtree fails, so the tree goes on.
- :class:`Approach` and :class:`Verify` are the report's own approach (fixed steps toward the
  detection, distance from the box's area: d = 3.0 * (1 - A_box / A_frame)) and verification (the
  whole frame asked about), kept as the reference ours is measured against.

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

from typing import Annotated, Literal

from pydantic import BaseModel, Field

from missiontree.behaviours.search_approach import Approach
from missiontree.behaviours.search_common import await_frame, read_target
from missiontree.behaviours.search_locate import Locate, PriorPlanner, ResumeExplore
from missiontree.behaviours.search_scan import ColourAttention, ScanRotate
from missiontree.engine.leaf import Leaf, Status
from missiontree.engine.ports import Output
from missiontree.reasoning.calls import CallStatus, ModelCall, model_caller
from missiontree.reasoning.prompts import crop_match_prompt
from missiontree.reasoning.schemas import CropMatch
from missiontree.reasoning.search_priors import Target
from missiontree.types import RGBDFrame

__all__ = ["Approach", "ColourAttention", "Locate", "PriorPlanner", "ResumeExplore", "ScanRotate", "Verify"]


class Verify(Leaf):
    """The report's verification: the vision-language model is asked about the whole frame.

    Up to ``frames`` frames; SUCCESS: ``object_found``. Ours asks about the detection where the
    candidate is only (``LookFor`` and ``ConfirmTarget`` in ``trees/subtrees/approach_confirm.yaml``),
    so that nothing else in view can answer for it.
    """

    class Params(BaseModel):
        target: str = Field(description="What must be confirmed ('red backpack').")
        mode: Literal["frame"] = Field("frame", description="frame: the whole frame (the report; only mode).")
        frames: int = Field(3, ge=1, le=10, description="Frames to look at before failing.")
        found: Annotated[str, Output("the object found: label", type="dict")] = "search_found"

    params: Params

    def __init__(self, name: str, params: BaseModel | None = None) -> None:
        super().__init__(name, params)
        self.goal: Target | None = None
        self.call: ModelCall | None = None
        self.frame: RGBDFrame | None = None
        self.looks = 0
        self.started = 0.0

    def on_setup(self) -> None:
        """Read the target against the detector's classes."""
        if self.ctx is not None:
            self.goal = read_target(self.ctx, self.params.target)

    def initialise(self) -> None:
        """Wait for a frame newer than now."""
        self.call = None
        self.looks = 0
        self.started = self.context.robot.now()

    def update(self) -> Status:
        """Frame -> vision-language model, up to ``frames`` looks."""
        if self.goal is None:
            return self.fail("no target to verify")
        if self.call is None:
            frame, late = await_frame(self.context.robot, self.started)
            if frame is None:
                return self.fail(late) if late else self.running("waiting for a fresh frame")
            self.frame = frame
            self.looks += 1
            self.call = model_caller(self.context).ask(
                "vlm", [frame.color], crop_match_prompt(self.goal.wanted), CropMatch, node=self.name)
        status = self.call.status()
        if not status.done:
            return self.running(f"asking the vision-language model: is it a {self.goal.wanted}?")
        call, self.call = self.call, None
        if status is not CallStatus.SUCCEEDED:
            return self._again(f"the model failed: {call.error()}")
        verdict: CropMatch = call.result().value
        if not verdict.matches:
            wanted = self.goal.wanted
            return self._again(f"the vision-language model does not see a {wanted}: {verdict.reason}")
        found = {"id": "", "label": self.goal.label, "x": None, "y": None, "distance": None,
                 "bearing_deg": None}
        self.write("found", found)
        self.emit("object_found", target=self.goal.text, reason=verdict.reason, confidence=verdict.confidence,
                  **found)
        return self.succeed(f"found the {self.goal.text}: {verdict.reason}")

    def _again(self, why: str) -> Status:
        assert self.frame is not None and self.goal is not None
        if self.looks < self.params.frames:
            self.started = self.frame.stamp
            return self.running(f"look {self.looks + 1} of {self.params.frames} ({why})")
        return self.fail(f"not the {self.goal.text}: {why} (in {self.looks} frames)")
