"""The plugin manager: loads plugins and collects what they register.

:func:`load_plugins` builds a fresh pluggy manager each call (no process-global plugin state),
registers the built-in plugin (:mod:`missiontree.plugins.builtin`) directly, then — unless
autoloading is off — every module advertised under the entry point group ``missiontree``. It
then calls the registration hooks once per plugin, so it knows which plugin provided each node
type, backend and model provider::

    plugins = load_plugins()
    plugins.nodes.get("Wait")            # NodeType, .provider == "builtin"
    plugins.backend("sim")(options)      # a Robot
    plugins.hook.missiontree_mission_started(context=ctx, mission=spec)

Autoloading is off when ``MISSIONTREE_DISABLE_PLUGIN_AUTOLOAD`` is set to a true value or the
CLI is given ``--no-plugins``.
"""

from __future__ import annotations

import importlib.metadata
import os
from dataclasses import dataclass, field
from typing import Any

import pluggy

from missiontree.engine.registry import NodeRegistry, NodeType
from missiontree.errors import ConfigError, PluginError
from missiontree.plugins import builtin, hookspecs
from missiontree.plugins.builtin import resolve_factory

DISABLE_ENV = "MISSIONTREE_DISABLE_PLUGIN_AUTOLOAD"
BUILTIN = "builtin"
_DISABLE_HINT = f"or run with --no-plugins / {DISABLE_ENV}=1 to skip installed plugins"


@dataclass
class PluginInfo:
    """One loaded plugin.

    Attributes:
        name: Its name (the entry point name, ``builtin`` for ours).
        module: The module that holds its hook implementations.
        distribution: The installed distribution and version it came from, empty for built-ins.
        nodes: Node type names it registered.
        backends: Backend names it registered.
        providers: Model provider names it registered.
        sensors: Sensor kind names it registered.
    """

    name: str
    module: str
    distribution: str = ""
    nodes: list[str] = field(default_factory=list)
    backends: list[str] = field(default_factory=list)
    providers: list[str] = field(default_factory=list)
    sensors: list[str] = field(default_factory=list)


@dataclass
class Plugins:
    """What the loaded plugins provide.

    Attributes:
        pm: The pluggy manager (``pm.hook`` calls the mission started/finished hooks).
        nodes: Every node type.
        backends: Backend name → factory (a callable or a lazy ``"module:function"``).
        providers: Model provider name → factory.
        info: Every loaded plugin, built-in first, with what it registered.
        sensors: Sensor name → :class:`~missiontree.robot.sensors.SensorKind`.
    """

    pm: pluggy.PluginManager
    nodes: NodeRegistry
    backends: dict[str, Any]
    providers: dict[str, Any]
    info: list[PluginInfo]
    sensors: dict[str, Any] = field(default_factory=dict)

    @property
    def hook(self) -> Any:
        """The hook relay (``plugins.hook.missiontree_mission_started(...)``)."""
        return self.pm.hook

    def backend(self, name: str) -> Any:
        """The factory of backend ``name``, imported now.

        Raises:
            ConfigError: No such backend (the message lists the known ones).
            BackendUnavailableError: Its module cannot be imported (names what to install).
        """
        if name not in self.backends:
            known = ", ".join(sorted(self.backends)) or "none"
            raise ConfigError(f"unknown backend {name!r}; known backends: {known}")
        return resolve_factory("backend", name, self.backends[name])

    def provider(self, name: str) -> Any:
        """The factory of model provider ``name``, imported now (errors as :meth:`backend`)."""
        if name not in self.providers:
            known = ", ".join(sorted(self.providers)) or "none"
            raise ConfigError(f"unknown model provider {name!r}; known providers: {known}")
        return resolve_factory("provider", name, self.providers[name])

    def provided_by(self, kind: str, name: str) -> str:
        """Name of the plugin that registered ``name`` of ``kind`` (nodes, backends, providers, sensors)."""
        for plugin in self.info:
            if name in getattr(plugin, kind):
                return plugin.name
        return ""


class _ProviderScopedRegistry:
    """The node registry as one plugin sees it: everything it adds is stamped with its name."""

    def __init__(self, registry: NodeRegistry, provider: str, added: list[str]) -> None:
        self._registry = registry
        self._provider = provider
        self._added = added

    def add(self, node_type: NodeType | type, provider: str | None = None) -> None:
        """Register a node type as coming from this plugin."""
        before = len(self._registry)
        self._registry.add(node_type, provider=self._provider)
        if len(self._registry) > before:
            name = node_type.name if isinstance(node_type, NodeType) else node_type.__name__
            self._added.append(name)

    def __getattr__(self, name: str) -> Any:
        return getattr(self._registry, name)

    def __contains__(self, name: object) -> bool:
        return name in self._registry

    def __iter__(self) -> Any:
        return iter(self._registry)

    def __len__(self) -> int:
        return len(self._registry)


def autoload_enabled(autoload: bool | None = None) -> bool:
    """Whether entry-point plugins load: ``autoload`` if given, else not disabled by the environment."""
    if autoload is not None:
        return autoload
    value = os.environ.get(DISABLE_ENV, "").strip().lower()
    return value in {"", "0", "false", "no", "off"}


def discover_entry_points() -> list[importlib.metadata.EntryPoint]:
    """The installed entry points of the group ``missiontree``, sorted by name."""
    return sorted(importlib.metadata.entry_points(group=hookspecs.ENTRY_POINT_GROUP), key=lambda e: e.name)


def _entry_point_plugins() -> list[tuple[str, Any, str]]:
    """Import every ``missiontree`` entry point: (name, module, distribution), sorted by name."""
    loaded: list[tuple[str, Any, str]] = []
    seen: set[str] = set()
    for ep in discover_entry_points():
        if ep.name in seen or ep.name == BUILTIN:
            continue
        seen.add(ep.name)
        dist = f"{ep.dist.name} {ep.dist.version}" if ep.dist is not None else ""
        try:
            module = ep.load()
        except Exception as error:  # noqa: BLE001 - any import failure is reported as the plugin's
            where = f" from distribution {dist}" if dist else ""
            raise PluginError(
                f"plugin {ep.name!r} (entry point {ep.value!r}{where}) failed to import: "
                f"{type(error).__name__}: {error}; fix or uninstall it "
                f"(pip uninstall {ep.dist.name if ep.dist else ep.name}), {_DISABLE_HINT}"
            ) from error
        loaded.append((ep.name, module, dist))
    return loaded


def _register(pm: pluggy.PluginManager, name: str, module: Any, dist: str) -> PluginInfo:
    try:
        pm.register(module, name=name)
    except pluggy.PluginValidationError as error:
        raise PluginError(f"plugin {name!r} ({getattr(module, '__name__', module)}) is broken: {error}; "
                          f"see missiontree.plugins.hookspecs for the hooks, {_DISABLE_HINT}") from error
    return PluginInfo(name=name, module=getattr(module, "__name__", repr(module)), distribution=dist)


def _call_for_each(pm: pluggy.PluginManager, hook_name: str, plugin_name: str, **kwargs: Any) -> None:
    """Call one plugin's implementation of ``hook_name`` (if any) with ``kwargs``."""
    plugin = pm.get_plugin(plugin_name)
    for impl in getattr(pm.hook, hook_name).get_hookimpls():
        if impl.plugin is not plugin:
            continue
        try:
            impl.function(*[kwargs[arg] for arg in impl.argnames])
        except PluginError:
            raise
        except Exception as error:  # noqa: BLE001 - a plugin's bug is reported as the plugin's
            raise PluginError(f"plugin {plugin_name!r} failed in {hook_name}: {type(error).__name__}: "
                              f"{error}; fix the plugin, {_DISABLE_HINT}") from error


def _collect_named(
    pm: pluggy.PluginManager, hook_name: str, info: PluginInfo, target: dict[str, Any],
    owners: dict[str, str], kind: str,
) -> list[str]:
    """Call a ``dict``-filling hook of one plugin and merge its entries, refusing duplicates."""
    local: dict[str, Any] = {}
    _call_for_each(pm, hook_name, info.name, **{kind: local})
    for name, factory in local.items():
        if name in target:
            raise PluginError(f"{kind[:-1]} {name!r} registered twice: by {owners[name]!r} and by "
                              f"{info.name!r}; uninstall or rename one of them")
        target[name] = factory
        owners[name] = info.name
    return list(local)


def load_plugins(autoload: bool | None = None) -> Plugins:
    """Build a fresh plugin manager and collect every node type, backend, provider and sensor.

    Args:
        autoload: Load entry-point plugins; None means "unless ``MISSIONTREE_DISABLE_PLUGIN_AUTOLOAD``
            is set". The built-in plugin is always loaded.

    Raises:
        PluginError: A plugin failed to import, implements an unknown hook, or registered a name
            another plugin already took (the message names the plugins and the fix).
    """
    pm = pluggy.PluginManager(hookspecs.PROJECT)
    pm.add_hookspecs(hookspecs)
    info = [_register(pm, BUILTIN, builtin, "")]
    if autoload_enabled(autoload):
        info += [_register(pm, name, module, dist) for name, module, dist in _entry_point_plugins()]
    try:
        pm.check_pending()
    except pluggy.PluginValidationError as error:
        raise PluginError(f"{error}; hook names must match missiontree.plugins.hookspecs, "
                          f"{_DISABLE_HINT}") from error

    nodes = NodeRegistry()
    backends: dict[str, Any] = {}
    providers: dict[str, Any] = {}
    backend_owner: dict[str, str] = {}
    provider_owner: dict[str, str] = {}
    sensors: dict[str, Any] = {}
    sensor_owner: dict[str, str] = {}
    for plugin in info:
        _call_for_each(pm, "missiontree_register_nodes", plugin.name,
                       registry=_ProviderScopedRegistry(nodes, plugin.name, plugin.nodes))
        plugin.backends = _collect_named(pm, "missiontree_register_backends", plugin, backends,
                                         backend_owner, "backends")
        plugin.providers = _collect_named(pm, "missiontree_register_model_providers", plugin, providers,
                                          provider_owner, "providers")
        plugin.sensors = _collect_named(pm, "missiontree_register_sensors", plugin, sensors,
                                        sensor_owner, "sensors")
    _check_sensors(sensors, sensor_owner)
    return Plugins(pm=pm, nodes=nodes, backends=backends, providers=providers, info=info, sensors=sensors)


def _check_sensors(sensors: dict[str, Any], owners: dict[str, str]) -> None:
    """Every registered sensor is a SensorKind filed under its own name."""
    from missiontree.robot.sensors import SensorKind

    for name, kind in sensors.items():
        if not isinstance(kind, SensorKind):
            raise PluginError(f"plugin {owners[name]!r} registered sensor {name!r} as {type(kind).__name__}; "
                              f"expected missiontree.robot.sensors.SensorKind, {_DISABLE_HINT}")
        if kind.name != name:
            raise PluginError(f"plugin {owners[name]!r} registered sensor {kind.name!r} under the name "
                              f"{name!r}; use sensors[kind.name] = kind")
