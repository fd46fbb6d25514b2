"""Tests of `missiontree nodes`: the manifest of node types with parameters and ports."""

from __future__ import annotations

import json
from typing import Annotated

import pytest
from pydantic import BaseModel, Field

from missiontree.cli.main import main
from missiontree.cli.nodes import describe, format_entry
from missiontree.engine.leaf import Leaf, Status
from missiontree.engine.ports import Input, Output
from missiontree.engine.registry import NodeType
from missiontree.testing import clean_state


@pytest.fixture(autouse=True)
def _clean() -> None:
    clean_state()


class Approach(Leaf):
    """Drive to the target until within a distance."""

    class Params(BaseModel):
        distance: float = Field(0.5, gt=0, description="stop this close, in metres")
        label: str = Field(description="what to approach")
        target: Annotated[str, Input("the target's pose", type="Pose2D")] = "target"
        reached: Annotated[str, Output("whether it got there", type="bool")] = "reached"

    def update(self) -> Status:
        return Status.SUCCESS


def test_manifest_entry_lists_params_and_ports_separately() -> None:
    """A node type's entry has its parameters (type, default, doc) and its ports (direction, key, type)."""
    entry = describe(NodeType.from_leaf(Approach, provider="demo"))
    assert entry["summary"] == "Drive to the target until within a distance."
    assert entry["provider"] == "demo"
    assert entry["params"] == [
        {"name": "distance", "type": "float", "required": False, "default": 0.5,
         "doc": "stop this close, in metres"},
        {"name": "label", "type": "str", "required": True, "doc": "what to approach"},
    ]
    assert entry["ports"] == [
        {"name": "target", "direction": "in", "type": "Pose2D", "key": "target", "required": False,
         "doc": "the target's pose"},
        {"name": "reached", "direction": "out", "type": "bool", "key": "reached", "required": False,
         "doc": "whether it got there"},
    ]


def test_text_entry_shows_required_params_and_port_keys() -> None:
    """The text form marks required parameters and shows which key each port uses."""
    text = format_entry(describe(NodeType.from_leaf(Approach)))
    assert "label: str required" in text
    assert "<- reads  target (Pose2D, key 'target')" in text


def test_json_manifest_holds_the_built_in_node_types(capsys: pytest.CaptureFixture[str]) -> None:
    """`nodes --json` prints every node type, including the built-in Wait with its parameters."""
    assert main(["nodes", "--json", "--no-plugins"]) == 0
    nodes = {n["name"]: n for n in json.loads(capsys.readouterr().out)["nodes"]}
    assert nodes["Wait"]["provider"] == "builtin"
    assert nodes["Wait"]["params"]
    assert nodes["Sequence"]["category"] == "composite"


def test_unknown_type_suggests_the_nearest(capsys: pytest.CaptureFixture[str]) -> None:
    """Asking for an unknown node type exits 2 and suggests the nearest names."""
    assert main(["nodes", "Wiat", "--no-plugins"]) == 2
    assert "did you mean Wait" in capsys.readouterr().err
