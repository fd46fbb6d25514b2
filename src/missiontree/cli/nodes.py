"""``missiontree nodes``: the manifest of every node type, its parameters and blackboard ports.

Text for people, ``--json`` for tools (editors, docs generators). Each entry names the plugin
that provides the type.
"""

from __future__ import annotations

import argparse
import typing
from typing import Any

from pydantic.fields import FieldInfo

from missiontree.cli import add_plugin_flag, plugins_from_args, print_json
from missiontree.engine.json_lines import plain
from missiontree.engine.ports import Port
from missiontree.engine.registry import NodeRegistry, NodeType
from missiontree.errors import ConfigError


def register(subparsers: Any) -> None:
    """Add the ``nodes`` subcommand."""
    parser = subparsers.add_parser(
        "nodes", help="list node types with their parameters and ports",
        description="Print every node type mission files can use: parameters (type, default, meaning) "
        "and blackboard ports, and the plugin that provides it.",
    )
    parser.add_argument("names", nargs="*", metavar="TYPE", help="only these node types")
    parser.add_argument("--json", action="store_true", help="print the manifest as JSON")
    add_plugin_flag(parser)
    parser.set_defaults(func=run)


def type_name(annotation: Any) -> str:
    """A readable name of a parameter's type (``float``, ``list[str]``, ``Literal['a', 'b']``)."""
    if annotation is None or annotation is type(None):
        return "None"
    if isinstance(annotation, type) and not typing.get_args(annotation):
        return annotation.__name__
    return str(annotation).replace("typing.", "").replace("NoneType", "None")


def _default(info: FieldInfo) -> tuple[bool, Any]:
    if info.is_required():
        return True, None
    return False, plain(info.get_default(call_default_factory=True))


def describe_param(name: str, info: FieldInfo) -> dict[str, Any]:
    """One parameter: name, type, whether required, default and meaning."""
    required, default = _default(info)
    entry: dict[str, Any] = {"name": name, "type": type_name(info.annotation), "required": required,
                             "doc": info.description or ""}
    if not required:
        entry["default"] = default
    return entry


def describe_port(name: str, info: FieldInfo, port: Port) -> dict[str, Any]:
    """One port: parameter name, direction, value type, default key and meaning."""
    required, default = _default(info)
    entry: dict[str, Any] = {"name": name, "direction": port.direction, "type": port.type,
                             "doc": port.doc or info.description or "", "required": required}
    if not required:
        entry["key"] = default
    return entry


def describe(node_type: NodeType) -> dict[str, Any]:
    """The manifest entry of one node type."""
    fields = node_type.params.model_fields
    return {
        "name": node_type.name,
        "category": node_type.category,
        "provider": node_type.provider,
        "summary": node_type.summary,
        "params": [describe_param(n, f) for n, f in fields.items() if n not in node_type.ports],
        "ports": [describe_port(n, fields[n], p) for n, p in node_type.ports.items() if n in fields],
    }


def manifest(registry: NodeRegistry, names: list[str] | None = None) -> list[dict[str, Any]]:
    """Manifest entries of every node type (or of ``names``), sorted by name.

    Raises:
        ConfigError: A name is not a known node type (suggests the nearest).
    """
    if names:
        unknown = [n for n in names if n not in registry]
        if unknown:
            hints = "; ".join(f"{n!r}: did you mean {', '.join(registry.nearest(n)) or 'nothing close'}"
                              for n in unknown)
            raise ConfigError(f"unknown node type(s): {hints} (run `missiontree nodes` for the list)")
        return [describe(registry.get(n)) for n in sorted(set(names))]  # type: ignore[arg-type]
    return [describe(t) for t in registry]


def format_entry(entry: dict[str, Any]) -> str:
    """The text form of one manifest entry."""
    lines = [f"{entry['name']}  ({entry['category']}, from {entry['provider']})"]
    if entry["summary"]:
        lines.append(f"    {entry['summary']}")
    for param in entry["params"]:
        value = "required" if param["required"] else f"= {param['default']!r}"
        doc = f"  {param['doc']}" if param["doc"] else ""
        lines.append(f"    {param['name']}: {param['type']} {value}{doc}")
    for port in entry["ports"]:
        arrow = "<- reads " if port["direction"] == "in" else "-> writes"
        key = "key required" if port["required"] else f"key {port.get('key')!r}"
        doc = f"  {port['doc']}" if port["doc"] else ""
        lines.append(f"    {arrow} {port['name']} ({port['type']}, {key}){doc}")
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    """Print the manifest."""
    plugins = plugins_from_args(args)
    entries = manifest(plugins.nodes, args.names)
    if args.json:
        print_json({"nodes": entries})
    elif not entries:
        print("no node types registered (is a built-in module missing from plugins/builtin.py?)")
    else:
        print("\n\n".join(format_entry(e) for e in entries))
    return 0
