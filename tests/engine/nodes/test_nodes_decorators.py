"""Tests of the built-in decorators, timing ones on a stepped robot clock."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import py_trees
import pytest

from missiontree.engine.build import build_tree
from missiontree.engine.context import MissionContext
from missiontree.engine.loader import load_mission
from missiontree.engine.nodes import register_nodes
from missiontree.engine.registry import NodeRegistry
from missiontree.testing import ClockRobot, ScriptedLeaf

Status = py_trees.common.Status
Nodes = dict[str, py_trees.behaviour.Behaviour]


@pytest.fixture
def robot() -> ClockRobot:
    return ClockRobot()


@pytest.fixture
def build(tmp_path: Path, robot: ClockRobot) -> Callable[[str], Nodes]:
    """Build a tree from YAML, set it up on the ClockRobot; behaviours by name (root as 'root')."""
    registry = NodeRegistry()
    register_nodes(registry)
    registry.add(ScriptedLeaf, provider="tests")

    def _build(text: str) -> Nodes:
        path = tmp_path / "m.yaml"
        path.write_text(text)
        root = build_tree(load_mission(path, registry), registry)
        py_trees.trees.setup(root, context=MissionContext(robot=robot))  # type: ignore[arg-type]
        return {"root": root, **{n.name: n for n in root.iterate()}}

    return _build


def test_retry_runs_child_up_to_attempts(build: Callable[[str], Nodes]) -> None:
    """Retry succeeds when a later attempt succeeds, and counts attempts."""
    nodes = build("root:\n  Retry:\n    attempts: 3\n    child:\n"
                  "      ScriptedLeaf: {name: flaky, script: F}\n")
    nodes["root"].tick_once()  # attempt 1 fails -> RUNNING
    nodes["root"].tick_once()  # attempt 2 fails -> RUNNING
    assert nodes["root"].status == Status.RUNNING
    nodes["root"].tick_once()  # attempt 3 fails -> FAILURE
    assert nodes["root"].status == Status.FAILURE


def test_retry_stops_at_a_verdict(build: Callable[[str], Nodes]) -> None:
    """A verdict below a Retry (an answer a new attempt cannot change) fails it at once, quoting it."""
    nodes = build("root:\n  Retry:\n    attempts: 5\n    child:\n"
                  "      ScriptedLeaf: {name: search, script: V, reason: 'not found: nothing left'}\n")
    nodes["root"].tick_once()
    assert nodes["root"].status == Status.FAILURE
    assert nodes["search"].calls.count("initialise") == 1
    assert nodes["root"].feedback_message.endswith("not found: nothing left")


def test_retry_after_a_verdict_forgets_it(build: Callable[[str], Nodes]) -> None:
    """A leaf's verdict lasts until it runs afresh: its next plain failure is retried."""
    nodes = build("root:\n  Retry:\n    attempts: 3\n    child:\n"
                  "      ScriptedLeaf: {name: search, script: VFS, restart: false}\n")
    nodes["root"].tick_once()
    assert nodes["root"].status == Status.FAILURE
    nodes["root"].tick_once()  # a fresh run of the Retry: the leaf fails plainly -> retried
    assert nodes["root"].status == Status.RUNNING
    nodes["root"].tick_once()
    assert nodes["root"].status == Status.SUCCESS


def test_repeat_needs_times_successes(build: Callable[[str], Nodes]) -> None:
    """Repeat succeeds after the child succeeded `times` times."""
    nodes = build("root:\n  Repeat:\n    times: 2\n    child: Succeed\n")
    nodes["root"].tick_once()
    assert nodes["root"].status == Status.RUNNING
    nodes["root"].tick_once()
    assert nodes["root"].status == Status.SUCCESS


def test_timeout_uses_robot_clock(build: Callable[[str], Nodes], robot: ClockRobot) -> None:
    """Timeout fails on simulated time, however little wall time passed, and halts the child."""
    nodes = build("root:\n  Timeout:\n    seconds: 5\n    child: {Running: {name: work}}\n")
    nodes["root"].tick_once()
    robot.spin_until(4.9)
    nodes["root"].tick_once()
    assert nodes["root"].status == Status.RUNNING
    robot.spin_until(5.1)
    nodes["root"].tick_once()
    assert nodes["root"].status == Status.FAILURE
    assert nodes["work"].status == Status.INVALID
    assert "timed out" in nodes["root"].feedback_message


def test_rate_limit_ticks_child_at_most_every_period(
    build: Callable[[str], Nodes], robot: ClockRobot
) -> None:
    """RateLimit ticks its child once per period and repeats the last result in between."""
    nodes = build("root:\n  RateLimit:\n    period: 1.0\n    child:\n"
                  "      ScriptedLeaf: {name: probe, script: S}\n")
    for step in range(25):  # 2.5 s of ticks at 10 Hz
        robot.spin_until(step * 0.1)
        nodes["root"].tick_once()
        assert nodes["root"].status == Status.SUCCESS
    assert nodes["probe"].calls.count("update") == 3  # type: ignore[attr-defined]  # at t=0, 1.0, 2.0


def test_rate_limit_reticks_child_halted_while_running(
    build: Callable[[str], Nodes], robot: ClockRobot
) -> None:
    """A child halted while RUNNING is ticked again at once when the branch is re-entered."""
    nodes = build("root:\n  RateLimit:\n    period: 10.0\n    child:\n"
                  "      ScriptedLeaf: {name: job, script: R}\n")
    nodes["root"].tick_once()
    nodes["root"].stop(Status.INVALID)  # the branch was pre-empted
    nodes["root"].tick_once()
    assert nodes["job"].calls.count("update") == 2  # type: ignore[attr-defined]


def test_guard_halts_child_when_condition_turns_false(build: Callable[[str], Nodes]) -> None:
    """Guard re-checks the blackboard every tick and halts its running child when it fails."""
    nodes = build("blackboard: {battery: 0.9}\nroot:\n  Guard:\n    key: battery\n    op: '>'\n"
                  "    value: 0.2\n"
                  "    child: {Running: {name: work}}\n")
    py_trees.blackboard.Blackboard.set("/battery", 0.9)
    nodes["root"].tick_once()
    assert nodes["work"].status == Status.RUNNING
    py_trees.blackboard.Blackboard.set("/battery", 0.1)
    nodes["root"].tick_once()
    assert nodes["root"].status == Status.FAILURE
    assert nodes["work"].status == Status.INVALID
    assert "battery > 0.2" in nodes["root"].feedback_message


def test_oneshot_runs_child_once(build: Callable[[str], Nodes]) -> None:
    """OneShot keeps returning the child's success without ticking it again."""
    nodes = build("root:\n  OneShot:\n    child:\n      ScriptedLeaf: {name: once, script: S}\n")
    for _ in range(3):
        nodes["root"].tick_once()
    assert nodes["root"].status == Status.SUCCESS
    assert nodes["once"].calls.count("update") == 1  # type: ignore[attr-defined]


@pytest.mark.parametrize(("node", "child", "expected"), [
    ("ForceSuccess", "Fail", Status.SUCCESS),
    ("ForceSuccess", "Running", Status.RUNNING),
    ("ForceFailure", "Succeed", Status.FAILURE),
    ("Inverter", "Fail", Status.SUCCESS),
    ("Inverter", "Succeed", Status.FAILURE),
])
def test_status_shaping_decorators(
    build: Callable[[str], Nodes], node: str, child: str, expected: Status
) -> None:
    """ForceSuccess, ForceFailure and Inverter map the child's status as documented."""
    nodes = build(f"root:\n  {node}:\n    child: {child}\n")
    nodes["root"].tick_once()
    assert nodes["root"].status == expected


def test_guard_compares_with_another_key(build: Callable[[str], Nodes]) -> None:
    """Guard's value may be {bb: key}: the condition compares two blackboard keys each tick."""
    nodes = build("blackboard: {speed: 1, limit: 2}\nroot:\n  Guard:\n    key: speed\n    op: '<'\n"
                  "    value: {bb: limit}\n    child: Running\n")
    py_trees.blackboard.Blackboard.set("/speed", 1)
    py_trees.blackboard.Blackboard.set("/limit", 2)
    nodes["root"].tick_once()
    assert nodes["root"].status == Status.RUNNING
    py_trees.blackboard.Blackboard.set("/limit", 0.5)
    nodes["root"].tick_once()
    assert nodes["root"].status == Status.FAILURE


@pytest.mark.parametrize("node", ["Inverter", "ForceSuccess"])
def test_a_child_failing_by_an_error_is_not_turned_into_success(
        build: Callable[[str], Nodes], node: str) -> None:
    """A child that raised (a fault, not a false condition) stays FAILURE under Inverter and ForceSuccess."""
    nodes = build(f"root:\n  {node}:\n    child:\n      ScriptedLeaf: {{name: broken, script: X}}\n")
    nodes["root"].tick_once()
    assert nodes["root"].status == Status.FAILURE
    assert "error" in nodes["root"].feedback_message


def test_a_fault_is_forgotten_when_the_child_runs_again(build: Callable[[str], Nodes]) -> None:
    """A leaf that raised once and then fails normally is inverted again on its next run."""
    nodes = build("root:\n  Inverter:\n    child:\n"
                  "      ScriptedLeaf: {name: flaky, script: XF, restart: false}\n")
    nodes["root"].tick_once()  # tick 1: raises -> FAILURE with a fault, kept as FAILURE
    assert nodes["root"].status == Status.FAILURE
    nodes["root"].tick_once()  # tick 2: an ordinary FAILURE -> SUCCESS
    assert nodes["root"].status == Status.SUCCESS
