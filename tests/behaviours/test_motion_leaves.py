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
