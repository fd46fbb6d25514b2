"""The plugin module the ``missiontree`` entry point names: hook implementations only."""

from __future__ import annotations

from typing import Any

from missiontree.engine.registry import NodeRegistry
from missiontree.plugins.hookspecs import hookimpl
from missiontree_battery.battery import BATTERY
from missiontree_battery.blob import create_colour_blob
from missiontree_battery.nodes import IsBatteryLow


@hookimpl
def missiontree_register_sensors(sensors: dict[str, Any]) -> None:
    """Add the ``battery`` sensor."""
    sensors[BATTERY.name] = BATTERY


@hookimpl
def missiontree_register_nodes(registry: NodeRegistry) -> None:
    """Add the IsBatteryLow condition."""
    registry.add(IsBatteryLow)


@hookimpl
def missiontree_register_model_providers(providers: dict[str, Any]) -> None:
    """Add the ``colour_blob`` detector provider."""
    providers["colour_blob"] = create_colour_blob
