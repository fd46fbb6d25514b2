"""Tests of missiontree.testing: the clock robot double, the scripted leaf and the helpers."""

from __future__ import annotations

import py_trees
import pytest
import structlog

from missiontree.engine.leaf import Status
from missiontree.errors import BackendError
from missiontree.robot.interface import Robot
from missiontree.testing import (
    ClockRobot,
    ScriptedLeaf,
    capture_tick_log,
    clean_state,
    fresh_plugins,
    tick_until,
)
from missiontree.types import Pose2D


@pytest.fixture(autouse=True)
def _clean() -> None:
    clean_state()


def test_clock_robot_satisfies_the_robot_protocol() -> None:
    """The test double is a Robot (runtime protocol check)."""
    assert isinstance(ClockRobot(), Robot)


def test_clock_robot_clock_only_moves_forward() -> None:
    """spin_until moves the clock forward and never back."""
    robot = ClockRobot(start=2.0)
    robot.spin_until(3.0)
    robot.spin_until(1.0)
    assert robot.now() == 3.0


def test_clock_robot_refuses_navigation() -> None:
    """The double cannot navigate and says to use the simulator."""
    with pytest.raises(BackendError, match="simulator"):
        ClockRobot().navigate_to(Pose2D(0.0, 0.0, 0.0))


def test_scripted_leaf_follows_its_script_and_repeats_the_last_letter() -> None:
    """ScriptedLeaf returns R, R, then S for every later tick of the same run."""
    leaf = ScriptedLeaf("s", script="RRS")
    assert tick_until(leaf, [Status.SUCCESS]) == 3
    assert leaf.calls[:4] == ["initialise", "update", "update", "update"]


def test_tick_until_raises_when_the_status_never_comes() -> None:
    """tick_until gives up with an AssertionError after max_ticks."""
    with pytest.raises(AssertionError, match="still RUNNING after 5 ticks"):
        tick_until(ScriptedLeaf("r", script="R"), max_ticks=5)


def test_capture_tick_log_returns_result_and_lines() -> None:
    """capture_tick_log runs the tree and returns the run result with the parsed lines."""
    result, lines = capture_tick_log(ScriptedLeaf("s", script="S"))
    assert result.status == Status.SUCCESS
    assert [line["event"] for line in lines] == ["mission_started", "tick", "halted", "mission_finished"]


def test_capture_tick_log_bounds_a_tree_that_never_ends() -> None:
    """A forever-running test tree stops at the default 60 s limit instead of hanging."""
    result, _ = capture_tick_log(ScriptedLeaf("r", script="R"), tick_hz=1)
    assert (result.stopped_by, result.ticks) == ("limit", 60)


def test_clean_state_clears_blackboard_and_structlog_context() -> None:
    """clean_state empties the blackboard and structlog's bound context."""
    py_trees.blackboard.Blackboard.set("/left", 1)
    structlog.contextvars.bind_contextvars(mission="old")
    clean_state()
    assert py_trees.blackboard.Blackboard.storage == {}
    assert structlog.contextvars.get_contextvars() == {}


def test_fresh_plugins_gives_independent_managers() -> None:
    """Each call builds a new manager and registry, so tests cannot leak plugin state."""
    first, second = fresh_plugins(), fresh_plugins()
    assert first.pm is not second.pm and first.nodes is not second.nodes
    first.pm.register(object(), name="stray")
    assert second.pm.get_plugin("stray") is None
