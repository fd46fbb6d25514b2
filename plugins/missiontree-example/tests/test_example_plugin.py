"""Tests of the example plugin: its leaf counts down and it registers through the entry point."""

from __future__ import annotations

import py_trees
import pytest
from missiontree_example.countdown import CountDown

from missiontree.engine.leaf import Status
from missiontree.testing import capture_tick_log, clean_state, fresh_plugins


@pytest.fixture(autouse=True)
def _clean() -> None:
    clean_state()


def test_countdown_runs_then_succeeds_writing_ticks_left() -> None:
    """CountDown(ticks=2) is RUNNING twice, then succeeds; the blackboard shows what was left."""
    leaf = CountDown("count", CountDown.Params(ticks=2, remaining="left"))
    leaf.setup()
    leaf.tick_once()  # left 2 -> RUNNING
    assert leaf.status == Status.RUNNING
    leaf.tick_once()  # left 1 -> RUNNING
    assert py_trees.blackboard.Blackboard.get("/left") == 1
    leaf.tick_once()  # left 0 -> SUCCESS
    assert leaf.status == Status.SUCCESS
    assert py_trees.blackboard.Blackboard.get("/left") == 0


def test_countdown_fails_with_reason_at_fail_at() -> None:
    """fail_at makes the leaf fail with a reason the tick log records."""
    leaf = CountDown("count", CountDown.Params(ticks=3, fail_at=1))
    result, lines = capture_tick_log(leaf)
    assert result.status == Status.FAILURE
    reasons = [c.get("reason") for line in lines for c in line.get("changed", []) if c["status"] == "FAILURE"]
    assert reasons == ["count stopped at 1 (fail_at)"]


def test_entry_point_registers_countdown_as_example() -> None:
    """The installed distribution's entry point provides CountDown under the plugin name 'example'."""
    plugins = fresh_plugins(autoload=True)
    node_type = plugins.nodes.get("CountDown")
    assert node_type is not None
    assert node_type.provider == "example"
    assert plugins.provided_by("nodes", "CountDown") == "example"


def test_no_autoload_leaves_countdown_out() -> None:
    """With autoloading off the plugin's node type is not known."""
    assert "CountDown" not in fresh_plugins(autoload=False).nodes
