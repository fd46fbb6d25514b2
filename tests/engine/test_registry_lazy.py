"""Node types registered by name and imported when first asked for."""

from __future__ import annotations

import pytest

from missiontree.engine.registry import NodeRegistry
from missiontree.errors import PluginError


def test_a_lazy_type_is_known_by_name_before_it_is_imported() -> None:
    """Membership, length and names need no import."""
    registry = NodeRegistry()
    registry.add_lazy("Wait", "missiontree.no_such_module:Wait")
    assert "Wait" in registry and len(registry) == 1 and registry.names() == ["Wait"]


def test_get_imports_a_lazy_type() -> None:
    """get() imports the module and returns the declared type, stamped with its provider."""
    registry = NodeRegistry()
    registry.add_lazy("Wait", "missiontree.engine.nodes.basic:Wait", provider="mine")
    node_type = registry.get("Wait")
    assert node_type is not None and node_type.name == "Wait" and node_type.provider == "mine"


def test_a_lazy_type_that_cannot_be_imported_is_a_plugin_error() -> None:
    """A missing module is reported with the type's name and target when the type is asked for."""
    registry = NodeRegistry()
    registry.add_lazy("Wait", "missiontree.no_such_module:Wait")
    with pytest.raises(PluginError, match="'Wait' .*no_such_module"):
        registry.get("Wait")


def test_a_lazy_target_declaring_another_name_is_refused() -> None:
    """A target whose type is called otherwise than registered is an error, not a silent rename."""
    registry = NodeRegistry()
    registry.add_lazy("Pause", "missiontree.engine.nodes.basic:Wait")
    with pytest.raises(PluginError, match="declares 'Wait'"):
        registry.get("Pause")


def test_a_name_taken_lazily_cannot_be_added_again() -> None:
    """Lazy and eager registrations share one namespace."""
    from missiontree.engine.nodes.basic import Wait

    registry = NodeRegistry()
    registry.add_lazy("Wait", "missiontree.engine.nodes.basic:Wait", provider="one")
    with pytest.raises(PluginError, match="registered twice: by 'one'"):
        registry.add(Wait, provider="two")


def test_absorb_keeps_lazy_types_lazy() -> None:
    """Merging one registry into another moves a lazy entry without importing it."""
    source, target = NodeRegistry(), NodeRegistry()
    source.add_lazy("Wait", "missiontree.no_such_module:Wait", provider="p")
    target.absorb(source)
    assert target.names() == ["Wait"] and target.provider_of("Wait") == "p"
