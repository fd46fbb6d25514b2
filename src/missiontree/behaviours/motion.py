"""Motion leaves: go to a pose through the navigation stack, or turn in place.

:class:`NavigateTo` is Nav2's NavigateToPose as a leaf, in the simple commander's shape (send,
poll, cancel; never blocking the tick): ``initialise`` sends the goal, ``update`` polls the handle
and returns at once, ``terminate`` cancels the goal when the leaf is halted. :class:`Rotate` turns
the robot by an angle with ``drive`` and a proportional controller on the remaining angle.
"""

from __future__ import annotations

import math
from typing import Annotated, Any

from pydantic import BaseModel, Field

from missiontree.engine.leaf import Leaf, Status
from missiontree.engine.ports import Output
from missiontree.robot.actions import ActionHandle, ActionStatus
from missiontree.types import Pose2D, Tolerance, wrap_angle

#: A yaw tolerance that accepts any final heading (the patrol-robot thesis §3.6.3).
ANY_HEADING = 2.0 * math.pi


def robot_lost(robot: Any, max_pose_age: float) -> str:
    """Why ``robot`` counts as lost now ("" when not): no pose, or one older than ``max_pose_age`` s."""
    stamped = robot.pose()
    if stamped is None:
        return "the robot reports no pose"
    age = robot.now() - stamped.stamp
    if age > max_pose_age:
        return f"the robot's pose was last updated {age:.1f} s ago (limit {max_pose_age:g} s)"
    return ""


class GoalLeaf(Leaf):
    """A leaf that sends one navigation goal and polls it, never blocking the tick.

    It keeps the goal's ``handle``, its pose ``goal`` and when it went out (``started``, robot s):
    :class:`NavigateTo` and the approach's DriveToStandoff drive this one way.
    """

    def __init__(self, name: str, params: BaseModel | None = None) -> None:
        super().__init__(name, params)
        self.handle: ActionHandle | None = None
        self.goal: Pose2D | None = None
        self.started = 0.0

    def send_goal(self, goal: Pose2D, tolerance: Tolerance) -> None:
        """Send ``goal`` to the navigation stack now."""
        robot = self.context.robot
        self.goal = goal
        self.started = robot.now()
        self.handle = robot.navigate_to(goal, tolerance)

    def overdue(self, timeout: float | None) -> bool:
        """Whether the goal ran over ``timeout`` s of robot time (None: never); cancelled and dropped then."""
        if timeout is None or self.handle is None or self.context.robot.now() - self.started <= timeout:
            return False
        self.handle.cancel()
        self.handle = None
        return True


class NavigateTo(GoalLeaf):
    """Drive to a map pose with the navigation stack; fails with the planner's reason.

    Emits ``goal_sent`` when the goal goes out and ``goal_result`` when it ends. A yaw tolerance
    of 6.28 (2π) accepts any final heading, as the patrol-robot thesis configured Nav2.
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
        self.invalid = ""

    def initialise(self) -> None:
        """Send the goal (a goal that is not a finite pose is not sent: ``update`` fails with why)."""
        self.handle = None
        self.invalid = ""
        values = {axis: self.value(axis) for axis in ("x", "y", "yaw")}
        self.invalid = _not_finite(values)
        if self.invalid:
            self.goal = None
            return
        tolerance = Tolerance(self.params.xy_tolerance, self.params.yaw_tolerance)
        self.send_goal(Pose2D(float(values["x"]), float(values["y"]), float(values["yaw"])), tolerance)
        assert self.goal is not None
        self.emit("goal_sent", x=self.goal.x, y=self.goal.y, yaw=self.goal.yaw,
                  xy_tolerance=tolerance.xy, yaw_tolerance=tolerance.yaw)

    def update(self) -> Status:
        """Poll the goal."""
        if self.invalid:
            return self.fail(f"goal not sent: {self.invalid}")
        assert self.handle is not None and self.goal is not None
        status = self.handle.status()
        if not status.done:
            if self.overdue(self.params.timeout):
                return self._ended(ActionStatus.ABORTED, f"not reached within {self.params.timeout:g} s")
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
    """Turn in place by an angle (sign = direction, any size: 6.28 is a full turn), P control on what is left.

    The angle turned is integrated from the heading's change tick by tick, never read as the gap
    between two wrapped headings: a 360° scan turns 360° and a 4 rad turn goes counter-clockwise.
    """

    class Params(BaseModel):
        angle: float = Field(
            description="Angle to turn (rad), positive counter-clockwise; 6.28 is a full turn.")
        tolerance: float = Field(0.05, gt=0, description="Remaining angle that counts as done (rad).")
        gain: float = Field(2.0, gt=0, description="Angular speed per radian of remaining angle (1/s).")
        max_speed: float = Field(1.0, gt=0, description="Largest angular speed (rad/s).")
        timeout: float = Field(20.0, gt=0, description="Give up after this many seconds.")

    params: Params

    def __init__(self, name: str, params: BaseModel | None = None) -> None:
        super().__init__(name, params)
        self.angle = 0.0
        self.turned = 0.0
        self.last_yaw = 0.0
        self.started = 0.0
        self.invalid = ""

    def initialise(self) -> None:
        """Fix the angle to turn and start integrating the heading's change."""
        robot = self.context.robot
        stamped = robot.pose()
        if stamped is None:
            raise RuntimeError(f"{self.name}: the robot has no pose yet; wait for localisation")
        raw = self.value("angle")
        self.invalid = _not_finite({"angle": raw})
        self.angle = float(raw) if not self.invalid else 0.0
        self.turned = 0.0
        self.last_yaw = stamped.pose.yaw
        self.started = robot.now()

    def update(self) -> Status:
        """Add the heading's change since the last tick; command the next speed, or stop when done."""
        robot = self.context.robot
        if self.invalid:
            robot.drive(0.0, 0.0)
            return self.fail(f"not turning: {self.invalid}")
        stamped = robot.pose()
        assert stamped is not None
        yaw = stamped.pose.yaw
        # One tick turns far less than half a turn, so the wrapped change is the true change.
        self.turned += wrap_angle(yaw - self.last_yaw)
        self.last_yaw = yaw
        remaining = self.angle - self.turned
        if abs(remaining) <= self.params.tolerance:
            robot.drive(0.0, 0.0)
            return self.succeed(f"turned {self.turned:.2f} rad, heading {yaw:.2f} rad")
        if robot.now() - self.started > self.params.timeout:
            robot.drive(0.0, 0.0)
            return self.fail(f"turned {self.turned:.2f} of {self.angle:.2f} rad in "
                             f"{self.params.timeout:g} s; still {remaining:.2f} rad to go")
        speed = max(-self.params.max_speed, min(self.params.max_speed, self.params.gain * remaining))
        robot.drive(0.0, speed)
        return self.running(f"{remaining:.2f} rad to turn")

    def terminate(self, new_status: Status) -> None:
        """Stop turning when halted."""
        if new_status == Status.INVALID and self.ctx is not None:
            self.ctx.robot.drive(0.0, 0.0)


def _not_finite(values: dict[str, object]) -> str:
    """Why these values are not finite numbers ("" when they all are)."""
    bad = []
    for name, value in values.items():
        try:
            number = float(value)  # type: ignore[arg-type]
        except (TypeError, ValueError):
            bad.append(f"{name}={value!r} is not a number")
            continue
        if not math.isfinite(number):
            bad.append(f"{name}={value!r} is not finite")
    return "; ".join(bad) + ("; set a finite number (the blackboard key or the parameter)" if bad else "")
