"""FleetPatrol on a stand-in robot: visits counted, a one-waypoint stretch guarded, a lost robot failing."""

from __future__ import annotations

from typing import Any

import py_trees
import pytest

from missiontree.behaviours.fleet_patrol import FleetPatrol
from missiontree.engine.context import MissionContext
from missiontree.robot.actions import INFRASTRUCTURE, ActionResult, ActionStatus
from missiontree.testing import clean_state
from missiontree.types import Pose2D, PoseStamped

Status = py_trees.common.Status


@pytest.fixture(autouse=True)
def _clean() -> None:
    clean_state()


class _Handle:
    def __init__(self, status: ActionStatus, result: ActionResult | None = None) -> None:
        self._status, self._result = status, result

    def status(self) -> ActionStatus:
        return self._status

    def result(self) -> ActionResult | None:
        return self._result

    def feedback(self) -> None:
        return None

    def cancel(self) -> None:
        pass


class _Robot:
    """Arrives at once (or, ``lost``, aborts as a vanished server)."""

    name = "robot1"

    def __init__(self, lost: bool = False) -> None:
        self.t = 0.0
        self.lost = lost

    def now(self) -> float:
        return self.t

    def pose(self) -> PoseStamped:
        return PoseStamped(self.t, Pose2D(0.0, 0.0, 0.0))

    def navigate_to(self, goal: Pose2D, tolerance: Any = None) -> _Handle:
        if self.lost:
            result = ActionResult(ActionStatus.ABORTED, "gone", 0, kind=INFRASTRUCTURE)
            return _Handle(ActionStatus.ABORTED, result)
        return _Handle(ActionStatus.SUCCEEDED)


class _Events:
    def __init__(self) -> None:
        self.seen: list[str] = []

    def emit(self, event: str, /, **fields: Any) -> None:
        self.seen.append(event)


def _leaf(robot: _Robot, laps: int, waypoints: list[list[float]]) -> tuple[FleetPatrol, _Events]:
    leaf = FleetPatrol("patrol", FleetPatrol.Params(waypoints=waypoints, laps=laps))
    events = _Events()
    leaf.setup(context=MissionContext(robot=robot, events=events))  # type: ignore[arg-type]
    return leaf, events


def _tick(leaf: FleetPatrol, robot: _Robot, times: int) -> Status:
    for _ in range(times):
        for _ in leaf.tick():
            pass
        robot.t += 0.1
    return leaf.status


def test_a_single_waypoint_is_counted_again_only_after_revisit_after() -> None:
    """Standing on its only waypoint for 5 s, a robot counts it once, not on every tick."""
    robot = _Robot()
    leaf, events = _leaf(robot, 0, [[0.0, 0.0, 0.0]])
    _tick(leaf, robot, 50)
    assert events.seen.count("waypoint_reached") == 1


def test_one_lap_alone_succeeds_after_every_waypoint() -> None:
    """Without a fleet the leaf is a fleet of one: two waypoints reached, then SUCCESS."""
    robot = _Robot()
    leaf, events = _leaf(robot, 1, [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    assert _tick(leaf, robot, 10) is Status.SUCCESS
    assert events.seen.count("waypoint_reached") == 2


def test_a_goal_aborted_by_a_vanished_server_fails_as_lost() -> None:
    """An infrastructure abort is a lost robot (patrol_lost, FAILURE), not a skipped waypoint."""
    robot = _Robot(lost=True)
    leaf, events = _leaf(robot, 1, [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    assert _tick(leaf, robot, 2) is Status.FAILURE  # sent on the first tick, polled on the second
    assert "patrol_lost" in events.seen and "waypoint_skipped" not in events.seen


def test_a_robot_sent_to_an_alarm_drives_there_and_resumes() -> None:
    """A dispatched alarm preempts the patrol: alarm_look_started, alarm_looked (reached), then waypoints."""
    robot = _Robot()
    leaf, events = _leaf(robot, 0, [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    _tick(leaf, robot, 1)
    assert leaf.dispatcher is not None
    leaf.dispatcher.responses["robot1"] = {"x": 3.0, "y": 0.0, "alarm": 1, "raised_by": "robot2", "t": 0.0}
    _tick(leaf, robot, 3)
    assert events.seen.index("alarm_look_started") < events.seen.index("alarm_looked")
    assert leaf.dispatcher.response_for("robot1") is None
    assert events.seen[-1] in ("goal_sent", "waypoint_reached")
