"""FleetPatrol: one robot's share of a patrol that the whole fleet drives (docs/fleet.md).

Every robot's copy of the tree holds a FleetPatrol leaf over the same route; they share one
:class:`~missiontree.behaviours.fleet_dispatch.PatrolDispatcher` (``context.fleet.shared``), which
cuts the route into one stretch per robot and re-cuts it when a robot is lost. Each leaf asks it
for its next waypoint, drives there through its own robot's navigation and reports the visit.

As :class:`~missiontree.behaviours.patrol.Patrol` does: a waypoint the planner cannot reach is
skipped with the reason (``waypoint_skipped``); a goal that ended because the machinery is gone
(an :data:`~missiontree.robot.actions.INFRASTRUCTURE` result) or a pose older than
``max_pose_age`` fails this robot's leaf (``patrol_lost``): the robot is lost, the fleet
(:class:`~missiontree.engine.fleet.FleetRoot`) records it and the dispatcher gives its waypoints to
the others. A robot with nothing owed waits (RUNNING) until the fleet is done, so a later loss can
still hand it work. Without a fleet (a single-robot run) the leaf is a fleet of one.

Alarm dispatch (``respond``, the patrol-robot thesis §5.3.4): a new alarm on this robot's ``alarm``
port (its Surveillance's) goes to the dispatcher, which sends the nearest free other robot; a
robot sent leaves its patrol goal (its place kept), drives to within ``look_tolerance`` of the
alarm's position, then resumes.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated, Any

from pydantic import BaseModel, Field

from missiontree.behaviours.fleet_dispatch import PatrolDispatcher
from missiontree.behaviours.motion import ANY_HEADING, robot_lost
from missiontree.behaviours.waypoints import RouteSource, Waypoint
from missiontree.engine.leaf import Leaf, Status
from missiontree.engine.ports import Input, Output
from missiontree.robot.actions import INFRASTRUCTURE, ActionHandle, ActionStatus
from missiontree.types import Pose2D, Tolerance

__all__ = ["FleetPatrol"]


class FleetPatrol(Leaf):
    """Patrol this robot's stretch of a route the fleet shares; re-balanced when a robot is lost.

    Emits ``goal_sent``, ``waypoint_reached`` and ``waypoint_skipped`` (each with ``robot``),
    ``patrol_lost`` when its robot is gone, ``alarm_look_started`` and ``alarm_looked`` when sent
    to look at another robot's alarm; the dispatcher emits ``fleet_assigned``,
    ``fleet_rebalanced`` and ``alarm_dispatched``. Writes the waypoint it is heading for to its
    ``waypoint`` port (under the robot's blackboard namespace).
    """

    class Params(RouteSource):
        laps: int = Field(1, ge=0, description="Visits owed to each waypoint; 0 patrols until stopped.")
        xy_tolerance: float = Field(0.3, gt=0, description="Distance that counts as reached (m).")
        yaw_tolerance: float = Field(ANY_HEADING, gt=0, le=ANY_HEADING,
                                     description="Heading error accepted (rad); 6.28 accepts any heading.")
        waypoint_timeout: float | None = Field(
            None, gt=0, description="Skip a waypoint not reached within this many seconds.")
        max_pose_age: float = Field(
            10.0, gt=0, description="Fail (the robot is lost) when its pose is older than this (s).")
        revisit_after: float = Field(
            10.0, ge=0, description="A robot whose next waypoint is the one it just reached (a stretch of "
            "one) waits this long before counting it again (s).")
        respond: bool = Field(True, description="Answer alarms: this robot's alarms send the nearest free "
                              "robot to look, and this robot goes when sent (the patrol-robot thesis "
                              "§5.3.4).")
        look_tolerance: float = Field(1.5, gt=0, description="How near to an alarm's position counts as "
                                      "having looked (m): people stand there.")
        look_timeout: float = Field(90.0, gt=0, description="Give up looking after this many seconds.")
        waypoint: Annotated[str, Output("the waypoint being driven to", type="dict")] = "patrol_waypoint"
        alarm: Annotated[str, Input("the alarm this robot's surveillance raised", type="dict")] = "alarm"

    params: Params

    def __init__(self, name: str, params: BaseModel | None = None) -> None:
        super().__init__(name, params)
        self.route: list[Waypoint] = []
        self.dispatcher: PatrolDispatcher | None = None
        self.handle: ActionHandle | None = None
        self.target = -1
        self.goal_started = 0.0
        self.reached = 0
        self.skipped = 0
        self.last_index = -1
        self.last_reached = 0.0
        self.look: ActionHandle | None = None
        self.look_started = 0.0
        self.alarms_seen: set[Any] = set()

    def on_setup(self) -> None:
        """Load the route and join the fleet's dispatcher for it (one per fleet and route)."""
        p = self.params
        self.route = p.load_route(f"{self.name}.waypoints")
        if self.ctx is None:
            return
        fleet = self.ctx.fleet
        robot = self.ctx.robot
        if fleet is None:  # a single robot: a fleet of one
            self.dispatcher = PatrolDispatcher(self.route, p.laps, [robot.name], self._fleet_emit, robot.now)
            return
        source = Path(p.waypoints_file).stem if p.waypoints_file else "inline"
        key = f"patrol:{source}:{p.route or ''}:{p.laps}:{len(self.route)}"
        self.dispatcher = fleet.shared(key, lambda: PatrolDispatcher(
            self.route, p.laps, list(fleet.names), self._fleet_emit, fleet.clock))
        fleet.on_loss(self.dispatcher.lose)

    def _fleet_emit(self, event: str, **fields: Any) -> None:
        """A dispatcher event: to the fleet's log when there is one, else through this robot's sink."""
        fleet = self.ctx.fleet if self.ctx is not None else None
        sink = fleet.events if fleet is not None and fleet.events is not None else None
        if sink is not None:
            sink.emit(event, node=self.name, **fields)
        else:
            self.emit(event, **fields)

    # -- lifecycle -------------------------------------------------------------------------------

    def initialise(self) -> None:
        """Nothing to start: the next update asks the dispatcher."""
        if self.dispatcher is None:
            self.on_setup()

    def update(self) -> Status:
        """Poll the goal; on its end report the visit and ask for the next waypoint."""
        assert self.dispatcher is not None
        robot = self.context.robot
        lost = self._robot_lost()
        if lost:
            return self._lost(lost)
        stamped = robot.pose()
        self.dispatcher.join(robot.name, stamped.pose if stamped is not None else None)
        if self.params.respond:
            self._notice_alarm()
            task = self.dispatcher.response_for(robot.name)
            if task is not None:
                return self._answer(task)
        if self.handle is not None:
            status = self._poll()
            if status is not None:
                return status
        if self.handle is None:
            index = self.dispatcher.next_for(robot.name)
            if index is not None and index == self.last_index and \
                    robot.now() - self.last_reached < self.params.revisit_after:
                return self.running(f"guarding {self.dispatcher.waypoints[index].name}")
            if index is None:
                if self.dispatcher.done():
                    return self.succeed(f"fleet done: {self.reached} reached, {self.skipped} skipped here")
                return self.running("waiting: nothing owed on this robot's stretch")
            self._send(index)
        return self.running(self._progress())

    def _poll(self) -> Status | None:
        """The running goal's end (visit, skip or loss); None while it runs or after a visit/skip."""
        assert self.handle is not None and self.dispatcher is not None
        status = self.handle.status()
        waypoint = self.dispatcher.waypoints[self.target]
        if not status.done:
            timeout = self.params.waypoint_timeout
            if timeout is not None and self.context.robot.now() - self.goal_started > timeout:
                self.handle.cancel()
                self._skip(waypoint, f"not reached within {timeout:g} s")
            return None
        if status is ActionStatus.SUCCEEDED:
            self.handle = None
            self.reached += 1
            self.emit("waypoint_reached", waypoint=waypoint.name, index=self.target,
                      x=waypoint.pose.x, y=waypoint.pose.y)
            self.dispatcher.visited(self.context.robot.name, self.target)
            self.last_index, self.last_reached = self.target, self.context.robot.now()
            return None
        result = self.handle.result()
        reason = result.reason if result is not None and result.reason else status.value
        if result is not None and getattr(result, "kind", "") == INFRASTRUCTURE:
            return self._lost(f"{status.value}: {reason}")
        self._skip(waypoint, f"{status.value}: {reason}")
        return None

    def terminate(self, new_status: Status) -> None:
        """Halted or ended: cancel a goal still running (the dispatcher keeps the place and the task)."""
        for handle in (self.handle, self.look):
            if handle is None:
                continue
            try:
                if not handle.status().done:
                    handle.cancel()
            except Exception:  # noqa: BLE001 - a halt must go on whatever the backend does
                pass
        self.handle = self.look = None

    # -- alarms ----------------------------------------------------------------------------------

    def _notice_alarm(self) -> None:
        """A new alarm of this robot's with a position: ask the dispatcher to send someone to look."""
        assert self.dispatcher is not None
        alarm = self.read("alarm")
        if not isinstance(alarm, dict):
            return
        key = (alarm.get("id"), alarm.get("raised_at"))
        position = alarm.get("position")
        if key in self.alarms_seen or not isinstance(position, list | tuple) or len(position) < 2:
            return
        self.alarms_seen.add(key)
        x, y = float(position[0]), float(position[1])
        if math.isfinite(x) and math.isfinite(y):
            self.dispatcher.alarm(self.context.robot.name, x, y, alarm.get("id"))

    def _answer(self, task: dict[str, Any]) -> Status:
        """Drive to look at the alarm this robot was sent to; back to the patrol when done."""
        assert self.dispatcher is not None
        robot = self.context.robot
        if self.look is None:
            if self.handle is not None:  # the patrol's goal gives way; its place is kept
                self.handle.cancel()
                self.handle = None
            self.look_started = robot.now()
            self.look = robot.navigate_to(Pose2D(task["x"], task["y"], 0.0),
                                          Tolerance(self.params.look_tolerance, ANY_HEADING))
            self.emit("alarm_look_started", x=task["x"], y=task["y"], alarm=task["alarm"],
                      raised_by=task["raised_by"])
        status = self.look.status()
        if not status.done:
            if robot.now() - self.look_started <= self.params.look_timeout:
                return self.running(f"looking at the alarm of {task['raised_by']} ({task['x']:.1f}, "
                                    f"{task['y']:.1f})")
            self.look.cancel()
            return self._looked(task, "timeout")
        if status is ActionStatus.SUCCEEDED:
            return self._looked(task, "reached")
        result = self.look.result()
        if result is not None and getattr(result, "kind", "") == INFRASTRUCTURE:
            self.look = None
            return self._lost(f"{status.value}: {result.reason}")
        return self._looked(task, "unreachable: " + (result.reason if result is not None else status.value))

    def _looked(self, task: dict[str, Any], outcome: str) -> Status:
        assert self.dispatcher is not None
        self.look = None
        self.emit("alarm_looked", outcome=outcome, alarm=task["alarm"], raised_by=task["raised_by"],
                  x=task["x"], y=task["y"], took_s=round(self.context.robot.now() - self.look_started, 2))
        self.dispatcher.responded(self.context.robot.name, outcome.split(":")[0])
        return self.running("back to the patrol")

    # -- helpers ---------------------------------------------------------------------------------

    def _send(self, index: int) -> None:
        assert self.dispatcher is not None
        waypoint = self.dispatcher.waypoints[index]
        robot = self.context.robot
        tolerance = Tolerance(self.params.xy_tolerance, self.params.yaw_tolerance)
        self.target = index
        self.goal_started = robot.now()
        self.handle = robot.navigate_to(waypoint.pose, tolerance)
        self.write("waypoint", {"name": waypoint.name, "index": index, "x": waypoint.pose.x,
                                "y": waypoint.pose.y})
        self.emit("goal_sent", waypoint=waypoint.name, index=index, x=waypoint.pose.x, y=waypoint.pose.y,
                  yaw=waypoint.pose.yaw, xy_tolerance=tolerance.xy, yaw_tolerance=tolerance.yaw)
        if self.ctx is not None:
            self.ctx.mark("goal", waypoint.pose.x, waypoint.pose.y, waypoint.name)

    def _skip(self, waypoint: Waypoint, reason: str) -> None:
        assert self.dispatcher is not None
        self.handle = None
        self.skipped += 1
        self.emit("waypoint_skipped", waypoint=waypoint.name, index=self.target,
                  x=waypoint.pose.x, y=waypoint.pose.y, reason=reason)
        self.dispatcher.skip(self.context.robot.name, self.target, reason)

    def _robot_lost(self) -> str:
        """Why this robot counts as lost now ("" when it does not): no pose, or a pose gone stale."""
        return robot_lost(self.context.robot, self.params.max_pose_age)

    def _lost(self, reason: str) -> Status:
        """Fail this robot's patrol: the machinery that drives it is gone (the fleet re-balances)."""
        if self.handle is not None:
            handle, self.handle = self.handle, None
            try:
                handle.cancel()
            except Exception:  # noqa: BLE001 - the robot is gone already
                pass
        where = self.dispatcher.waypoints[self.target].name if self.dispatcher and self.target >= 0 else ""
        self.emit("patrol_lost", waypoint=where, reason=reason)
        return self.fail(f"robot lost{' on the way to ' + where if where else ''}: {reason}")

    def _progress(self) -> str:
        if self.dispatcher is None or self.target < 0 or self.handle is None:
            return "waiting for the fleet's assignment"
        waypoint = self.dispatcher.waypoints[self.target]
        return f"to {waypoint.name} ({waypoint.pose.x:.2f}, {waypoint.pose.y:.2f})"
