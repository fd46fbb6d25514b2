"""Tests of NavigateTo and Rotate on a scripted robot."""

from __future__ import annotations

import math

import py_trees
from patrol_doubles import Events, FakeRobot

from missiontree.behaviours.motion import NavigateTo, Rotate
from missiontree.engine.context import MissionContext
from missiontree.engine.leaf import Status
from missiontree.engine.validate import validate_params
from missiontree.testing import tick_until


def test_navigate_to_sends_goal_and_succeeds() -> None:
    """The goal goes out in initialise with its tolerance, goal_sent and goal_result are emitted."""
    robot, events = FakeRobot(), Events()
    leaf = NavigateTo("go", NavigateTo.Params(x=1.0, y=2.0, yaw=0.5, yaw_tolerance=6.28))
    leaf.setup(context=MissionContext(robot=robot, events=events))
    tick_until(leaf)
    assert leaf.status == Status.SUCCESS
    assert robot.goals[0].goal.yaw == 0.5 and robot.goals[0].tolerance.yaw == 6.28
    assert events.of("goal_sent")[0]["x"] == 1.0
    assert events.of("goal_result")[0]["status"] == "succeeded"


def test_navigate_to_fails_with_planner_reason() -> None:
    """An aborted goal fails the leaf with the planner's reason as feedback."""
    robot = FakeRobot()
    robot.unreachable.add((3.0, 3.0))
    leaf = NavigateTo("go", NavigateTo.Params(x=3.0, y=3.0))
    leaf.setup(context=MissionContext(robot=robot))
    tick_until(leaf)
    assert leaf.status == Status.FAILURE
    assert "goal inside an obstacle" in leaf.feedback_message


def test_navigate_to_cancels_goal_when_halted() -> None:
    """Halting the leaf mid-goal cancels the goal."""
    robot = FakeRobot()
    robot.polls_per_goal = 100
    leaf = NavigateTo("go", NavigateTo.Params(x=1.0, y=0.0))
    leaf.setup(context=MissionContext(robot=robot))
    leaf.tick_once()
    leaf.stop(Status.INVALID)
    assert robot.goals[0].cancelled


def test_navigate_to_reads_goal_from_blackboard() -> None:
    """A {bb: key} coordinate is read from the blackboard when the leaf starts."""
    robot = FakeRobot()
    writer = py_trees.blackboard.Client(name="writer")
    writer.register_key("goal_x", access=py_trees.common.Access.WRITE)
    writer.goal_x = 4.5
    params, issues = validate_params(NavigateTo.Params, {"x": {"bb": "goal_x"}, "y": 0.0})
    assert not issues
    leaf = NavigateTo("go", params)
    leaf.setup(context=MissionContext(robot=robot))
    leaf.tick_once()
    assert robot.goals[0].goal.x == 4.5


def test_navigate_to_times_out() -> None:
    """A goal not reached within the timeout is cancelled and the leaf fails saying so."""
    robot = FakeRobot()
    robot.polls_per_goal = 100
    leaf = NavigateTo("go", NavigateTo.Params(x=1.0, y=0.0, timeout=2.0))
    leaf.setup(context=MissionContext(robot=robot))
    leaf.tick_once()
    robot.advance(3.0)
    leaf.tick_once()
    assert leaf.status == Status.FAILURE and "within 2 s" in leaf.feedback_message
    assert robot.goals[0].cancelled


def test_rotate_turns_by_the_angle() -> None:
    """Rotate drives with a P controller until the heading is within tolerance, then stops."""
    robot = FakeRobot()
    leaf = Rotate("turn", Rotate.Params(angle=math.pi / 2))
    leaf.setup(context=MissionContext(robot=robot))
    for _ in range(200):
        leaf.tick_once()
        if leaf.status != Status.RUNNING:
            break
        robot.advance(0.05)
    assert leaf.status == Status.SUCCESS
    assert abs(robot.current.yaw - math.pi / 2) <= 0.05
    assert robot.drives[-1] == (0.0, 0.0)


class WrappingRobot(FakeRobot):
    """A FakeRobot whose pose reports the heading wrapped to (-pi, pi], as real localisation does."""

    def pose(self):  # type: ignore[no-untyped-def]
        stamped = super().pose()
        assert stamped is not None
        p = stamped.pose
        return type(stamped)(stamped.stamp, type(p)(p.x, p.y, math.remainder(p.yaw, 2 * math.pi)))


def _turn(angle: float, robot: FakeRobot | None = None) -> tuple[Rotate, FakeRobot]:
    robot = robot or WrappingRobot()
    leaf = Rotate("turn", Rotate.Params(angle=angle, max_speed=1.5))
    leaf.setup(context=MissionContext(robot=robot))
    for _ in range(2000):
        leaf.tick_once()
        if leaf.status != Status.RUNNING:
            break
        robot.advance(0.05)
    return leaf, robot


def test_rotate_a_full_turn_turns_a_full_turn() -> None:
    """Rotate 6.28 turns the robot about 360 degrees (the wrapped target used to be the start heading)."""
    leaf, robot = _turn(6.28)
    assert leaf.status == Status.SUCCESS
    # FakeRobot integrates the unwrapped heading: it is the angle really turned.
    assert abs(robot.current.yaw - 6.28) <= 0.06
    assert all(w >= 0.0 for _, w in robot.drives)


def test_rotate_sign_gives_the_direction_beyond_half_a_turn() -> None:
    """Rotate 4.0 turns 4 rad counter-clockwise and -4.0 clockwise (not the shorter way round)."""
    leaf, robot = _turn(4.0)
    assert leaf.status == Status.SUCCESS and abs(robot.current.yaw - 4.0) <= 0.06
    assert all(w >= 0.0 for _, w in robot.drives)
    leaf, robot = _turn(-4.0)
    assert leaf.status == Status.SUCCESS and abs(robot.current.yaw + 4.0) <= 0.06
    assert all(w <= 0.0 for _, w in robot.drives)


def test_rotate_two_turns_from_a_heading_near_the_wrap() -> None:
    """From 3.1 rad, two full turns counter-clockwise cross the wrap and end at 3.1 + 4pi."""
    robot = WrappingRobot()
    robot.set_pose(robot.current.__class__(0.0, 0.0, 3.1))
    leaf, robot = _turn(4 * math.pi, robot)
    assert leaf.status == Status.SUCCESS and abs(robot.current.yaw - (3.1 + 4 * math.pi)) <= 0.06


def test_rotate_not_a_number_fails_at_once_without_turning() -> None:
    """Rotate with a NaN angle from the blackboard fails on its first tick with the reason, robot stopped."""
    writer = py_trees.blackboard.Client(name="writer")
    writer.register_key("turn_by", access=py_trees.common.Access.WRITE)
    writer.turn_by = float("nan")
    params, issues = validate_params(Rotate.Params, {"angle": {"bb": "turn_by"}})
    assert not issues
    robot = FakeRobot()
    leaf = Rotate("turn", params)
    leaf.setup(context=MissionContext(robot=robot))
    leaf.tick_once()
    assert leaf.status == Status.FAILURE and "not finite" in leaf.feedback_message
    assert robot.drives == [(0.0, 0.0)]


def test_navigate_to_non_finite_goal_from_blackboard_fails_without_sending() -> None:
    """A NaN or infinite goal read from the blackboard fails the leaf with the reason; no goal goes out."""
    for bad in (float("nan"), float("inf"), -float("inf")):
        writer = py_trees.blackboard.Client(name="writer")
        writer.register_key("goal_x", access=py_trees.common.Access.WRITE)
        writer.goal_x = bad
        params, issues = validate_params(NavigateTo.Params, {"x": {"bb": "goal_x"}, "y": 0.0})
        assert not issues
        robot, events = FakeRobot(), Events()
        leaf = NavigateTo("go", params)
        leaf.setup(context=MissionContext(robot=robot, events=events))
        leaf.tick_once()
        assert leaf.status == Status.FAILURE
        assert "x=" in leaf.feedback_message and "not finite" in leaf.feedback_message
        assert robot.goals == [] and events.of("goal_sent") == []


def test_drive_to_standoff_gives_a_goal_up_after_its_timeout() -> None:
    """A standoff goal past ``goal_timeout`` is cancelled, recorded as a try not reached, and fails."""
    from missiontree.behaviours.approach_steps import DriveToStandoff

    robot = FakeRobot()
    robot.polls_per_goal = 100
    writer = py_trees.blackboard.Client(name="writer")
    for key in ("standoff", "search_candidate", "approach_tries"):
        writer.register_key(key, access=py_trees.common.Access.WRITE)
    writer.standoff = {"x": 1.0, "y": 0.0, "yaw": 0.0}
    writer.search_candidate = {"id": "cup_1", "label": "cup", "x": 1.5, "y": 0.0}
    writer.approach_tries = []
    leaf = DriveToStandoff("drive", DriveToStandoff.Params(goal_timeout=2.0))
    leaf.setup(context=MissionContext(robot=robot))
    leaf.tick_once()
    assert leaf.status == Status.RUNNING
    robot.advance(3.0)
    leaf.tick_once()
    assert leaf.status == Status.FAILURE and "within 2 s" in leaf.feedback_message
    assert robot.goals[0].cancelled and leaf.handle is None
    assert writer.approach_tries[-1]["reached"] is False
