"""The built-in node types: composites, decorators and the blackboard and utility leaves.

They register through the same ``missiontree_register_nodes`` hook as any plugin's nodes
(:mod:`missiontree.plugins.builtin` calls :func:`register_nodes`).
"""

from __future__ import annotations

from missiontree.engine.nodes.basic import Fail, Running, Succeed, Wait
from missiontree.engine.nodes.blackboard import CheckBlackboard, SetBlackboard, WaitForBlackboard
from missiontree.engine.nodes.composites import COMPOSITES
from missiontree.engine.nodes.decorators import DECORATORS
from missiontree.engine.nodes.script import ScriptCondition, ScriptLeaf
from missiontree.engine.registry import NodeRegistry, NodeType

LEAVES = [SetBlackboard, CheckBlackboard, WaitForBlackboard, Wait, Succeed, Fail, Running]


def register_nodes(registry: NodeRegistry) -> None:
    """Add every built-in node type to ``registry`` (provider ``builtin``)."""
    for node_type in [*COMPOSITES, *DECORATORS]:
        registry.add(node_type)
    for leaf in LEAVES:
        registry.add(leaf, provider="builtin")
    registry.add(NodeType.from_leaf(ScriptLeaf, name="Script"))
    registry.add(ScriptCondition, provider="builtin")


__all__ = ["LEAVES", "register_nodes"]
