"""Tests of the built-in leaves: blackboard set/check/wait, Wait on the mission clock, Fail."""

from __future__ import annotations

import py_trees
import pytest

from missiontree.engine.context import MissionContext
from missiontree.engine.nodes.basic import Fail, Wait
from missiontree.engine.nodes.blackboard import CheckBlackboard, SetBlackboard, WaitForBlackboard
from missiontree.engine.nodes.conditions import MISSING, evaluate
from missiontree.engine.ports import BlackboardRef
from missiontree.testing import ClockRobot

Status = py_trees.common.Status
BB = py_trees.blackboard.Blackboard


def test_wait_counts_robot_clock_seconds() -> None:
    """Wait succeeds after its seconds have passed on the robot's clock."""
    robot = ClockRobot()
    leaf = Wait("pause", Wait.Params(seconds=2))
    leaf.setup(context=MissionContext(robot=robot))  # type: ignore[arg-type]
    leaf.tick_once()
    robot.spin_until(1.9)
    leaf.tick_once()
    assert leaf.status == Status.RUNNING
    robot.spin_until(2.0)
    leaf.tick_once()
    assert leaf.status == Status.SUCCESS


def test_set_blackboard_copies_referenced_key() -> None:
    """SetBlackboard with value {bb: other} copies the other key's current value."""
    BB.set("/source", [1, 2])
    leaf = SetBlackboard("copy", SetBlackboard.Params(key="target", value=BlackboardRef("source")))
    leaf.tick_once()
    assert leaf.status == Status.SUCCESS and BB.get("/target") == [1, 2]


@pytest.mark.parametrize(("fields", "stored", "expected"), [
    ({"key": "k", "value": 3}, 3, Status.SUCCESS),
    ({"key": "k", "op": ">", "value": 5}, 3, Status.FAILURE),
    ({"key": "k", "op": "in", "value": ["a", "b"]}, "a", Status.SUCCESS),
    ({"key": "k"}, 0, Status.SUCCESS),  # no op, no value: the key is set
    ({"key": "k", "op": "unset"}, MISSING, Status.SUCCESS),
    ({"key": "k", "op": "<", "value": 1}, "text", Status.FAILURE),  # incomparable: false, not an error
])
def test_check_blackboard(fields: dict[str, object], stored: object, expected: Status) -> None:
    """CheckBlackboard applies its operator to the stored value."""
    if stored is not MISSING:
        BB.set("/k", stored)
    leaf = CheckBlackboard("check", CheckBlackboard.Params(**fields))  # type: ignore[arg-type]
    leaf.tick_once()
    assert leaf.status == expected


def test_wait_for_blackboard_runs_until_condition_holds() -> None:
    """WaitForBlackboard stays RUNNING until the key takes the value."""
    leaf = WaitForBlackboard("wait", WaitForBlackboard.Params(key="door", value="open"))
    leaf.tick_once()
    assert leaf.status == Status.RUNNING and "waiting" in leaf.feedback_message
    BB.set("/door", "open")
    leaf.tick_once()
    assert leaf.status == Status.SUCCESS


def test_fail_records_reason() -> None:
    """Fail fails with its reason as the failure reason."""
    leaf = Fail("stop", Fail.Params(reason="battery low"))
    leaf.tick_once()
    assert leaf.status == Status.FAILURE and leaf.failure_reason == "battery low"


def test_evaluate_explains_incomparable_values() -> None:
    """A comparison between text and a number is false with the reason."""
    holds, reason = evaluate("<", "text", 1)
    assert not holds and "cannot compare" in reason
