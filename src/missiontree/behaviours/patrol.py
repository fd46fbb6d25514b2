"""The patrol: loop a waypoint route through the navigation stack, skipping what cannot be reached.

The patrol-robot thesis §4.5.8: a waypoint that Nav2 aborts (inside an obstacle's inscribed zone, a blocked
corridor) is logged and skipped, and the patrol goes on to the next one. Here the route comes
from the tree, a config file or a Nav2-style waypoint YAML (:mod:`missiontree.behaviours.waypoints`);
it runs a number of laps (0 = forever).

Unreachable is not lost. A waypoint the planner cannot reach is skipped; a goal that ended because
the machinery is gone — the backend says so (:data:`~missiontree.robot.actions.INFRASTRUCTURE`:
no NavigateToPose server, a vanished server, a lost result) or the robot's pose has not been
updated for ``max_pose_age`` seconds (the robot vanished) — fails the patrol at once with the
reason. Eighteen waypoints "skipped" in a row because nothing answers is a lost robot, not a
patrol.

Preemption: when a higher-priority branch (visual servoing on an alarm) halts the patrol, its
goal is cancelled but its place is kept, so the next time it starts it drives to the waypoint
it was interrupted on, on the same lap. Only finishing (all laps done) or failing resets it.
A halt that falls on the tick the goal ended (the robot arrived, the patrol had not yet polled)
counts the visit and moves the place on: driving back to that waypoint after servoing would
repeat the visit, or lose it when the person who raised the alarm stands on it.
"""

from __future__ import annotations

from typing import Annotated

from pydantic import BaseModel, Field

from missiontree.behaviours.motion import ANY_HEADING, robot_lost
from missiontree.behaviours.waypoints import RouteSource, Waypoint
from missiontree.engine.leaf import Leaf, Status
from missiontree.engine.ports import Output
from missiontree.robot.actions import INFRASTRUCTURE, ActionHandle, ActionResult, ActionStatus
from missiontree.types import Tolerance


class Patrol(Leaf):
    """Loop a waypoint route for some laps (0 = forever), skipping unreachable waypoints with a reason.

    Emits ``goal_sent`` per goal, ``waypoint_reached`` and ``waypoint_skipped`` (with the
    planner's reason), ``patrol_preempted`` when halted mid-goal and ``lap_done``. Writes the
    waypoint it is heading for to its ``waypoint`` port.
    """

    class Params(RouteSource):
        laps: int = Field(1, ge=0, description="Laps to drive; 0 patrols forever.")
        xy_tolerance: float = Field(0.3, gt=0, description="Distance that counts as reached (m).")
        yaw_tolerance: float = Field(
            ANY_HEADING, gt=0, le=ANY_HEADING,
            description="Heading error accepted (rad); 6.28 accepts any heading (the patrol-robot thesis "
            "§3.6.3).")
        waypoint_timeout: float | None = Field(
            None, gt=0, description="Skip a waypoint not reached within this many seconds.")
        max_consecutive_skips: int = Field(
            0, ge=0, description="Fail after this many skips in a row (0: never; a whole lap skipped fails).")
        max_pose_age: float = Field(
            10.0, gt=0, description="Fail when the robot's pose is older than this (s): the robot is lost "
            "(generous: a loaded machine delays pose messages by seconds).")
        waypoint: Annotated[str, Output("the waypoint being driven to", type="dict")] = "patrol_waypoint"

    params: Params

    def __init__(self, name: str, params: BaseModel | None = None) -> None:
        super().__init__(name, params)
        self.route: list[Waypoint] = []
        self.index = 0
        self.lap = 0
        self.reached = 0
        self.skipped = 0
        self.consecutive_skips = 0
        self.handle: ActionHandle | None = None
        self.goal_started = 0.0
        self.laps_done = False  # the last lap ended as the patrol was halted: succeed on the next start

    def on_setup(self) -> None:
        """Load the route (a missing or malformed file fails here, before the first tick)."""
        p = self.params
        self.route = p.load_route(f"{self.name}.waypoints")

    # -- lifecycle -------------------------------------------------------------------------------

    def initialise(self) -> None:
        """Head for the current waypoint: the first one, or the one the patrol was interrupted on."""
        if not self.route:
            self.on_setup()
        if not self.laps_done:
            self._send()

    def update(self) -> Status:
        """Poll the goal; on its end move on, and finish after the last lap."""
        if self.laps_done:
            return self._finish()
        assert self.handle is not None
        status = self.handle.status()
        waypoint = self.route[self.index]
        lost = self._robot_lost()
        if lost:
            if not status.done:
                self.handle.cancel()
            return self._lost(waypoint, lost)
        if not status.done:
            timeout = self.params.waypoint_timeout
            if timeout is not None and self.context.robot.now() - self.goal_started > timeout:
                self.handle.cancel()
                outcome = self._skip(waypoint, f"not reached within {timeout:g} s")
            else:
                return self.running(self._progress(waypoint))
        elif status is ActionStatus.SUCCEEDED:
            self._reached(waypoint)
            outcome = None
        else:
            result = self.handle.result()
            reason = (result.reason if result is not None and result.reason else status.value)
            if _infrastructure(result):
                return self._lost(waypoint, f"{status.value}: {reason}")
            outcome = self._skip(waypoint, f"{status.value}: {reason}")
        self.handle = None
        if outcome is not None:
            return outcome
        return self._advance()

    def terminate(self, new_status: Status) -> None:
        """Halted mid-goal: cancel it and keep the place. Finished or failed: start over next time.

        Halted as its goal had just succeeded (not yet polled): the visit counts and the place moves
        on to the next waypoint, which the next start drives to.
        """
        if self.handle is not None:
            handle, self.handle = self.handle, None
            waypoint = self.route[self.index]
            if new_status is Status.INVALID and _succeeded(handle):
                self._reached(waypoint)
                self._next()
            else:
                handle.cancel()
                self.emit("patrol_preempted", waypoint=waypoint.name, index=self.index, lap=self.lap)
        if new_status in (Status.SUCCESS, Status.FAILURE):
            self.index = 0
            self.lap = 0
            self.consecutive_skips = 0
            self.laps_done = False

    # -- helpers ---------------------------------------------------------------------------------

    def _send(self) -> None:
        waypoint = self.route[self.index]
        robot = self.context.robot
        tolerance = Tolerance(self.params.xy_tolerance, self.params.yaw_tolerance)
        self.goal_started = robot.now()
        self.handle = robot.navigate_to(waypoint.pose, tolerance)
        self.write("waypoint", {"name": waypoint.name, "index": self.index, "lap": self.lap,
                                "x": waypoint.pose.x, "y": waypoint.pose.y})
        self.emit("goal_sent", waypoint=waypoint.name, index=self.index, lap=self.lap,
                  x=waypoint.pose.x, y=waypoint.pose.y, yaw=waypoint.pose.yaw,
                  xy_tolerance=tolerance.xy, yaw_tolerance=tolerance.yaw)
        if self.ctx is not None:
            self.ctx.mark("goal", waypoint.pose.x, waypoint.pose.y, waypoint.name)

    def _robot_lost(self) -> str:
        """Why the robot counts as lost now ("" when it does not): no pose, or a pose gone stale."""
        return robot_lost(self.context.robot, self.params.max_pose_age)

    def _lost(self, waypoint: Waypoint, reason: str) -> Status:
        """Fail the patrol: the machinery that drives the robot is gone (not a waypoint to skip)."""
        self.handle = None
        self.emit("patrol_lost", waypoint=waypoint.name, index=self.index, lap=self.lap, reason=reason)
        return self.fail(f"robot lost on the way to {waypoint.name} (not an unreachable waypoint): {reason}")

    def _skip(self, waypoint: Waypoint, reason: str) -> Status | None:
        self.skipped += 1
        self.consecutive_skips += 1
        self.emit("waypoint_skipped", waypoint=waypoint.name, index=self.index, lap=self.lap,
                  x=waypoint.pose.x, y=waypoint.pose.y, reason=reason)
        limit = self.params.max_consecutive_skips or len(self.route)
        if self.consecutive_skips >= limit:
            self.handle = None
            return self.fail(f"{self.consecutive_skips} waypoints in a row unreachable, last "
                             f"{waypoint.name}: {reason}")
        return None

    def _reached(self, waypoint: Waypoint) -> None:
        self.reached += 1
        self.consecutive_skips = 0
        self.emit("waypoint_reached", waypoint=waypoint.name, index=self.index, lap=self.lap,
                  x=waypoint.pose.x, y=waypoint.pose.y)

    def _next(self) -> None:
        """Move the place to the next waypoint (and lap); note when the last lap is done."""
        self.index += 1
        if self.index >= len(self.route):
            self.index = 0
            self.lap += 1
            self.emit("lap_done", lap=self.lap, reached=self.reached, skipped=self.skipped)
            if self.params.laps and self.lap >= self.params.laps:
                self.laps_done = True

    def _finish(self) -> Status:
        return self.succeed(f"{self.lap} lap(s): {self.reached} waypoints reached, {self.skipped} skipped")

    def _advance(self) -> Status:
        self._next()
        if self.laps_done:
            return self._finish()
        self._send()
        return self.running(self._progress(self.route[self.index]))

    def _progress(self, waypoint: Waypoint) -> str:
        laps = f"{self.lap + 1}/{self.params.laps}" if self.params.laps else f"{self.lap + 1}"
        return f"lap {laps}, to {waypoint.name} ({waypoint.pose.x:.2f}, {waypoint.pose.y:.2f})"


def _succeeded(handle: ActionHandle) -> bool:
    """Whether the goal has succeeded; a status that cannot be read (a backend closing) is not success."""
    try:
        return handle.status() is ActionStatus.SUCCEEDED
    except Exception:  # noqa: BLE001 - a halt must go on whatever the backend does
        return False


def _infrastructure(result: ActionResult | None) -> bool:
    """True when a goal ended because the machinery is gone, as the backend reports it."""
    return result is not None and getattr(result, "kind", "") == INFRASTRUCTURE
