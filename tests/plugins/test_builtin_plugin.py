"""Tests of the built-in plugin: listed modules, lazy backends, clear errors."""

from __future__ import annotations

import pytest

from missiontree.errors import PluginError
from missiontree.plugins import builtin
from missiontree.plugins.builtin import resolve_factory
from missiontree.plugins.manager import load_plugins
from missiontree.testing import clean_state


@pytest.fixture(autouse=True)
def _clean() -> None:
    clean_state()


def test_every_listed_node_module_registers_its_types() -> None:
    """Each module in NODE_MODULES imports and adds node types provided by 'builtin'."""
    plugins = load_plugins(autoload=False)
    if builtin.NODE_MODULES:
        assert len(plugins.nodes) > 0
    assert all(t.provider == "builtin" for t in plugins.nodes)


def test_backends_are_registered_lazily_as_module_function_strings() -> None:
    """Listing backends imports nothing: sim and ros2 are 'module:function' references."""
    backends = load_plugins(autoload=False).backends
    assert backends["sim"] == "missiontree.backends.sim:create_robot"
    assert backends["ros2"] == "missiontree.backends.ros2:create_robot"


def test_missing_listed_module_is_a_plugin_error(monkeypatch: pytest.MonkeyPatch) -> None:
    """A node module listed but missing is reported with the list it is in."""
    monkeypatch.setattr(builtin, "NODE_MODULES", ["missiontree.no_such_nodes"])
    with pytest.raises(PluginError, match=r"'missiontree.no_such_nodes' \(listed in .*NODE_MODULES\)"):
        load_plugins(autoload=False)


def test_resolve_factory_rejects_a_malformed_reference() -> None:
    """A backend registered as something that is neither callable nor 'module:function' is refused."""
    with pytest.raises(PluginError, match="expected a callable or a 'module:function' string"):
        resolve_factory("backend", "odd", 42)


def test_resolve_factory_names_a_missing_function() -> None:
    """A 'module:function' reference whose function does not exist says which."""
    with pytest.raises(PluginError, match="module 'json' has no function 'nope'"):
        resolve_factory("backend", "odd", "json:nope")


def test_resolve_factory_imports_the_function() -> None:
    """A valid reference resolves to the function itself."""
    import json

    assert resolve_factory("backend", "j", "json:dumps") is json.dumps


def test_mission_hooks_of_listed_modules_run_for_every_mission(monkeypatch: pytest.MonkeyPatch) -> None:
    """The built-in plugin hands mission started/finished to every module in MISSION_HOOK_MODULES."""
    import sys
    import types

    seen: list[str] = []
    module = types.ModuleType("missiontree_test_mission_hooks")
    module.missiontree_mission_started = lambda context, mission: seen.append(f"started {mission}")
    module.missiontree_mission_finished = lambda context, summary: seen.append(f"finished {summary}")
    monkeypatch.setitem(sys.modules, module.__name__, module)
    monkeypatch.setattr(builtin, "MISSION_HOOK_MODULES", [module.__name__])
    hook = load_plugins(autoload=False).pm.hook
    hook.missiontree_mission_started(context=None, mission="m")
    hook.missiontree_mission_finished(context=None, summary={"status": "SUCCESS"})
    assert seen == ["started m", "finished {'status': 'SUCCESS'}"]


def test_ros2_event_mirroring_is_listed_and_imports_without_rclpy() -> None:
    """The ROS 2 backend's mission hook is wired in, and importing it does not import rclpy."""
    import importlib
    import sys

    assert "missiontree.backends.ros2.plugin" in builtin.MISSION_HOOK_MODULES
    had_rclpy = "rclpy" in sys.modules
    importlib.import_module("missiontree.backends.ros2.plugin")
    assert ("rclpy" in sys.modules) == had_rclpy


def test_lazy_node_types_are_exactly_what_the_behaviours_module_registers() -> None:
    """LAZY_NODE_TYPES names every behaviour leaf, each declaring the same type as registered eagerly."""
    from missiontree.behaviours import register_nodes
    from missiontree.engine.registry import NodeRegistry

    eager = NodeRegistry()
    register_nodes(eager)
    lazy = NodeRegistry()
    for name, target in builtin.LAZY_NODE_TYPES.items():
        lazy.add_lazy(name, target)
    assert lazy.names() == eager.names()
    for node_type in eager:
        assert lazy.get(node_type.name).params is node_type.params  # type: ignore[union-attr]


def test_loading_plugins_imports_no_behaviour_module() -> None:
    """load_plugins leaves the behaviour modules (and their numba/scipy/OpenCV imports) unimported."""
    import subprocess
    import sys

    code = ("import sys; from missiontree.plugins.manager import load_plugins; "
            "p = load_plugins(autoload=False); assert 'Explore' in p.nodes; "
            "print(sorted(m for m in sys.modules if m.startswith('missiontree.behaviours.')))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "[]"


def test_a_mission_node_type_is_imported_when_asked_for() -> None:
    """Asking the registry for Patrol imports its module and gives the built-in's declaration."""
    node_type = load_plugins(autoload=False).nodes.get("Patrol")
    assert node_type is not None and node_type.provider == "builtin" and node_type.category == "leaf"


def test_the_scene_graphs_second_look_is_a_node_type_missions_can_name() -> None:
    """LookAgain (second looks at doubtful places and table tops) is a built-in node type."""
    plugins = load_plugins(autoload=False)
    assert "LookAgain" in [t.name for t in plugins.nodes]
