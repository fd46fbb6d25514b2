"""Checked mission spec → a real py_trees tree.

:func:`build_tree` calls each node type's factory bottom-up with the node's name, its validated
parameters (``{bb: key}`` kept as :class:`~missiontree.engine.ports.BlackboardRef`) and its built
children. Nodes are only constructed, not set up: trees build and render with no robot; the
runner calls ``setup(context=...)`` afterwards. :func:`write_blackboard_defaults` writes the
mission's ``blackboard:`` section before the first tick.
"""

from __future__ import annotations

from typing import Any

import py_trees

from missiontree.engine.conditions import attach, parse_conditions
from missiontree.engine.registry import NodeRegistry
from missiontree.engine.spec import MissionSpec, NodeSpec
from missiontree.engine.validate import check_node
from missiontree.errors import MissionFileError, Problem

Behaviour = py_trees.behaviour.Behaviour


def build_tree(spec: MissionSpec, registry: NodeRegistry) -> Behaviour:
    """Build the py_trees tree of a checked mission and return its root.

    Raises:
        MissionFileError: A node cannot be built (only when ``spec`` was not checked against
            ``registry``, or a factory refused its parameters).
    """
    return build_node(spec.root, registry)


def build_node(node: NodeSpec, registry: NodeRegistry) -> Behaviour:
    """Build one node and its subtree."""
    node_type = registry.get(node.type)
    if node.params is None or node_type is None:
        problems = check_node(node, registry)
        if problems:
            raise MissionFileError(problems)
    node_type = registry.get(node.type)
    assert node_type is not None and node.params is not None
    children = [build_node(child, registry) for child in node.children]
    try:
        behaviour = node_type.factory(node.name, node.params, children)
    except MissionFileError as exc:
        raise MissionFileError([_at(node, p.message, p.hint) for p in exc.problems]) from None
    except Exception as exc:  # noqa: BLE001 - a plugin's factory bug becomes a located problem, not a crash
        hint = f"check the parameters of {node.type} (provider {node_type.provider})"
        raise MissionFileError([_at(node, f"cannot build {node.type}: {exc}", hint)]) from exc
    if not isinstance(behaviour, Behaviour):
        message = f"expected {node.type} to build a py_trees behaviour, found {type(behaviour).__name__}"
        raise MissionFileError([_at(node, message, f"fix the plugin {node_type.provider!r}")])
    if node.conditions:
        attach(behaviour, _conditions(node))
    return behaviour


def _conditions(node: NodeSpec) -> Any:
    """The node's parsed conditions (parsed now when the spec was not checked)."""
    if node.prepost is not None:
        return node.prepost
    parsed, errors = parse_conditions(node.conditions)
    if errors:
        raise MissionFileError([_at(node, f"{key}: {error}") for key, error in errors.items()])
    return parsed


def write_blackboard_defaults(spec: MissionSpec) -> None:
    """Write the mission's ``blackboard:`` defaults (call before the first tick)."""
    for key, value in spec.blackboard.items():
        py_trees.blackboard.Blackboard.set(_absolute(key), value)


def _absolute(key: str) -> str:
    return key if key.startswith("/") else f"/{key}"


def _at(node: NodeSpec, message: str, hint: str = "") -> Problem:
    src = node.source
    return Problem(src.file, src.line, src.col, node.path, message, hint)


def node_specs_by_behaviour(spec: MissionSpec, root: Behaviour) -> dict[Any, NodeSpec]:
    """Map each built behaviour's id to the NodeSpec it came from (same depth-first order)."""
    pairs = zip(root.iterate(), _post_order(spec.root), strict=True)
    return {behaviour.id: node for behaviour, node in pairs}


def _post_order(node: NodeSpec) -> list[NodeSpec]:
    # py_trees' Behaviour.iterate() yields children before their parent.
    found: list[NodeSpec] = []
    for child in node.children:
        found.extend(_post_order(child))
    found.append(node)
    return found
