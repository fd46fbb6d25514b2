"""JSON Schema of the mission file format, generated from the node registry.

Every registered node type — built-in or from a plugin — becomes one alternative of the ``node``
definition, with its parameters taken from its pydantic ``Params`` model (descriptions included,
so editors show them on hover). Any parameter that is not a port also accepts a blackboard
reference ``{bb: key}`` and a subtree parameter reference ``"${name}"``. ``missiontree schema``
prints the result; docs/mission-format.md explains how to point an editor at it.
"""

from __future__ import annotations

import copy
from typing import Any

from missiontree.engine.loader import INCLUDE
from missiontree.engine.ports import ports_of
from missiontree.engine.registry import NodeRegistry, NodeType
from missiontree.engine.spec import CHILD_KEY, CHILDREN_KEY, NAME_KEY, POST_KEYS, PRE_KEYS, RunSection
from missiontree.engine.validate import reads_refs

SCHEMA_DIALECT = "https://json-schema.org/draft/2020-12/schema"
_NODE_REF = {"$ref": "#/$defs/node"}
_BB_REF = {"$ref": "#/$defs/blackboard_ref"}
_PARAM_REF = {"$ref": "#/$defs/param_ref"}


def mission_schema(registry: NodeRegistry) -> dict[str, Any]:
    """The JSON Schema (draft 2020-12) of mission and subtree files for the types in ``registry``."""
    defs: dict[str, Any] = {
        "blackboard_ref": {
            "type": "object", "properties": {"bb": {"type": "string", "minLength": 1}},
            "required": ["bb"], "additionalProperties": False,
            "description": "Read this parameter from the blackboard key `bb` when the node starts.",
        },
        "param_ref": {
            "type": "string", "pattern": r"^\$\{[A-Za-z_][A-Za-z0-9_]*\}$",
            "description": "A subtree parameter, replaced by its value when the subtree is included.",
        },
    }
    alternatives: list[dict[str, Any]] = []
    bare_names: list[str] = []
    for node_type in registry:
        name = f"node.{node_type.name}"
        defs[name], needs_params = _node_schema(node_type, defs)
        alternatives.append({"$ref": f"#/$defs/{name}"})
        if node_type.category == "leaf" and not needs_params:
            bare_names.append(node_type.name)
    defs[f"node.{INCLUDE}"] = _include_schema()
    alternatives.append({"$ref": f"#/$defs/node.{INCLUDE}"})
    if bare_names:
        alternatives.insert(0, {"enum": bare_names, "description": "A leaf that needs no parameters."})
    alternatives.append(_PARAM_REF)
    defs["node"] = {"anyOf": alternatives}
    run = RunSection.model_json_schema()
    return {
        "$schema": SCHEMA_DIALECT,
        "$id": "https://missiontree.dev/schema/mission.json",
        "title": "missiontree mission",
        "description": "A behaviour-tree mission for missiontree (see docs/mission-format.md).",
        "type": "object",
        "properties": {
            "version": {"const": 1, "description": "Format version (1)."},
            "description": {"type": "string", "description": "What the mission does."},
            "params": {"type": "object", "description": "Parameters of this file (name: default), "
                       "referenced as ${name}; an Include may override them."},
            "required": {"type": "array", "items": {"type": "string"},
                         "description": "Parameters an Include must give (no default)."},
            "run": {**run, "description": "Defaults for `missiontree run`; command-line flags win."},
            "blackboard": {"type": "object", "description": "Blackboard keys written before the first tick."},
            "root": {**_NODE_REF, "description": "The root node of the tree."},
        },
        "required": ["root"],
        "additionalProperties": False,
        "$defs": defs,
    }


def _node_schema(node_type: NodeType, defs: dict[str, Any]) -> tuple[dict[str, Any], bool]:
    """The schema of ``{Type: {params}}`` and whether anything in it is required."""
    params = node_type.params.model_json_schema(ref_template="#/$defs/{model}")
    for def_name, definition in params.pop("$defs", {}).items():
        defs.setdefault(def_name, definition)
    properties: dict[str, Any] = {}
    ports = ports_of(node_type.params)
    fields = node_type.params.model_fields
    for prop, prop_schema in params.get("properties", {}).items():
        field_name = next((n for n, f in fields.items() if (f.alias or n) == prop), prop)
        if field_name in ports:
            port = ports[field_name]
            prop_schema = {**prop_schema, "description": (
                f"Blackboard key this node {'reads' if port.direction == 'in' else 'writes'}"
                f" ({port.type}): {port.doc or prop_schema.get('description', '')}")}
            properties[prop] = {"anyOf": [prop_schema, _PARAM_REF]}
        else:
            meta = {k: prop_schema[k] for k in ("description", "title") if k in prop_schema}
            prop_schema = {k: v for k, v in prop_schema.items() if k != "bb_ref"}
            refs = [_BB_REF, _PARAM_REF] if reads_refs(node_type, field_name) else [_PARAM_REF]
            properties[prop] = {"anyOf": [copy.deepcopy(prop_schema), *refs], **meta}
    properties[NAME_KEY] = {"type": "string", "description": "Name of this node (default: its type)."}
    properties.update(_condition_properties())
    required = list(params.get("required", []))
    if node_type.category == "decorator":
        properties[CHILD_KEY] = {**_NODE_REF, "description": "The node this decorator wraps."}
        required.append(CHILD_KEY)
    elif node_type.category == "composite":
        properties[CHILDREN_KEY] = {"type": "array", "items": _NODE_REF, "minItems": 1,
                                    "description": "The children, ticked in order."}
        required.append(CHILDREN_KEY)
    body: dict[str, Any] = {"type": "object", "properties": properties, "additionalProperties": False,
                            "description": node_type.summary}
    if required:
        body["required"] = required
    value = body if required else {"anyOf": [body, {"type": "null"}], "description": node_type.summary}
    return {
        "type": "object",
        "description": f"{node_type.name} ({node_type.category}, from {node_type.provider}): "
        f"{node_type.summary}",
        "properties": {node_type.name: value},
        "required": [node_type.name],
        "additionalProperties": False,
    }, bool(required)


_CONDITION_WORDS = {
    "fail_if": "Before a tick (node not running): if true, FAILURE without ticking it.",
    "succeed_if": "Before a tick (node not running): if true, SUCCESS without ticking it.",
    "skip_if": "Before a tick (node not running): if true, skipped: SUCCESS without ticking it.",
    "while": "Before every tick: if false, not ticked (halted when running) and FAILURE.",
    "on_success": "After the node ends SUCCESS: assignments `key = expression` (`;`-separated).",
    "on_failure": "After the node ends FAILURE: assignments `key = expression`.",
    "on_halted": "When the node is halted while running: assignments `key = expression`.",
    "post": "After the node ends SUCCESS or FAILURE (after on_success/on_failure): assignments.",
}


def _condition_properties() -> dict[str, Any]:
    """The pre-conditions (expressions) and post-conditions (assignments) any node may carry."""
    kinds = {**{k: "expression" for k in PRE_KEYS}, **{k: "assignments" for k in POST_KEYS}}
    return {key: {"anyOf": [{"type": "string", "minLength": 1}, {"type": "boolean"}, _PARAM_REF],
                  "description": f"{_CONDITION_WORDS[key]} (an {kinds[key]} over blackboard keys; "
                  "see docs/mission-format.md, Conditions)"}
            for key in (*PRE_KEYS, *POST_KEYS)}


def _include_schema() -> dict[str, Any]:
    return {
        "type": "object",
        "description": "A subtree from another file, with parameters.",
        "properties": {INCLUDE: {
            "type": "object",
            "properties": {
                "file": {"type": "string", "description": "Subtree file, relative to this file or trees/."},
                "params": {"type": "object", "description": "Values of the subtree's parameters."},
                NAME_KEY: {"type": "string", "description": "Name of the subtree's root node."},
                **_condition_properties(),
            },
            "required": ["file"],
            "additionalProperties": False,
        }},
        "required": [INCLUDE],
        "additionalProperties": False,
    }
