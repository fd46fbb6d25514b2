"""The plugin module the ``missiontree`` entry point names: hook implementations only."""

from __future__ import annotations

from missiontree.engine.registry import NodeRegistry
from missiontree.plugins.hookspecs import hookimpl
from missiontree_example.countdown import CountDown


@hookimpl
def missiontree_register_nodes(registry: NodeRegistry) -> None:
    """Add the CountDown leaf."""
    registry.add(CountDown)
