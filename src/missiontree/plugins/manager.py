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
import sys
from dataclasses import dataclass, field
from typing import Any

import pluggy

from missiontree.engine.registry import NodeRegistry, NodeType
from missiontree.errors import ConfigError, PluginError
from missiontree.plugins import builtin, hookspecs
from missiontree.plugins.builtin import resolve_factory

DISABLE_ENV = "MISSIONTREE_DISABLE_PLUGIN_AUTOLOAD"
BUILTIN = "builtin"
_warned: set[str] = set()


def _warn(plugin: BrokenPlugin) -> None:
    """Say on stderr (once per process) that a broken plugin was left out: stdout stays the command's."""
    if plugin.error not in _warned:
        _warned.add(plugin.error)
        print(f"missiontree: warning: {plugin.error} (the plugin was left out; other plugins loaded)",
              file=sys.stderr)


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


@dataclass(frozen=True)
class BrokenPlugin:
    """An entry-point plugin left out because it is broken.

    Attributes:
        name: Its entry point name.
        distribution: The distribution and version it came from.
        error: What is wrong, naming the plugin and the fix.
    """

    name: str
    distribution: str
    error: str


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
        broken: Entry-point plugins left out, with the reason (see :func:`load_plugins`).
    """

    pm: pluggy.PluginManager
    nodes: NodeRegistry
    backends: dict[str, Any]
    providers: dict[str, Any]
    info: list[PluginInfo]
    sensors: dict[str, Any] = field(default_factory=dict)
    broken: list[BrokenPlugin] = field(default_factory=list)

    @property
    def hook(self) -> Any:
        """The mission hooks' relay (``plugins.hook.missiontree_mission_started(...)``).

        Unlike pluggy's own relay, it calls every plugin's implementation even when one raises (the
        built-in hooks, which record the run's trajectory, always run), then raises one
        :class:`~missiontree.errors.PluginError` naming each plugin that failed.
        """
        return EachPluginHook(self.pm)

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

    def add_lazy(self, name: str, target: str, provider: str | None = None) -> None:
        """Register node type ``name`` as coming from this plugin, imported from ``target`` when used."""
        self._registry.add_lazy(name, target, provider=self._provider)
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


def _entry_point_plugins() -> tuple[list[tuple[str, Any, str]], list[BrokenPlugin]]:
    """Import every ``missiontree`` entry point: (name, module, distribution) by name, and the broken ones."""
    loaded: list[tuple[str, Any, str]] = []
    broken: list[BrokenPlugin] = []
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
            broken.append(BrokenPlugin(ep.name, dist, (
                f"plugin {ep.name!r} (entry point {ep.value!r}{where}) failed to import: "
                f"{type(error).__name__}: {error}; fix or uninstall it "
                f"(pip uninstall {ep.dist.name if ep.dist else ep.name}), {_DISABLE_HINT}")))
            continue
        loaded.append((ep.name, module, dist))
    return loaded, broken


def _register(pm: pluggy.PluginManager, name: str, module: Any, dist: str) -> PluginInfo:
    try:
        pm.register(module, name=name)
    except pluggy.PluginValidationError as error:
        raise PluginError(f"plugin {name!r} ({getattr(module, '__name__', module)}) is broken: {error}; "
                          f"see missiontree.plugins.hookspecs for the hooks, {_DISABLE_HINT}") from error
    return PluginInfo(name=name, module=getattr(module, "__name__", repr(module)), distribution=dist)


class EachPluginHook:
    """A hook relay that calls each plugin's implementation in turn, whatever the others do.

    ``relay.missiontree_mission_finished(context=..., summary=...)`` runs every implementation in
    the order the plugins were registered (built-ins first); a plugin that raises does not stop the
    ones after it. Afterwards one :class:`PluginError` names every plugin that failed and why.
    """

    def __init__(self, pm: pluggy.PluginManager) -> None:
        self._pm = pm

    def __getattr__(self, hook_name: str) -> Any:
        caller = getattr(self._pm.hook, hook_name)

        def call(**kwargs: Any) -> None:
            failures: list[str] = []
            first: Exception | None = None
            for impl in caller.get_hookimpls():  # registration order: built-ins first
                try:
                    impl.function(*[kwargs[arg] for arg in impl.argnames])
                except Exception as error:  # noqa: BLE001 - a plugin's bug must not stop the others
                    name = self._pm.get_name(impl.plugin) or repr(impl.plugin)
                    failures.append(f"plugin {name!r}: {type(error).__name__}: {error}")
                    first = first or error
            if failures:
                raise PluginError(f"{hook_name} failed in {len(failures)} plugin(s): {'; '.join(failures)}; "
                                  f"the other plugins' hooks ran; fix the plugin, {_DISABLE_HINT}") from first

        return call


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


def load_plugins(autoload: bool | None = None, strict: bool = False) -> Plugins:
    """Build a fresh plugin manager and collect every node type, backend, provider and sensor.

    A broken entry-point plugin — it fails to import, implements a hook missiontree does not have,
    raises in a registration hook, or registers a name another plugin took — names itself and is
    left out whole (nothing it registered is kept, its mission hooks do not run); the others load.
    Each is listed in :attr:`Plugins.broken` and logged as a warning, so an unrelated command still
    runs, and a mission that needs the broken plugin's nodes is refused by the checker.

    Args:
        autoload: Load entry-point plugins; None means "unless ``MISSIONTREE_DISABLE_PLUGIN_AUTOLOAD``
            is set". The built-in plugin is always loaded.
        strict: Raise on the first broken plugin instead (a plugin's own tests use it).

    Raises:
        PluginError: The built-in plugin is broken, or (``strict``) any plugin is (the message names
            the plugin and the fix).
    """
    pm = pluggy.PluginManager(hookspecs.PROJECT)
    pm.add_hookspecs(hookspecs)
    info = [_register(pm, BUILTIN, builtin, "")]
    broken: list[BrokenPlugin] = []
    if autoload_enabled(autoload):
        loaded, broken = _entry_point_plugins()
        for name, module, dist in loaded:
            try:
                info.append(_register(pm, name, module, dist))
                _check_hook_names(pm, name)
            except PluginError as error:
                if pm.get_plugin(name) is not None:
                    pm.unregister(name=name)
                broken.append(BrokenPlugin(name, dist, str(error)))
    if strict and broken:
        raise PluginError(broken[0].error)
    info = [plugin for plugin in info if pm.get_plugin(plugin.name) is not None]

    nodes = NodeRegistry()
    backends: dict[str, Any] = {}
    providers: dict[str, Any] = {}
    sensors: dict[str, Any] = {}
    owners: dict[str, dict[str, str]] = {"backends": {}, "providers": {}, "sensors": {}}
    kept: list[PluginInfo] = []
    for plugin in info:
        try:
            found = _collect_plugin(pm, plugin)
            _merge(plugin, found, nodes, {"backends": backends, "providers": providers, "sensors": sensors},
                   owners)
        except PluginError as error:
            if plugin.name == BUILTIN or strict:
                raise
            pm.unregister(name=plugin.name)
            broken.append(BrokenPlugin(plugin.name, plugin.distribution, str(error)))
            continue
        kept.append(plugin)
    for left_out in broken:
        _warn(left_out)
    return Plugins(pm=pm, nodes=nodes, backends=backends, providers=providers, info=kept, sensors=sensors,
                   broken=broken)


def _check_hook_names(pm: pluggy.PluginManager, name: str) -> None:
    """Refuse a plugin with a hook implementation whose name is no missiontree hook (a misspelling)."""
    plugin = pm.get_plugin(name)
    for hook_name in dir(pm.hook):
        caller = getattr(pm.hook, hook_name, None)
        if not isinstance(caller, pluggy.HookCaller) or caller.spec is not None:
            continue
        if any(impl.plugin is plugin for impl in caller.get_hookimpls()):
            raise PluginError(f"plugin {name!r} implements {hook_name!r}, which is not a missiontree hook; "
                              f"hook names must match missiontree.plugins.hookspecs, {_DISABLE_HINT}")


@dataclass
class _Found:
    nodes: NodeRegistry
    named: dict[str, dict[str, Any]]


def _collect_plugin(pm: pluggy.PluginManager, plugin: PluginInfo) -> _Found:
    """Everything one plugin registers, in registries of its own (merged only if all of it is fine)."""
    own = NodeRegistry()
    added: list[str] = []
    _call_for_each(pm, "missiontree_register_nodes", plugin.name,
                   registry=_ProviderScopedRegistry(own, plugin.name, added))
    named: dict[str, dict[str, Any]] = {}
    for kind, hook in (("backends", "missiontree_register_backends"),
                       ("providers", "missiontree_register_model_providers"),
                       ("sensors", "missiontree_register_sensors")):
        local: dict[str, Any] = {}
        _call_for_each(pm, hook, plugin.name, **{kind: local})
        named[kind] = local
    _check_sensors(named["sensors"], plugin.name)
    return _Found(own, named)


def _merge(plugin: PluginInfo, found: _Found, nodes: NodeRegistry, targets: dict[str, dict[str, Any]],
           owners: dict[str, dict[str, str]]) -> None:
    """Add one plugin's registrations, refusing any name already taken (nothing is added then)."""
    for name in found.nodes.names():  # by name: a lazily registered type stays unimported
        if name in nodes:
            raise PluginError(f"node type {name!r} registered twice: by {nodes.provider_of(name)!r} "
                              f"and by {plugin.name!r}; rename one of them")
    for kind, local in found.named.items():
        for name in local:
            if name in targets[kind]:
                raise PluginError(f"{kind[:-1]} {name!r} registered twice: by {owners[kind][name]!r} and by "
                                  f"{plugin.name!r}; uninstall or rename one of them")
    nodes.absorb(found.nodes)
    plugin.nodes = found.nodes.names()
    for kind, local in found.named.items():
        targets[kind].update(local)
        owners[kind].update(dict.fromkeys(local, plugin.name))
        setattr(plugin, kind, list(local))


def _check_sensors(sensors: dict[str, Any], plugin: str) -> None:
    """Every sensor a plugin registered is a SensorKind filed under its own name."""
    from missiontree.robot.sensors import SensorKind

    for name, kind in sensors.items():
        if not isinstance(kind, SensorKind):
            raise PluginError(f"plugin {plugin!r} registered sensor {name!r} as {type(kind).__name__}; "
                              f"expected missiontree.robot.sensors.SensorKind, {_DISABLE_HINT}")
        if kind.name != name:
            raise PluginError(f"plugin {plugin!r} registered sensor {kind.name!r} under the name "
                              f"{name!r}; use sensors[kind.name] = kind")
