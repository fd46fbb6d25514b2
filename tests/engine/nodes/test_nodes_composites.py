"""Tests of the built-in composites: memory semantics of Sequence/Selector, Parallel policies."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import py_trees
import pytest

from missiontree.engine.build import build_tree
from missiontree.engine.loader import load_mission
from missiontree.engine.nodes import register_nodes
from missiontree.engine.registry import NodeRegistry
from missiontree.testing import ScriptedLeaf

Status = py_trees.common.Status
Build = Callable[[str], dict[str, py_trees.behaviour.Behaviour]]


@pytest.fixture
def build(tmp_path: Path) -> Build:
    """Build a tree from mission YAML; return its behaviours by name (root under 'root')."""
    registry = NodeRegistry()
    register_nodes(registry)
    registry.add(ScriptedLeaf, provider="tests")

    def _build(text: str) -> dict[str, py_trees.behaviour.Behaviour]:
        path = tmp_path / "m.yaml"
        path.write_text(text)
        root = build_tree(load_mission(path, registry), registry)
        root.setup_with_descendants()
        return {"root": root, **{n.name: n for n in root.iterate()}}

    return _build


def test_sequence_with_memory_resumes_running_child(build: Build) -> None:
    """memory: true — the first child is not ticked again while the second runs."""
    nodes = build("root:\n  Sequence:\n    memory: true\n    children:\n"
                  "      - ScriptedLeaf: {name: a, script: S}\n"
                  "      - ScriptedLeaf: {name: b, script: RRS}\n")
    for _ in range(3):
        nodes["root"].tick_once()
    assert nodes["root"].status == Status.SUCCESS
    assert nodes["a"].calls.count("update") == 1  # type: ignore[attr-defined]


def test_sequence_without_memory_rechecks_earlier_children(build: Build) -> None:
    """memory: false — every tick starts from the first child again."""
    nodes = build("root:\n  Sequence:\n    memory: false\n    children:\n"
                  "      - ScriptedLeaf: {name: a, script: S}\n"
                  "      - ScriptedLeaf: {name: b, script: RRS}\n")
    for _ in range(3):
        nodes["root"].tick_once()
    assert nodes["root"].status == Status.SUCCESS
    assert nodes["a"].calls.count("update") == 3  # type: ignore[attr-defined]


def test_selector_without_memory_preempts_lower_priority(build: Build) -> None:
    """A Selector without memory halts the running fallback once the first child succeeds."""
    nodes = build("root:\n  Selector:\n    memory: false\n    children:\n"
                  "      - CheckBlackboard: {key: done, value: true}\n      - Running: {name: work}\n")
    py_trees.blackboard.Blackboard.set("/done", False)
    nodes["root"].tick_once()  # check fails, work runs
    assert nodes["work"].status == Status.RUNNING
    py_trees.blackboard.Blackboard.set("/done", True)
    nodes["root"].tick_once()  # check succeeds: work is halted
    assert nodes["root"].status == Status.SUCCESS
    assert nodes["work"].status == Status.INVALID


def test_parallel_success_on_one(build: Build) -> None:
    """success_on_one finishes with the first child to succeed and halts the others."""
    nodes = build("root:\n  Parallel:\n    policy: success_on_one\n    children:\n"
                  "      - Running: {name: forever}\n      - ScriptedLeaf: {name: quick, script: RS}\n")
    nodes["root"].tick_once()
    assert nodes["root"].status == Status.RUNNING
    nodes["root"].tick_once()
    assert nodes["root"].status == Status.SUCCESS
    assert nodes["forever"].status == Status.INVALID


def test_parallel_success_on_selected_by_name(build: Build) -> None:
    """success_on_selected succeeds once the named children succeed, whatever the others do."""
    nodes = build("root:\n  Parallel:\n    policy: success_on_selected\n    selected: [done]\n    children:\n"
                  "      - Running: {name: forever}\n      - ScriptedLeaf: {name: done, script: RS}\n")
    nodes["root"].tick_once()
    nodes["root"].tick_once()
    assert nodes["root"].status == Status.SUCCESS


def test_parallel_success_on_all_fails_on_any_failure(build: Build) -> None:
    """success_on_all fails as soon as one child fails."""
    nodes = build("root:\n  Parallel:\n    children:\n      - Running\n      - Fail\n")
    nodes["root"].tick_once()
    assert nodes["root"].status == Status.FAILURE
