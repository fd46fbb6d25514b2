"""Substitution rules: nodes swapped for stubs by path or type glob, checked at file:line:col."""

from __future__ import annotations

from pathlib import Path

import py_trees
import pytest

from missiontree.engine.build import build_tree
from missiontree.engine.context import MissionContext
from missiontree.engine.loader import load_mission
from missiontree.engine.substitute import apply_rules, load_rules
from missiontree.errors import MissionFileError
from missiontree.testing import ClockRobot, capture_tick_log, clean_state, fresh_plugins

Status = py_trees.common.Status

MISSION = """\
version: 1
blackboard: {visits: 0}
root:
  Sequence:
    name: main
    memory: true
    children:
      - Fail: {name: camera, reason: no camera}
      - Sequence:
          name: drive
          memory: true
          children:
            - Wait: {seconds: 100}
            - Succeed: {name: arrive, on_success: "visits = visits + 1"}
"""


@pytest.fixture(autouse=True)
def _clean() -> None:
    clean_state()


def _tree(tmp_path: Path, rules_text: str) -> tuple[py_trees.behaviour.Behaviour, list, Path]:
    mission = tmp_path / "m.yaml"
    mission.write_text(MISSION)
    rules = tmp_path / "rules.yaml"
    rules.write_text(rules_text)
    registry = fresh_plugins().nodes
    spec = load_mission(mission, registry)
    root, done = apply_rules(spec, build_tree(spec, registry), load_rules(rules))
    return root, done, rules


def test_a_type_glob_replaces_the_node_and_the_mission_goes_on(tmp_path: Path) -> None:
    """`Fail` stubbed to SUCCESS, `Wait` to SUCCESS after 2 s: the mission succeeds in 2 s of robot time."""
    root, done, _ = _tree(tmp_path, "rules:\n  - match: Fail\n    status: SUCCESS\n"
                                   "  - match: Wa*\n    status: SUCCESS\n    after: 2\n")
    assert [(s.node, s.type) for s in done] == [("main/camera", "Fail"), ("main/drive/Wait", "Wait")]
    result, _ = capture_tick_log(root, tick_hz=10, blackboard={"visits": 0})
    assert result.status is Status.SUCCESS
    assert 1.9 <= result.duration <= 2.1


def test_a_path_glob_replaces_a_subtree_and_writes_the_blackboard(tmp_path: Path) -> None:
    """`*/drive` replaces the whole subtree; its writes land on the blackboard when it returns."""
    root, done, _ = _tree(tmp_path, "rules:\n  - match: main/camera\n    status: SUCCESS\n"
                                   "  - match: '*/drive'\n    status: SUCCESS\n    writes: {arrived: true}\n")
    assert [s.node for s in done] == ["main/camera", "main/drive"]
    assert [child.name for child in root.children] == ["camera", "drive"]
    assert not root.children[1].children
    result, _ = capture_tick_log(root, blackboard={"visits": 0})
    assert result.status is Status.SUCCESS
    assert py_trees.blackboard.Blackboard.get("/arrived") is True


def test_a_stub_keeps_the_nodes_conditions(tmp_path: Path) -> None:
    """The replaced node's on_success still runs on the stub (mission logic stays)."""
    root, _, _ = _tree(tmp_path, "rules:\n  - match: Fail\n    status: SUCCESS\n"
                                 "  - match: Wait\n    status: SUCCESS\n"
                                 "  - match: '*/arrive'\n    status: SUCCESS\n")
    capture_tick_log(root, blackboard={"visits": 0})
    assert py_trees.blackboard.Blackboard.get("/visits") == 1


def test_a_rule_that_matches_nothing_is_a_problem_at_its_line(tmp_path: Path) -> None:
    """A misspelt glob names its file:line:col and the nearest node."""
    with pytest.raises(MissionFileError) as caught:
        _tree(tmp_path, "rules:\n  - match: Fail\n    status: SUCCESS\n"
                        "  - match: main/camra\n    status: FAILURE\n")
    problem = caught.value.problems[0]
    assert (Path(problem.file).name, problem.line, problem.col) == ("rules.yaml", 4, 5)
    assert "matching none" in problem.message and "main/camera" in problem.hint


def test_a_rule_inside_a_replaced_subtree_is_a_problem(tmp_path: Path) -> None:
    """A rule whose nodes an earlier rule's replacement removed replaces nothing: reported."""
    with pytest.raises(MissionFileError, match="inside a subtree an earlier rule replaced"):
        _tree(tmp_path, "rules:\n  - match: '*/drive'\n    status: SUCCESS\n"
                        "  - match: Wait\n    status: SUCCESS\n")


def test_bad_rules_are_all_reported_located(tmp_path: Path) -> None:
    """An unknown key, a bad status, a negative delay and a bad key are four located problems."""
    with pytest.raises(MissionFileError) as caught:
        _tree(tmp_path, "rules:\n  - match: Fail\n    stauts: SUCCESS\n  - match: Wait\n    status: DONE\n"
                        "    after: -1\n    writes: {'9x': 1}\n")
    found = [(p.line, p.message.split(",")[0]) for p in caught.value.problems]
    assert [line for line, _ in found] == [3, 5, 6, 7]
    assert "did you mean status?" in caught.value.problems[0].hint


def test_a_stub_counts_its_delay_on_the_robot_clock(tmp_path: Path) -> None:
    """RUNNING until `after` has passed on the robot's clock, however fast it is ticked."""
    root, _, _ = _tree(tmp_path, "rules:\n  - match: Fail\n    status: FAILURE\n    after: 5\n")
    robot = ClockRobot()
    stub = root.children[0]
    stub.setup(context=MissionContext(robot=robot))
    for _ in range(3):
        stub.tick_once()
        assert stub.status is Status.RUNNING
    robot.time = 5.0
    stub.tick_once()
    assert stub.status is Status.FAILURE and "substituted Fail" in stub.feedback_message


def test_add_to_final_state_keeps_what_the_runner_said_before() -> None:
    """A key added to a runner's final state comes after, and beside, what its earlier callback said."""
    from types import SimpleNamespace

    from missiontree.engine.substitute import add_to_final_state

    runner = SimpleNamespace(final_state=lambda: {"a": 1})
    add_to_final_state(runner, "b", [2])
    assert runner.final_state() == {"a": 1, "b": [2]}
    bare = SimpleNamespace(final_state=None)
    add_to_final_state(bare, "b", 3)
    assert bare.final_state() == {"b": 3}
