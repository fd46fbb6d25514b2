"""Tests of the JSON Schema generated from the node registry."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml
from pydantic import BaseModel, Field

from missiontree.engine.leaf import Leaf, Status
from missiontree.engine.nodes import register_nodes
from missiontree.engine.registry import NodeRegistry
from missiontree.engine.schema import mission_schema
from missiontree.plugins.manager import load_plugins

jsonschema = pytest.importorskip("jsonschema")
REPO = Path(__file__).resolve().parents[2]


class Beep(Leaf):
    """Beep (a plugin's leaf)."""

    class Params(BaseModel):
        pitch: float = Field(440.0, description="Hz")

    def update(self) -> Status:
        return self.succeed()


def validator(registry: NodeRegistry) -> object:
    schema = mission_schema(registry)
    jsonschema.Draft202012Validator.check_schema(schema)
    return jsonschema.Draft202012Validator(schema)


def test_shipped_missions_conform_to_schema() -> None:
    """Every mission under trees/ validates against the schema of the built-in plugin's registry."""
    check = validator(load_plugins(autoload=False).nodes)
    files = sorted((REPO / "trees").rglob("*.yaml"))
    assert len(files) >= 3
    for path in files:
        errors = list(check.iter_errors(yaml.safe_load(path.read_text())))  # type: ignore[attr-defined]
        assert errors == [], f"{path}: {errors[0].message if errors else ''}"


def test_schema_rejects_unknown_parameter_and_missing_memory() -> None:
    """Editors flag a misspelt parameter and a Sequence without memory."""
    registry = NodeRegistry()
    register_nodes(registry)
    check = validator(registry)
    bad_param = {"root": {"Wait": {"secnds": 1}}}
    no_memory = {"root": {"Sequence": {"children": ["Succeed"]}}}
    wait = {"Wait": {"seconds": {"bb": "t"}}}
    good = {"root": {"Sequence": {"memory": True, "children": ["Succeed", wait]}}}
    assert not check.is_valid(bad_param)  # type: ignore[attr-defined]
    assert not check.is_valid(no_memory)  # type: ignore[attr-defined]
    assert check.is_valid(good)  # type: ignore[attr-defined]


def test_plugin_node_types_appear_in_schema() -> None:
    """A node type registered by a plugin gets its own schema entry with its parameter docs."""
    registry = NodeRegistry()
    register_nodes(registry)
    registry.add(Beep, provider="acme")
    schema = mission_schema(registry)
    beep = schema["$defs"]["node.Beep"]
    assert "from acme" in beep["description"]
    assert validator(registry).is_valid({"root": {"Beep": {"pitch": 880}}})  # type: ignore[attr-defined]
