"""The vision-language object-search report's approach, kept as the reference our search is measured against.

The report's APPROACHING state moves in small steps toward the detection, its distance estimated from
the box's area (d = 3.0 * (1 - A_box / A_frame)), a bounded number of attempts; its verdict: "often
failing to reach precise target positions". Ours is the shared subtree
``trees/subtrees/approach_confirm.yaml`` (:mod:`~missiontree.behaviours.approach_steps`: a standoff
pose facing the candidate on the learned map, placed by the depth image), each step a node.

Tick-log events: ``approach_step``.
"""

from __future__ import annotations

import enum
import math
from typing import Annotated, Literal

from pydantic import BaseModel, Field

from missiontree.behaviours.confirm_steps import detect
from missiontree.behaviours.search_common import await_frame, read_target
from missiontree.engine.leaf import Leaf, Status
from missiontree.engine.ports import Input
from missiontree.reasoning.calls import CallStatus, ModelCall
from missiontree.reasoning.phrases import fold_label
from missiontree.reasoning.search_priors import Target
from missiontree.robot.actions import ActionHandle
from missiontree.types import Detection, Pose2D, RGBDFrame, Tolerance


class _Step(enum.Enum):
    DRIVE = "driving"
    FRAME = "waiting for a fresh frame"
    DETECT = "looking with the detector"


class Approach(Leaf):
    """The report's approach: fixed steps toward the detection, its distance from the box's area.

    Steps of ``step`` m toward the detection's (or, before any, the colour mapper's) bearing, the
    distance d = 3.0 * (1 - A_box / A_frame), until d is below ``stop_distance`` or ``max_attempts``
    steps are used up.
    """

    class Params(BaseModel):
        mode: Literal["box_area"] = Field("box_area", description="box_area: the report's steps (only mode).")
        target: str = Field(description="What is searched for (its class is detected).")
        max_attempts: int = Field(3, ge=1, description="Approach steps before stopping where it is.")
        step: float = Field(0.5, gt=0, description="Length of one approach step (m).")
        stop_distance: float = Field(0.8, gt=0, description="Stop when the estimated distance is below (m).")
        min_score: float = Field(0.5, ge=0, le=1, description="Detector confidence filter.")
        goal_timeout: float = Field(120.0, gt=0, description="Give up a step not reached in this many s.")
        colour_seen: Annotated[str, Input("the colour mapper's sighting", type="dict")] = "colour_attention"

    params: Params

    def __init__(self, name: str, params: BaseModel | None = None) -> None:
        super().__init__(name, params)
        self.goal: Target | None = None
        self.step = _Step.FRAME
        self.call: ModelCall | None = None
        self.handle: ActionHandle | None = None
        self.frame: RGBDFrame | None = None
        self.attempts = 0
        self.started = 0.0

    def on_setup(self) -> None:
        """Read the target against the detector's classes."""
        if self.ctx is not None:
            self.goal = read_target(self.ctx, self.params.target)

    def initialise(self) -> None:
        """Look first."""
        self.step = _Step.FRAME
        self.call = None
        self.handle = None
        self.attempts = 0
        self.started = self.context.robot.now()

    def update(self) -> Status:
        """Advance the current step; each returns at once."""
        if self.goal is None:
            return self.fail("the report's approach needs the target's class: set `target`")
        if self.step is _Step.DRIVE:
            return self._driven()
        if self.step is _Step.FRAME:
            return self._framed()
        assert self.call is not None
        status = self.call.status()
        if not status.done:
            return self.running(_Step.DETECT.value)
        call, self.call = self.call, None
        return self._box_step(call.result() if status is CallStatus.SUCCEEDED else [])

    def terminate(self, new_status: Status) -> None:
        """Cancel the model call and the goal in flight."""
        if self.call is not None:
            self.call.cancel()
            self.call = None
        if self.handle is not None:
            self.handle.cancel()
            self.handle = None

    def _driven(self) -> Status:
        assert self.handle is not None
        status = self.handle.status()
        if not status.done and self.context.robot.now() - self.started > self.params.goal_timeout:
            self.handle.cancel()
            return self._stepped(f"not reached within {self.params.goal_timeout:g} s")
        if not status.done:
            feedback = self.handle.feedback()
            left = f"{feedback.distance_remaining:.1f} m to go" if feedback is not None else status.value
            return self.running(f"approaching: {left}")
        return self._stepped(status.value)

    def _stepped(self, how: str) -> Status:
        self.handle = None
        self.step = _Step.FRAME
        self.started = self.context.robot.now()
        if self.attempts >= self.params.max_attempts:
            return self.succeed(f"approach steps used up ({self.attempts}); last: {how}")
        return self.running("looking again after a step")

    def _framed(self) -> Status:
        frame, late = await_frame(self.context.robot, self.started)
        if frame is None:
            return self.fail(late) if late else self.running(_Step.FRAME.value)
        self.frame = frame
        self.call = detect(self, frame)
        self.step = _Step.DETECT
        return self.running(_Step.DETECT.value)

    def _box_step(self, detections: list[Detection]) -> Status:
        assert self.frame is not None and self.goal is not None
        robot = self.context.robot
        frame = self.frame
        k = frame.intrinsics
        want = fold_label(self.goal.label)
        mine = [d for d in detections if fold_label(d.label) == want and d.score >= self.params.min_score]
        if mine:
            best = max(mine, key=lambda d: d.score)
            area = max(0.0, best.box[2] - best.box[0]) * max(0.0, best.box[3] - best.box[1])
            distance = 3.0 * (1.0 - area / float(k.width * k.height))
            bearing = k.pixel_bearing(best.center[0])
        else:
            seen = self.read("colour_seen")
            if self.attempts > 0:
                return self.succeed(f"target out of view after {self.attempts} steps; verifying here")
            if not isinstance(seen, dict):
                return self.fail(f"no {self.goal.label} detected and no colour sighting to approach")
            distance, bearing = 3.0, float(seen.get("yaw", frame.camera_pose.yaw)) - frame.camera_pose.yaw
        if distance <= self.params.stop_distance:
            return self.succeed(f"estimated {distance:.2f} m from the box's area: close enough")
        stamped = robot.pose()
        assert stamped is not None
        pose = stamped.pose
        length = min(self.params.step, distance - self.params.stop_distance)
        heading = pose.yaw + bearing
        goal = Pose2D(pose.x + length * math.cos(heading), pose.y + length * math.sin(heading), heading)
        self.attempts += 1
        self.started = robot.now()
        self.handle = robot.navigate_to(goal, Tolerance(0.2, 0.3))
        self.emit("approach_step", mode="box_area", attempt=self.attempts, x=round(goal.x, 3),
                  y=round(goal.y, 3), estimated_distance=round(distance, 3), bearing=round(bearing, 3))
        self.step = _Step.DRIVE
        return self.running(f"step {self.attempts}: {length:.2f} m toward it (estimated {distance:.2f} m)")
