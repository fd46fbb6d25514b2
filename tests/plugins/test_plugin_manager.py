"""Tests of the plugin manager: entry points, autoload switch, provenance and plugin errors."""

from __future__ import annotations

import importlib.metadata
import sys
import types
from collections.abc import Callable
from typing import Any

import pytest

from missiontree.engine.leaf import Leaf, Status
from missiontree.errors import BackendUnavailableError, ConfigError, PluginError
from missiontree.plugins import manager
from missiontree.plugins.hookspecs import hookimpl
from missiontree.plugins.manager import load_plugins
from missiontree.testing import ClockRobot, clean_state


@pytest.fixture(autouse=True)
def _clean() -> None:
    clean_state()


class Beacon(Leaf):
    """Succeeds at once (a node type for plugin tests)."""

    def update(self) -> Status:
        return Status.SUCCESS


def _module(name: str, **hooks: Callable[..., Any]) -> types.ModuleType:
    module = types.ModuleType(name)
    for hook_name, function in hooks.items():
        setattr(module, hook_name, hookimpl(function))
    return module


@pytest.fixture
def entry_points(monkeypatch: pytest.MonkeyPatch) -> Callable[..., None]:
    """Install fake modules as the only ``missiontree`` entry points."""

    def install(**modules: types.ModuleType | str) -> None:
        eps = []
        for ep_name, module in modules.items():
            if isinstance(module, types.ModuleType):
                monkeypatch.setitem(sys.modules, module.__name__, module)
                value = module.__name__
            else:
                value = module
            eps.append(importlib.metadata.EntryPoint(name=ep_name, value=value, group="missiontree"))
        monkeypatch.setattr(manager, "discover_entry_points", lambda: eps)

    return install


def _beacon_plugin(name: str = "mt_test_beacon") -> types.ModuleType:
    def missiontree_register_nodes(registry: Any) -> None:
        registry.add(Beacon)

    def missiontree_register_backends(backends: dict[str, Any]) -> None:
        backends["clock"] = lambda options: ClockRobot()

    return _module(name, missiontree_register_nodes=missiontree_register_nodes,
                   missiontree_register_backends=missiontree_register_backends)


def test_entry_point_plugin_registers_nodes_and_backends_under_its_name(entry_points: Callable) -> None:
    """A plugin's node types and backends are recorded as provided by its entry point name."""
    entry_points(beacon=_beacon_plugin())
    plugins = load_plugins(autoload=True)
    assert plugins.nodes.get("Beacon").provider == "beacon"  # type: ignore[union-attr]
    assert plugins.provided_by("backends", "clock") == "beacon"
    assert isinstance(plugins.backend("clock")({}), ClockRobot)
    assert [p.name for p in plugins.info] == ["builtin", "beacon"]


def test_environment_variable_turns_autoload_off(entry_points: Callable,
                                                 monkeypatch: pytest.MonkeyPatch) -> None:
    """MISSIONTREE_DISABLE_PLUGIN_AUTOLOAD=1 skips entry points but keeps the built-in plugin."""
    entry_points(beacon=_beacon_plugin())
    monkeypatch.setenv("MISSIONTREE_DISABLE_PLUGIN_AUTOLOAD", "1")
    plugins = load_plugins()
    assert "Beacon" not in plugins.nodes
    assert [p.name for p in plugins.info] == ["builtin"]
    assert {"sim", "ros2"} <= set(plugins.backends)


def test_explicit_autoload_wins_over_the_environment(entry_points: Callable,
                                                     monkeypatch: pytest.MonkeyPatch) -> None:
    """load_plugins(autoload=True) loads entry points even when the variable says not to."""
    entry_points(beacon=_beacon_plugin())
    monkeypatch.setenv("MISSIONTREE_DISABLE_PLUGIN_AUTOLOAD", "1")
    assert "Beacon" in load_plugins(autoload=True).nodes


def test_plugin_that_fails_to_import_is_named_with_the_fix(entry_points: Callable) -> None:
    """An entry point whose module cannot be imported is left out, named with how to fix or skip it."""
    entry_points(broken="mt_no_such_module_xyz", beacon=_beacon_plugin())
    plugins = load_plugins(autoload=True)
    assert [b.name for b in plugins.broken] == ["broken"]
    assert "Beacon" in plugins.nodes and [p.name for p in plugins.info] == ["builtin", "beacon"]
    message = plugins.broken[0].error
    with pytest.raises(PluginError, match="mt_no_such_module_xyz"):
        load_plugins(autoload=True, strict=True)
    assert "plugin 'broken'" in message and "mt_no_such_module_xyz" in message
    assert "--no-plugins" in message and "MISSIONTREE_DISABLE_PLUGIN_AUTOLOAD=1" in message


def test_misspelt_hook_is_a_plugin_error(entry_points: Callable) -> None:
    """A hook implementation whose name is not a missiontree hook is refused."""
    entry_points(typo=_module("mt_test_typo", missiontree_register_node=lambda registry: None))
    plugins = load_plugins(autoload=True)
    assert [b.name for b in plugins.broken] == ["typo"]
    assert "'missiontree_register_node', which is not a missiontree hook" in plugins.broken[0].error
    assert plugins.pm.get_plugin("typo") is None
    with pytest.raises(PluginError, match="missiontree_register_node"):
        load_plugins(autoload=True, strict=True)


def test_hook_that_raises_is_a_plugin_error_naming_the_plugin(entry_points: Callable) -> None:
    """A plugin whose registration hook raises is reported by name, with the hook."""

    def missiontree_register_nodes(registry: Any) -> None:
        raise RuntimeError("forgot an import")

    def missiontree_register_backends(backends: dict[str, Any]) -> None:
        backends["crashy_backend"] = lambda options: ClockRobot()

    entry_points(crashy=_module("mt_test_crashy", missiontree_register_nodes=missiontree_register_nodes,
                                missiontree_register_backends=missiontree_register_backends))
    plugins = load_plugins(autoload=True)
    assert "crashy_backend" not in plugins.backends  # left out whole, not half registered
    assert plugins.pm.get_plugin("crashy") is None   # its mission hooks do not run either
    [broken] = plugins.broken
    assert broken.name == "crashy" and "failed in missiontree_register_nodes" in broken.error
    with pytest.raises(PluginError, match=r"plugin 'crashy' failed in missiontree_register_nodes.*forgot"):
        load_plugins(autoload=True, strict=True)


def test_node_type_registered_twice_names_both_plugins(entry_points: Callable) -> None:
    """Two plugins registering the same node type name is an error naming both."""
    second = _module("mt_test_second", missiontree_register_nodes=lambda registry: registry.add(Beacon))
    entry_points(first=_beacon_plugin("mt_test_first"), second=second)
    plugins = load_plugins(autoload=True)
    assert plugins.provided_by("nodes", "Beacon") == "first"
    assert [b.name for b in plugins.broken] == ["second"]
    assert "'Beacon' registered twice: by 'first' and by 'second'" in plugins.broken[0].error
    with pytest.raises(PluginError, match=r"'Beacon' registered twice: by 'first' and by 'second'"):
        load_plugins(autoload=True, strict=True)


def test_backend_registered_twice_names_both_plugins(entry_points: Callable) -> None:
    """A backend name taken by the built-in plugin cannot be taken again silently."""

    def missiontree_register_backends(backends: dict[str, Any]) -> None:
        backends["sim"] = lambda options: ClockRobot()

    entry_points(rival=_module("mt_test_rival", missiontree_register_backends=missiontree_register_backends))
    plugins = load_plugins(autoload=True)
    assert plugins.backends["sim"] == "missiontree.backends.sim:create_robot"
    assert "backend 'sim' registered twice: by 'builtin' and by 'rival'" in plugins.broken[0].error
    with pytest.raises(PluginError, match=r"backend 'sim' registered twice: by 'builtin' and by 'rival'"):
        load_plugins(autoload=True, strict=True)


def test_every_call_starts_fresh(entry_points: Callable) -> None:
    """A plugin loaded in one call is absent from the next call that does not load it."""
    entry_points(beacon=_beacon_plugin())
    assert "Beacon" in load_plugins(autoload=True).nodes
    assert "Beacon" not in load_plugins(autoload=False).nodes


def test_unknown_backend_lists_the_known_ones() -> None:
    """Asking for a backend nobody registered is a ConfigError listing the known backends."""
    with pytest.raises(ConfigError, match=r"unknown backend 'gazebo'; known backends: recorded, ros2, sim"):
        load_plugins(autoload=False).backend("gazebo")


def test_backend_whose_module_is_missing_names_what_to_install() -> None:
    """A lazily registered backend whose module is missing is BackendUnavailableError with a hint."""
    plugins = load_plugins(autoload=False)
    plugins.backends["ros2"] = "mt_missing_ros_backend_xyz:create_robot"
    with pytest.raises(BackendUnavailableError, match=r"backend 'ros2' is not available.*setup-ros2"):
        plugins.backend("ros2")


def test_unknown_provider_lists_the_known_ones() -> None:
    """Asking for an unregistered model provider is a ConfigError."""
    with pytest.raises(ConfigError, match="unknown model provider 'nope'"):
        load_plugins(autoload=False).provider("nope")
