"""Every pluggy hook missiontree calls — the whole plugin contract, in one module.

A plugin is a module (usually its own distribution) with functions named like the hooks
below, each marked ``@missiontree.plugins.hookspecs.hookimpl``, advertised under the entry
point group ``missiontree``::

    [project.entry-points.missiontree]
    my_plugin = "my_package.plugin"

missiontree's own node types, backends and providers register through these same hooks
(:mod:`missiontree.plugins.builtin`). Entry-point autoloading is switched off with the
environment variable ``MISSIONTREE_DISABLE_PLUGIN_AUTOLOAD=1`` or ``--no-plugins``.

Per-tick observation is not a hook: the runner's tick log visitor does it (a hook call per
tick per plugin would be on the hot path).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import pluggy

if TYPE_CHECKING:
    from missiontree.engine.registry import NodeRegistry

PROJECT = "missiontree"
ENTRY_POINT_GROUP = "missiontree"

hookspec = pluggy.HookspecMarker(PROJECT)
hookimpl = pluggy.HookimplMarker(PROJECT)


@hookspec
def missiontree_register_nodes(registry: NodeRegistry) -> None:
    """Add node types to ``registry`` with ``registry.add(LeafClass)`` or ``registry.add(NodeType(...))``.

    Called once when the plugin manager starts. A name already taken is an error that names
    both providers.
    """


@hookspec
def missiontree_register_backends(backends: dict[str, Any]) -> None:
    """Add robot backends: ``backends["name"] = factory``.

    ``factory(options: dict) -> Robot``, where options holds at least ``world``, ``robot``,
    ``seed`` and ``config`` (the CLI's ``--world``, ``--seed``, ``--config``), and ``sensors`` (the
    plugins' :class:`~missiontree.robot.sensors.SensorKind` list) when plugins registered sensors.
    Heavy imports (rclpy) belong inside the factory, so listing backends costs nothing.
    """


@hookspec
def missiontree_register_model_providers(providers: dict[str, Any]) -> None:
    """Add model providers: ``providers["name"] = factory``.

    ``factory(options: dict) -> provider`` where options are the provider's section of a
    models config (config/models/*.yaml). A provider implements one of the model protocols
    (Detector, VisionLanguageModel, LanguageModel, Embedder). Import vendor SDKs inside the
    factory.
    """


@hookspec
def missiontree_register_sensors(sensors: dict[str, Any]) -> None:
    """Add sensor kinds: ``sensors["name"] = SensorKind(...)`` (:mod:`missiontree.robot.sensors`).

    A kind names its value type, how the ROS 2 backend gets it (topic, message type, QoS, pure
    conversions) and how the simulator produces it (a model fed the simulator's state, time and
    motion, configured by the world file's ``plugins:`` section). Leaves read it with
    ``robot.sensor(name)``; the built-in ``SensorCondition``/``WaitForSensor`` test its numbers.
    """


@hookspec
def missiontree_mission_started(context: Any, mission: Any) -> None:
    """Called once before the first tick, with the MissionContext and the checked mission spec."""


@hookspec
def missiontree_mission_finished(context: Any, summary: dict[str, Any]) -> None:
    """Called once after the tree was halted and the robot stopped, with the run's summary."""
