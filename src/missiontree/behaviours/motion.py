"""Motion leaves: go to a pose through the navigation stack, or turn in place.

:class:`NavigateTo` is Nav2's NavigateToPose as a leaf, in the simple commander's shape
(STYLE §2): ``initialise`` sends the goal, ``update`` polls the handle and returns at once,
``terminate`` cancels the goal when the leaf is halted. :class:`Rotate` turns the robot by an
angle with ``drive`` and a proportional controller on the remaining angle.
"""

from __future__ import annotations

import math
from typing import Annotated

from pydantic import BaseModel, Field

from missiontree.engine.leaf import Leaf, Status
from missiontree.engine.ports import Output
from missiontree.robot.actions import ActionHandle, ActionStatus
from missiontree.types import Pose2D, Tolerance, wrap_angle

#: A yaw tolerance that accepts any final heading (seed 001 §3.6.3).
ANY_HEADING = 2.0 * math.pi


class NavigateTo(Leaf):
    """Drive to a map pose with the navigation stack; fails with the planner's reason.

    Emits ``goal_sent`` when the goal goes out and ``goal_result`` when it ends. A yaw tolerance
    of 6.28 (2π) accepts any final heading, as seed 001 configured Nav2.
    """

    class Params(BaseModel):
        x: float = Field(description="Goal x in the map frame (m); {bb: key} reads it when the leaf starts.")
        y: float = Field(description="Goal y in the map frame (m).")
        yaw: float = Field(0.0, description="Goal heading (rad).")
        xy_tolerance: float = Field(0.25, gt=0, description="Distance that counts as reached (m).")
        yaw_tolerance: float = Field(
            0.25, gt=0, le=ANY_HEADING, description="Heading error accepted (rad); 6.28 accepts any heading.")
        timeout: float | None = Field(None, gt=0, description="Give up (and cancel) after this many seconds.")
        result: Annotated[str, Output("how the goal ended: succeeded, aborted...", type="str")] = "nav_result"

    params: Params

    def __init__(self, name: str, params: BaseModel | None = None) -> None:
        super().__init__(name, params)
        self.handle: ActionHandle | None = None
        self.goal: Pose2D | None = None
        self.started = 0.0

    def initialise(self) -> None:
        """Send the goal."""
        self.goal = Pose2D(float(self.value("x")), float(self.value("y")), float(self.value("yaw")))
        tolerance = Tolerance(self.params.xy_tolerance, self.params.yaw_tolerance)
        robot = self.context.robot
        self.started = robot.now()
        self.handle = robot.navigate_to(self.goal, tolerance)
        self.emit("goal_sent", x=self.goal.x, y=self.goal.y, yaw=self.goal.yaw,
                  xy_tolerance=tolerance.xy, yaw_tolerance=tolerance.yaw)

    def update(self) -> Status:
        """Poll the goal."""
        assert self.handle is not None and self.goal is not None
        status = self.handle.status()
        if not status.done:
            timeout = self.params.timeout
            if timeout is not None and self.context.robot.now() - self.started > timeout:
                self.handle.cancel()
                return self._ended(ActionStatus.ABORTED, f"not reached within {timeout:g} s")
            feedback = self.handle.feedback()
            remaining = f"{feedback.distance_remaining:.2f} m to go" if feedback else status.value
            return self.running(f"to ({self.goal.x:.2f}, {self.goal.y:.2f}): {remaining}")
        result = self.handle.result()
        reason = result.reason if result is not None else ""
        return self._ended(status, reason)

    def _ended(self, status: ActionStatus, reason: str) -> Status:
        assert self.goal is not None
        self.handle = None
        self.write("result", status.value)
        self.emit("goal_result", status=status.value, reason=reason, x=self.goal.x, y=self.goal.y)
        if status is ActionStatus.SUCCEEDED:
            return self.succeed(f"reached ({self.goal.x:.2f}, {self.goal.y:.2f})")
        where = f"({self.goal.x:.2f}, {self.goal.y:.2f})"
        return self.fail(f"goal {where} {status.value}: {reason or 'no reason given'}")

    def terminate(self, new_status: Status) -> None:
        """Cancel the goal if the leaf is halted while it runs."""
        if self.handle is not None:
            self.handle.cancel()
            if self.goal is not None:
                self.emit("goal_result", status="canceled", reason="halted", x=self.goal.x, y=self.goal.y)
            self.handle = None


class Rotate(Leaf):
    """Turn in place by an angle with a proportional controller on the remaining angle."""

    class Params(BaseModel):
        angle: float = Field(description="Angle to turn (rad), positive counter-clockwise.")
        tolerance: float = Field(0.05, gt=0, description="Remaining angle that counts as done (rad).")
        gain: float = Field(2.0, gt=0, description="Angular speed per radian of remaining angle (1/s).")
        max_speed: float = Field(1.0, gt=0, description="Largest angular speed (rad/s).")
        timeout: float = Field(20.0, gt=0, description="Give up after this many seconds.")

    params: Params

    def __init__(self, name: str, params: BaseModel | None = None) -> None:
        super().__init__(name, params)
        self.target = 0.0
        self.started = 0.0

    def initialise(self) -> None:
        """Fix the target heading."""
        robot = self.context.robot
        stamped = robot.pose()
        if stamped is None:
            raise RuntimeError(f"{self.name}: the robot has no pose yet; wait for localisation")
        self.target = wrap_angle(stamped.pose.yaw + float(self.value("angle")))
        self.started = robot.now()

    def update(self) -> Status:
        """Command the next angular speed, or stop when within tolerance."""
        robot = self.context.robot
        stamped = robot.pose()
        assert stamped is not None
        error = wrap_angle(self.target - stamped.pose.yaw)
        if abs(error) <= self.params.tolerance:
            robot.drive(0.0, 0.0)
            return self.succeed(f"heading {stamped.pose.yaw:.2f} rad")
        if robot.now() - self.started > self.params.timeout:
            robot.drive(0.0, 0.0)
            return self.fail(f"still {error:.2f} rad from the target heading after {self.params.timeout:g} s")
        speed = max(-self.params.max_speed, min(self.params.max_speed, self.params.gain * error))
        robot.drive(0.0, speed)
        return self.running(f"{error:.2f} rad to turn")

    def terminate(self, new_status: Status) -> None:
        """Stop turning when halted."""
        if new_status == Status.INVALID and self.ctx is not None:
            self.ctx.robot.drive(0.0, 0.0)
