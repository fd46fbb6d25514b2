"""Tests of the builder: a checked mission becomes a real py_trees tree."""

from __future__ import annotations

from pathlib import Path

import py_trees
import pytest

from missiontree.engine.build import build_tree, node_specs_by_behaviour, write_blackboard_defaults
from missiontree.engine.loader import load_mission
from missiontree.engine.nodes import register_nodes
from missiontree.engine.nodes.basic import Wait
from missiontree.engine.nodes.decorators import ClockedTimeout, Guard, RateLimit
from missiontree.engine.ports import BlackboardRef
from missiontree.engine.registry import NodeRegistry
from missiontree.testing import tick_until

REPO = Path(__file__).resolve().parents[2]
Status = py_trees.common.Status
Behaviour = py_trees.behaviour.Behaviour


@pytest.fixture
def registry() -> NodeRegistry:
    reg = NodeRegistry()
    register_nodes(reg)
    return reg


def test_example_builds_real_py_trees_nodes(registry: NodeRegistry) -> None:
    """Composites and decorators are py_trees classes with the written settings."""
    spec = load_mission(REPO / "trees/examples/timer_and_blackboard.yaml", registry)
    root = build_tree(spec, registry)
    assert isinstance(root, py_trees.composites.Sequence) and root.memory is True
    by_name = {node.name: node for node in root.iterate()}
    assert isinstance(by_name["heartbeat_and_timer"], py_trees.composites.Parallel)
    assert isinstance(by_name["heartbeat_and_timer"].policy, py_trees.common.ParallelPolicy.SuccessOnOne)
    assert isinstance(by_name["while_armed"], Guard)
    assert isinstance(by_name["RateLimit"], RateLimit)
    assert isinstance(by_name["Timeout"], ClockedTimeout)
    assert by_name["report"].memory is False


def test_references_stay_references_in_leaf_params(tmp_path: Path, registry: NodeRegistry) -> None:
    """A {bb: key} parameter reaches the leaf unresolved and is read when the leaf starts."""
    path = tmp_path / "m.yaml"
    path.write_text("blackboard: {delay: 0.0}\nroot:\n  Wait: {seconds: {bb: delay}}\n")
    spec = load_mission(path, registry)
    root = build_tree(spec, registry)
    assert isinstance(root, Wait) and root.params.seconds == BlackboardRef("delay")  # type: ignore[attr-defined]
    write_blackboard_defaults(spec)
    root.setup()
    assert tick_until(root) == 1 and root.status == Status.SUCCESS


def test_example_subtree_mission_runs_to_success_on_a_clock(registry: NodeRegistry) -> None:
    """The include example finishes with SUCCESS when ticked on a stepped clock."""
    from missiontree.engine.context import MissionContext
    from missiontree.testing import ClockRobot

    spec = load_mission(REPO / "trees/examples/subtree_include.yaml", registry)
    root = build_tree(spec, registry)
    robot = ClockRobot()
    py_trees.trees.setup(root, context=MissionContext(robot=robot))  # type: ignore[arg-type]
    write_blackboard_defaults(spec)
    for _ in range(100):
        root.tick_once()
        if root.status != Status.RUNNING:
            break
        robot.spin_until(robot.now() + 0.1)
    assert root.status == Status.SUCCESS
    assert 2.5 <= robot.now() <= 3.0  # the slower countdown took 2.5 simulated seconds


def test_specs_map_to_behaviours(registry: NodeRegistry) -> None:
    """Every built behaviour maps back to the NodeSpec (and so the file line) it came from."""
    spec = load_mission(REPO / "trees/examples/subtree_include.yaml", registry)
    root = build_tree(spec, registry)
    mapping = node_specs_by_behaviour(spec, root)
    assert len(mapping) == len(spec.nodes())
    assert mapping[root.id] is spec.root


def test_factory_error_becomes_located_problem(tmp_path: Path, registry: NodeRegistry) -> None:
    """A plugin factory that raises is reported at the node's line, naming the plugin, not as a crash."""
    from pydantic import BaseModel

    from missiontree.engine.registry import NodeType
    from missiontree.errors import MissionFileError

    class NoParams(BaseModel):
        pass

    def broken(name: str, params: BaseModel, children: list[Behaviour]) -> Behaviour:
        raise RuntimeError("driver missing")

    registry.add(NodeType("Broken", "leaf", NoParams, broken, provider="acme"))
    path = tmp_path / "m.yaml"
    path.write_text("root:\n  Sequence:\n    memory: true\n    children: [Succeed, Broken]\n")
    spec = load_mission(path, registry)
    with pytest.raises(MissionFileError) as info:
        build_tree(spec, registry)
    (problem,) = info.value.problems
    assert (problem.line, problem.col) == (4, 25)
    assert "driver missing" in problem.message and "acme" in problem.hint
