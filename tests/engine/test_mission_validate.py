"""Tests of the node checker: parameter validation with blackboard references, type hints, providers."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import pytest
from pydantic import BaseModel

from missiontree.engine.leaf import Leaf, Status
from missiontree.engine.loader import load_mission
from missiontree.engine.nodes import register_nodes
from missiontree.engine.nodes.basic import Wait
from missiontree.engine.ports import BlackboardRef, Output
from missiontree.engine.registry import NodeRegistry
from missiontree.engine.validate import type_label, validate_params
from missiontree.errors import MissionFileError


class Dock(Leaf):
    """Dock at a named station (a stand-in for a plugin's leaf)."""

    class Params(BaseModel):
        station: str
        speed: float = 0.2
        result: Annotated[str, Output("docking result")] = "dock_result"

    def update(self) -> Status:
        return self.succeed()


@pytest.fixture
def registry() -> NodeRegistry:
    reg = NodeRegistry()
    register_nodes(reg)
    reg.add(Dock, provider="acme-docking")
    return reg


def test_reference_accepted_for_required_parameter() -> None:
    """{bb: key} satisfies a required parameter and is kept as a BlackboardRef."""
    params, issues = validate_params(Dock.Params, {"station": {"bb": "home"}, "speed": "0.5"})
    assert issues == []
    assert params is not None
    assert params.station == BlackboardRef("home")  # type: ignore[attr-defined]
    assert params.speed == 0.5  # type: ignore[attr-defined]  # validated and coerced


def test_reference_refused_for_a_port() -> None:
    """A port already names its key, so {bb: ...} there is refused with the fix."""
    _, issues = validate_params(Dock.Params, {"station": "a", "result": {"bb": "x"}})
    assert len(issues) == 1 and "write `result: x`" in issues[0].hint


def test_unknown_parameter_suggests_nearest() -> None:
    """An unknown parameter is located at its key and names the nearest known one."""
    _, issues = validate_params(Wait.Params, {"secnds": 1})
    unknown = [i for i in issues if i.at_key]
    assert unknown and unknown[0].hint == "did you mean 'seconds'?"


def test_unknown_type_names_plugin_provider(tmp_path: Path, registry: NodeRegistry) -> None:
    """An unknown type near a plugin's type names that plugin."""
    path = tmp_path / "m.yaml"
    path.write_text("root:\n  Dok: {station: a}\n")
    with pytest.raises(MissionFileError) as info:
        load_mission(path, registry)
    assert "Dock (from acme-docking)" in str(info.value)


def test_plugin_leaf_checked_like_builtin(tmp_path: Path, registry: NodeRegistry) -> None:
    """A plugin's node type is checked against its own Params model."""
    path = tmp_path / "m.yaml"
    path.write_text("root:\n  Dock: {speed: fast}\n")
    with pytest.raises(MissionFileError) as info:
        load_mission(path, registry)
    text = str(info.value)
    assert "m.yaml:2:3: root/Dock: expected parameter 'station' (text), found none" in text
    assert "m.yaml:2:17: root/Dock: speed: expected a valid number" in text


def test_reference_to_key_written_by_output_port_is_not_dangling(
    tmp_path: Path, registry: NodeRegistry
) -> None:
    """A {bb: key} is fine when some node's output port writes that key."""
    path = tmp_path / "m.yaml"
    path.write_text("root:\n  Sequence:\n    memory: true\n    children:\n"
                    "      - Dock: {station: a, result: docked}\n"
                    "      - SetBlackboard: {key: copy, value: {bb: docked}}\n")
    assert load_mission(path, registry).root.children[1].params.value == BlackboardRef("docked")  # type: ignore


def test_type_labels_are_readable() -> None:
    """Parameter types print as words a mission author knows."""
    assert type_label(float) == "number"
    assert type_label(bool) == "true/false"
    assert type_label(list[str]) == "list of text"
    assert type_label(int | None) == "integer"


class Route(BaseModel):
    """A nested parameter model (like a plugin's waypoint list)."""

    class Point(BaseModel):
        x: float
        y: float

    points: list[Point]
    mode: int | str = 1


def test_nested_errors_point_at_the_written_item() -> None:
    """Errors inside lists of mappings name the item; union members merge into one message."""
    _, issues = validate_params(Route, {"points": [{"x": 1, "y": 2}, {"x": "far", "y": 0}, {"x": 0}],
                                        "mode": [1]})
    messages = {issue.loc: issue.message for issue in issues}
    assert messages[("points", 1, "x")].startswith("points[1].x: expected a valid number")
    assert messages[("points", 2)] == "points[2]: expected key 'y', found none"
    assert messages[("mode",)] == "mode: expected a valid integer or a valid string, found [1]"
