"""missiontree's own plugin: built-in node types, model providers and robot backends.

It registers through the same hooks as any plugin (no private path for built-ins), but the plugin
manager adds it directly rather than through an entry point, so switching autoloading off keeps the
built-ins.

Everything it pulls in is listed here, in one place:

- :data:`NODE_MODULES`: modules exposing ``register_nodes(registry)`` (the engine's own nodes,
  cheap to import).
- :data:`LAZY_NODE_TYPES`: the behaviour leaves, node type name → ``"module:attribute"``, imported
  only when a mission (or a listing) asks for that type: a patrol does not import exploration's
  numba kernels, the scene graph's scipy or the search's OpenCV code.
- :data:`PROVIDER_MODULES`: modules exposing ``register_providers(providers)``.
- :data:`BACKENDS`: backend name → ``"module:function"``, resolved only when a run asks for that
  backend (so listing backends never imports rclpy), see :func:`resolve_factory`.
- :data:`MISSION_HOOK_MODULES`: modules whose ``missiontree_mission_started`` /
  ``missiontree_mission_finished`` hook implementations run for every mission (each decides
  whether the mission concerns it, e.g. the ROS 2 backend mirrors events to topics only when the
  robot is a Ros2Robot, and imports rclpy only then).
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from types import ModuleType
from typing import TYPE_CHECKING, Any

from missiontree.errors import BackendUnavailableError, PluginError
from missiontree.plugins.hookspecs import hookimpl

if TYPE_CHECKING:
    from missiontree.engine.registry import NodeRegistry

#: Modules whose ``register_nodes(registry)`` adds built-in node types.
NODE_MODULES: list[str] = [
    "missiontree.engine.nodes",
    "missiontree.engine.nodes.sensors",  # SensorCondition, WaitForSensor: any numeric plugin sensor
]

#: The behaviour leaves (what :func:`missiontree.behaviours.register_nodes` adds), registered by
#: name and imported when first asked for (:meth:`~missiontree.engine.registry.NodeRegistry.add_lazy`).
LAZY_NODE_TYPES: dict[str, str] = {
    "NavigateTo": "missiontree.behaviours.motion:NavigateTo",
    "Rotate": "missiontree.behaviours.motion:Rotate",
    "Patrol": "missiontree.behaviours.patrol:Patrol",
    "FleetPatrol": "missiontree.behaviours.fleet_patrol:FleetPatrol",
    "FleetExplore": "missiontree.behaviours.fleet_explore:FleetExplore",
    "FleetLocate": "missiontree.behaviours.fleet_search:FleetLocate",
    "FleetFound": "missiontree.behaviours.fleet_search:FleetFound",
    "FleetSearchWatch": "missiontree.behaviours.fleet_search:FleetSearchWatch",
    "FleetBuildSceneGraph": "missiontree.behaviours.fleet_scene:FleetBuildSceneGraph",
    "Surveillance": "missiontree.behaviours.surveillance:Surveillance",
    "ServoToTarget": "missiontree.behaviours.servo:ServoToTarget",
    "ReadIntent": "missiontree.behaviours.intent:ReadIntent",
    "ChooseIntentTarget": "missiontree.behaviours.intent_choose:ChooseIntentTarget",
    "ServeIntent": "missiontree.behaviours.intent_choose:ServeIntent",
    "ServeCommands": "missiontree.behaviours.commands:SERVE_COMMANDS",
    "Explore": "missiontree.behaviours.explore:Explore",
    "BuildSceneGraph": "missiontree.behaviours.scene:BuildSceneGraph",
    "LookAgain": "missiontree.behaviours.scene_look:LookAgain",
    "ScanRotate": "missiontree.behaviours.search:ScanRotate",
    "ColourAttention": "missiontree.behaviours.search:ColourAttention",
    "ResumeExplore": "missiontree.behaviours.search:ResumeExplore",
    "Locate": "missiontree.behaviours.search:Locate",
    "Approach": "missiontree.behaviours.search:Approach",
    "Verify": "missiontree.behaviours.search:Verify",
    "PlanStandoff": "missiontree.behaviours.approach_steps:PlanStandoff",
    "DriveToStandoff": "missiontree.behaviours.approach_steps:DriveToStandoff",
    "FaceTarget": "missiontree.behaviours.approach_steps:FaceTarget",
    "PlaceByDepth": "missiontree.behaviours.confirm_steps:PlaceByDepth",
    "LookFor": "missiontree.behaviours.confirm_steps:LookFor",
    "ConfirmTarget": "missiontree.behaviours.confirm_steps:ConfirmTarget",
}

#: Modules whose ``register_providers(providers)`` adds built-in model providers.
PROVIDER_MODULES: list[str] = [
    "missiontree.reasoning.providers",
    "missiontree.perception.providers",
]

#: Backend name → ``"module:function"`` of its ``factory(options) -> Robot``.
BACKENDS: dict[str, str] = {
    "sim": "missiontree.backends.sim:create_robot",
    "ros2": "missiontree.backends.ros2:create_robot",
    # a recording played through the robot interface (--world RECORDING.rawlog); motion is refused
    "recorded": "missiontree.backends.recorded:create_robot",
}

#: Modules with mission started/finished hooks of built-in backends (cheap to import: no rclpy).
MISSION_HOOK_MODULES: list[str] = [
    "missiontree.backends.ros2.plugin",
    "missiontree.runlog.record",  # runview.json: the declared tree, map and trajectory for the viewer
]

#: What to install when a backend's module cannot be imported.
BACKEND_HINTS: dict[str, str] = {
    "ros2": "install the ROS 2 extra: `make setup-ros2` (pip install 'missiontree[ros2]' plus the "
    "locally built nav2_msgs/tf2_msgs)",
}


def _import_listed(module_name: str, list_name: str) -> ModuleType:
    try:
        return importlib.import_module(module_name)
    except ImportError as error:
        raise PluginError(
            f"built-in module {module_name!r} (listed in missiontree.plugins.builtin.{list_name}) "
            f"failed to import: {error}; fix the module or remove it from the list"
        ) from error


@hookimpl
def missiontree_register_nodes(registry: NodeRegistry) -> None:
    """Add the node types of every module in :data:`NODE_MODULES`, and :data:`LAZY_NODE_TYPES` by name."""
    for module_name in NODE_MODULES:
        _import_listed(module_name, "NODE_MODULES").register_nodes(registry)
    for name, target in LAZY_NODE_TYPES.items():
        registry.add_lazy(name, target)


@hookimpl
def missiontree_register_model_providers(providers: dict[str, Any]) -> None:
    """Add the model providers of every module in :data:`PROVIDER_MODULES`."""
    for module_name in PROVIDER_MODULES:
        _import_listed(module_name, "PROVIDER_MODULES").register_providers(providers)


@hookimpl
def missiontree_register_backends(backends: dict[str, Any]) -> None:
    """Add the built-in backends as lazy ``"module:function"`` references."""
    backends.update(BACKENDS)


def _mission_hooks(hook_name: str) -> list[Callable[..., Any]]:
    modules = (_import_listed(name, "MISSION_HOOK_MODULES") for name in MISSION_HOOK_MODULES)
    return [hook for module in modules if (hook := getattr(module, hook_name, None)) is not None]


@hookimpl
def missiontree_mission_started(context: Any, mission: Any) -> None:
    """Give every module in :data:`MISSION_HOOK_MODULES` its look at the starting mission."""
    for hook in _mission_hooks("missiontree_mission_started"):
        hook(context=context, mission=mission)


@hookimpl
def missiontree_mission_finished(context: Any, summary: dict[str, Any]) -> None:
    """Give every module in :data:`MISSION_HOOK_MODULES` its look at the finished mission."""
    for hook in _mission_hooks("missiontree_mission_finished"):
        hook(context=context, summary=summary)


def resolve_factory(kind: str, name: str, factory: Any) -> Callable[..., Any]:
    """Turn a registered factory into a callable, importing ``"module:function"`` strings now.

    Args:
        kind: ``backend`` or ``provider`` (for messages).
        name: The registered name (for messages).
        factory: A callable, or a ``"module:function"`` string.

    Raises:
        BackendUnavailableError: The module cannot be imported (the message names what to install).
        PluginError: The string is malformed or the module lacks the function.
    """
    if callable(factory):
        return factory
    if not isinstance(factory, str) or ":" not in factory:
        raise PluginError(
            f"{kind} {name!r} was registered as {factory!r}; expected a callable or a "
            f"'module:function' string"
        )
    module_name, _, attr = factory.partition(":")
    try:
        module = importlib.import_module(module_name)
    except ImportError as error:
        hint = BACKEND_HINTS.get(name, f"check that the package providing {module_name!r} is installed")
        raise BackendUnavailableError(
            f"{kind} {name!r} is not available: importing {module_name!r} failed ({error}); {hint}"
        ) from error
    function = getattr(module, attr, None)
    if not callable(function):
        raise PluginError(f"{kind} {name!r}: module {module_name!r} has no function {attr!r}")
    return function
