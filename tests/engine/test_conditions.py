"""Tests of pre- and post-conditions on nodes and the Script leaves, on small trees (BT.CPP 4 semantics)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import py_trees
import pytest

from missiontree.engine.build import build_tree, write_blackboard_defaults
from missiontree.engine.faults import fault_of
from missiontree.engine.loader import check_mission, load_mission
from missiontree.engine.nodes import register_nodes
from missiontree.engine.registry import NodeRegistry
from missiontree.testing import ScriptedLeaf, capture_tick_log, clean_state

Status = py_trees.common.Status
Behaviour = py_trees.behaviour.Behaviour


@pytest.fixture(autouse=True)
def _clean() -> None:
    clean_state()


@pytest.fixture
def registry() -> NodeRegistry:
    reg = NodeRegistry()
    register_nodes(reg)
    reg.add(ScriptedLeaf)
    return reg


def _build(tmp_path: Path, registry: NodeRegistry, text: str) -> tuple[Behaviour, dict[str, Any]]:
    path = tmp_path / "m.yaml"
    path.write_text(text)
    spec = load_mission(path, registry)
    root = build_tree(spec, registry)
    write_blackboard_defaults(spec)
    root.setup()
    return root, {node.name: node for node in root.iterate()}


def _bb(key: str) -> Any:
    return py_trees.blackboard.Blackboard.get(f"/{key}")


def _tree(*children: str, blackboard: str = "{a: 1, n: 0, done: 0}") -> str:
    lines = "".join(f"      - {child}\n" for child in children)
    return f"blackboard: {blackboard}\nroot:\n  Sequence:\n    memory: true\n    children:\n{lines}"


def test_skip_if_true_skips_the_node_as_success(tmp_path: Path, registry: NodeRegistry) -> None:
    """skip_if true: the node is not ticked, returns SUCCESS, and its post-conditions do not run."""
    root, nodes = _build(tmp_path, registry, _tree(
        'ScriptedLeaf: {name: x, script: F, skip_if: "a == 1", post: "done = 1"}', "Script: {code: 'n = 5'}"))
    root.tick_once()
    assert nodes["x"].calls == [] and nodes["x"].status == Status.SUCCESS
    assert "skip_if: `a == 1` is true, skipped" in nodes["x"].feedback_message
    assert root.status == Status.SUCCESS and _bb("n") == 5 and _bb("done") == 0


def test_fail_if_and_succeed_if_decide_without_ticking_and_run_post(tmp_path: Path,
                                                                     registry: NodeRegistry) -> None:
    """fail_if true gives FAILURE, succeed_if true SUCCESS, unticked; on_failure/on_success run (BT.CPP)."""
    root, nodes = _build(tmp_path, registry, _tree(
        'ScriptedLeaf: {name: s, script: F, succeed_if: "a > 0", on_success: "n = n + 1"}',
        'ScriptedLeaf: {name: f, script: S, fail_if: "a == 1", on_failure: "done := 7"}'))
    root.tick_once()
    assert nodes["s"].calls == [] and nodes["s"].status == Status.SUCCESS and _bb("n") == 1
    assert nodes["f"].calls == [] and nodes["f"].status == Status.FAILURE and _bb("done") == 7
    assert nodes["f"].failure_reason == "fail_if: `a == 1` is true, not ticked"
    assert root.status == Status.FAILURE and fault_of(root) is None  # a condition, not an error


def test_fail_if_is_checked_before_succeed_if_and_skip_if(tmp_path: Path, registry: NodeRegistry) -> None:
    """With several pre-conditions true, BT.CPP's order holds: fail_if, then succeed_if, then skip_if."""
    root, nodes = _build(tmp_path, registry, _tree(
        'Succeed: {name: x, skip_if: "true", succeed_if: "true", fail_if: "a == 1"}'))
    root.tick_once()
    assert nodes["x"].status == Status.FAILURE


def test_while_false_before_start_fails_without_ticking(tmp_path: Path, registry: NodeRegistry) -> None:
    """A false while on a node not running: not ticked, FAILURE (BT.CPP: SKIPPED), no post-conditions."""
    root, nodes = _build(tmp_path, registry, _tree(
        'ScriptedLeaf: {name: x, script: S, while: "a == 2", post: "done = 1"}'))
    root.tick_once()
    assert nodes["x"].calls == [] and nodes["x"].status == Status.FAILURE and _bb("done") == 0


def test_while_turning_false_halts_a_running_node(tmp_path: Path, registry: NodeRegistry) -> None:
    """A while turning false on a RUNNING node halts the node (on_halted runs) and it ends FAILURE."""
    root, nodes = _build(tmp_path, registry, _tree(
        'ScriptedLeaf: {name: x, script: R, while: "a == 1", on_halted: "done = 3", post: "n = 9"}'))
    root.tick_once()
    root.tick_once()
    assert nodes["x"].status == Status.RUNNING and nodes["x"].calls.count("update") == 2
    py_trees.blackboard.Blackboard.set("/a", 2)
    root.tick_once()
    assert nodes["x"].calls[-1] == "terminate:INVALID" and nodes["x"].calls.count("update") == 2
    assert nodes["x"].status == Status.FAILURE and _bb("done") == 3 and _bb("n") == 0
    assert "while: `a == 1` became false, halted" in nodes["x"].failure_reason


def test_while_true_lets_a_running_node_go_on(tmp_path: Path, registry: NodeRegistry) -> None:
    """A while that stays true: the node is ticked each time until it finishes, then post runs."""
    root, nodes = _build(tmp_path, registry, _tree(
        'ScriptedLeaf: {name: x, script: RRS, while: "a == 1", post: "n += 1"}'))
    for _ in range(3):
        root.tick_once()
    assert nodes["x"].status == Status.SUCCESS and nodes["x"].calls.count("update") == 3 and _bb("n") == 1


def test_on_halted_runs_when_a_parent_halts_the_node(tmp_path: Path, registry: NodeRegistry) -> None:
    """A running node halted by its parent runs on_halted, not on_failure or post."""
    text = ("blackboard: {stop: false, halted: 0, n: 0}\nroot:\n  Selector:\n    memory: false\n"
            "    children:\n"
            '      - ScriptCondition: {code: "stop"}\n'
            '      - ScriptedLeaf: {name: x, script: R, on_halted: "halted = 1", post: "n = 1"}\n')
    root, nodes = _build(tmp_path, registry, text)
    root.tick_once()
    py_trees.blackboard.Blackboard.set("/stop", True)
    root.tick_once()
    assert nodes["x"].status == Status.INVALID and _bb("halted") == 1 and _bb("n") == 0


def test_post_conditions_after_a_tick(tmp_path: Path, registry: NodeRegistry) -> None:
    """on_success after SUCCESS, on_failure after FAILURE, post after either (after the on_ script)."""
    text = ("blackboard: {a: 0, b: 0, c: 0}\nroot:\n  Sequence:\n    memory: true\n    children:\n"
            '      - Succeed: {on_success: "a = 1", on_failure: "a = -1", post: "c = a * 10"}\n'
            '      - ForceSuccess:\n          child: {Fail: {on_failure: "b = 2", post: "c = c + b"}}\n')
    root, _ = _build(tmp_path, registry, text)
    root.tick_once()
    assert root.status == Status.SUCCESS and (_bb("a"), _bb("b"), _bb("c")) == (1, 2, 12)


def test_condition_that_cannot_be_evaluated_is_a_fault(tmp_path: Path, registry: NodeRegistry) -> None:
    """A key of the wrong type fails the node with a fault naming why; ForceSuccess keeps it FAILURE."""
    root, nodes = _build(tmp_path, registry, _tree(
        "Script: {code: \"level = 'low'\"}",  # written at run time: the check before the run cannot see it
        'ForceSuccess: {child: {ScriptedLeaf: {name: x, skip_if: "level < 0.2"}}}'))
    root.tick_once()
    assert nodes["x"].calls == [] and root.status == Status.FAILURE
    found = fault_of(root)
    assert found is not None and found[0] is nodes["x"] and "expects two numbers or two texts" in found[1]


def test_post_assignment_that_fails_is_a_fault(tmp_path: Path, registry: NodeRegistry) -> None:
    """A post-condition that cannot be evaluated turns the node's SUCCESS into a faulted FAILURE."""
    root, nodes = _build(tmp_path, registry, _tree('Succeed: {name: x, post: "n = n / 0"}'))
    root.tick_once()
    assert nodes["x"].status == Status.FAILURE
    assert fault_of(root) == (nodes["x"], "post: division by zero (0 / 0)")


def test_script_and_script_condition_leaves(tmp_path: Path, registry: NodeRegistry) -> None:
    """Script assigns and succeeds; ScriptCondition succeeds on true, fails on false, faults on errors."""
    root, nodes = _build(tmp_path, registry, _tree(
        "Script: {code: 'n := n + 2; label = \"at \" + \"dock\"'}",
        'ScriptCondition: {name: holds, code: "n == 2 and label == \'at dock\'"}',
        'ScriptCondition: {name: fails, code: "n > 2"}'))
    root.tick_once()
    assert _bb("n") == 2 and nodes["holds"].status == Status.SUCCESS
    assert nodes["fails"].status == Status.FAILURE and nodes["fails"].failure_reason == "`n > 2` is false"
    assert fault_of(root) is None


def test_conditions_on_a_composite(tmp_path: Path, registry: NodeRegistry) -> None:
    """A condition on a composite skips its whole subtree."""
    text = ("blackboard: {a: 1, n: 0}\nroot:\n  Sequence:\n    memory: true\n    skip_if: 'a == 1'\n"
            "    children:\n      - Script: {code: 'n = 1'}\n")
    root, _ = _build(tmp_path, registry, text)
    root.tick_once()
    assert root.status == Status.SUCCESS and _bb("n") == 0


def test_tick_log_records_the_condition_reason(tmp_path: Path, registry: NodeRegistry) -> None:
    """The tick log's entry for a node decided by a condition carries why (reason on FAILURE, feedback)."""
    root, _ = _build(tmp_path, registry, _tree(
        'Succeed: {name: skipped, skip_if: "a == 1"}', 'Succeed: {name: failed, fail_if: "a == 1"}'))
    _, lines = capture_tick_log(root)
    changed = {c["node"].rsplit("/", 1)[-1]: c for line in lines if line["event"] == "tick"
               for c in line["changed"]}
    assert changed["failed"]["reason"] == "fail_if: `a == 1` is true, not ticked"
    assert changed["skipped"]["status"] == "SUCCESS"
    assert changed["skipped"]["feedback"] == "skip_if: `a == 1` is true, skipped"


def test_bad_expression_is_reported_at_file_line_col(tmp_path: Path, registry: NodeRegistry) -> None:
    """A refused part of an expression is reported at its own column in the mission file."""
    path = tmp_path / "m.yaml"
    path.write_text("blackboard: {a: 1}\nroot:\n  Succeed:\n    skip_if: a > 1 and open(a)\n"
                    "    post: \"a = a.b\"\n")
    _, problems = check_mission(path, registry)
    shown = [f"{p.line}:{p.col}: {p.message}" for p in problems]
    assert any(s.startswith("4:24: skip_if:") and "function call" in s for s in shown), shown
    assert any(s.startswith("5:16: post:") and "attribute access" in s for s in shown), shown


def test_unknown_key_is_reported_with_a_suggestion(tmp_path: Path, registry: NodeRegistry) -> None:
    """A key that nothing sets or writes is a problem before the run, with the nearest known key."""
    path = tmp_path / "m.yaml"
    path.write_text("blackboard: {battery: 1.0}\nroot:\n  Sequence:\n    memory: true\n    children:\n"
                    "      - Script: {code: 'visits = 0'}\n"
                    "      - Succeed: {skip_if: 'batery < 0.2 or visits > 3'}\n")
    _, problems = check_mission(path, registry)
    assert len(problems) == 1, problems
    problem = problems[0]
    assert (problem.line, problem.col) == (7, 29)  # at the misspelt key inside the quoted expression
    assert "'batery'" in problem.message and "battery" in problem.hint


def test_keys_assigned_by_scripts_satisfy_bb_references(tmp_path: Path, registry: NodeRegistry) -> None:
    """A {bb: key} that only a Script or post writes is not reported as dangling."""
    path = tmp_path / "m.yaml"
    path.write_text("root:\n  Sequence:\n    memory: true\n    children:\n"
                    "      - Succeed: {post: 'delay = 0.0'}\n      - Wait: {seconds: {bb: delay}}\n")
    _, problems = check_mission(path, registry)
    assert problems == []


def test_bad_script_code_is_a_problem(tmp_path: Path, registry: NodeRegistry) -> None:
    """Script code off the whitelist is refused at its `code:` value."""
    path = tmp_path / "m.yaml"
    path.write_text("root:\n  Script: {code: 'x = __import__(\"os\")'}\n")
    _, problems = check_mission(path, registry)
    assert len(problems) == 1 and problems[0].line == 2 and "function call" in problems[0].message


def test_schema_accepts_conditions_and_script_leaves(registry: NodeRegistry) -> None:
    """The schema takes the condition keys on any node and the Script leaves; unknown keys still fail."""
    jsonschema = pytest.importorskip("jsonschema")
    from missiontree.engine.schema import mission_schema

    schema = mission_schema(registry)
    jsonschema.Draft202012Validator.check_schema(schema)
    check = jsonschema.Draft202012Validator(schema)
    mission = {"blackboard": {"a": 1}, "root": {"Sequence": {
        "memory": True, "skip_if": "a > 1", "while": True, "children": [
            {"Succeed": {"fail_if": "a == 2", "succeed_if": "false", "on_success": "a = 2",
                         "on_failure": "a := 3", "on_halted": "a = 4", "post": "a += 1"}},
            {"Script": {"code": "a = a + 1"}}, {"ScriptCondition": {"code": "a > 0"}}]}}}
    assert list(check.iter_errors(mission)) == []
    bad = {"root": {"Succeed": {"skip_iff": "a > 1"}}}
    assert list(check.iter_errors(bad)) != []


def test_conditions_hold_under_the_runner_with_watched_large_composites(tmp_path: Path,
                                                                         registry: NodeRegistry) -> None:
    """Children of a large composite (whose halts the recorder watches) keep their conditions in a run."""
    children = [f"Script: {{name: s{i}, code: 'n += 1', skip_if: 'n >= 5'}}" for i in range(20)]
    root, _ = _build(tmp_path, registry, _tree(*children))
    result, lines = capture_tick_log(root)
    assert result.status == Status.SUCCESS and _bb("n") == 5
    skipped = [c for line in lines if line["event"] == "tick" for c in line["changed"]
               if c.get("feedback") == "skip_if: `n >= 5` is true, skipped"]
    assert len(skipped) == 15


def test_type_mismatch_with_fixed_defaults_is_reported_before_the_run(tmp_path: Path,
                                                                       registry: NodeRegistry) -> None:
    """An expression over keys only the defaults set fails the check as it would fail at run time."""
    path = tmp_path / "m.yaml"
    path.write_text("blackboard: {level: low, n: 0}\nroot:\n  Sequence:\n    memory: true\n    children:\n"
                    "      - Succeed: {skip_if: 'level < 0.2'}\n"
                    "      - Script: {code: 'n = n + 1'}\n      - ScriptCondition: {code: 'n < 0.2'}\n")
    _, problems = check_mission(path, registry)
    assert [(p.line, "type" in p.message or "two numbers" in p.message) for p in problems] == [(6, True)]


def test_conditions_on_an_include_go_on_the_subtree_root(tmp_path: Path, registry: NodeRegistry) -> None:
    """An Include's skip_if applies to the subtree's root; problems are reported in the including file."""
    (tmp_path / "sub.yaml").write_text("root:\n  Script: {code: 'n = 1', post: 'done = 1'}\n")
    root, _ = _build(tmp_path, registry, _tree("Include: {file: sub.yaml, skip_if: 'a == 1'}"))
    root.tick_once()
    assert root.status == Status.SUCCESS and _bb("n") == 0 and _bb("done") == 0
    path = tmp_path / "bad.yaml"
    path.write_text("blackboard: {a: 1}\nroot:\n  Include: {file: sub.yaml, skip_if: 'a.b', post: 'n = 2'}\n")
    _, problems = check_mission(path, registry)
    assert [(p.file, p.line, p.col) for p in problems] == [(str(path), 3, 39), (str(path), 3, 45)]
    assert "attribute access" in problems[0].message and "found both" in problems[1].message


def _log(tmp_path: Path, registry: NodeRegistry, text: str) -> list[dict[str, Any]]:
    path = tmp_path / "m.yaml"
    path.write_text(text)
    spec = load_mission(path, registry)
    _, lines = capture_tick_log(build_tree(spec, registry), blackboard=spec.blackboard)
    return lines


def test_the_tick_log_records_each_nodes_conditions_as_the_run_starts(tmp_path: Path,
                                                                       registry: NodeRegistry) -> None:
    """A `conditions` event names the node's path and every condition's text; mission_started stays first."""
    lines = _log(tmp_path, registry, _tree('Succeed: {name: x, skip_if: "a == 1", on_success: "n := n + 1"}'))
    assert lines[0]["event"] == "mission_started"
    (event,) = [line for line in lines if line["event"] == "conditions"]
    assert event["node"] == "Sequence/x"
    assert event["conditions"] == {"skip_if": "a == 1", "on_success": "n := n + 1"}


def test_a_condition_that_decides_gives_its_reason_once(tmp_path: Path, registry: NodeRegistry) -> None:
    """A skip decided on every tick of a Selector without memory is one `condition` event with its reason."""
    text = ("blackboard: {a: 1}\nroot:\n  Sequence:\n    memory: true\n    children:\n"
            "      - Repeat:\n          times: 5\n          child:\n"
            "            Succeed: {name: x, skip_if: a == 1}\n")
    lines = _log(tmp_path, registry, text)
    decided = [line for line in lines if line["event"] == "condition"]
    assert len(decided) == 1
    assert decided[0]["node"] == "Sequence/Repeat/x" and decided[0]["status"] == "SUCCESS"
    assert decided[0]["key"] == "skip_if" and decided[0]["expression"] == "a == 1"
    assert decided[0]["reason"] == "skip_if: `a == 1` is true, skipped"
