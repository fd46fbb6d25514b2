"""``missiontree render TREE``: draw a mission's tree as text, Graphviz dot or SVG.

The drawing comes from the checked mission (every node's type, name and the parameters written
in the file), so it needs no robot. ``--format svg`` runs Graphviz's ``dot``; without it the
command says how to install it or how to get the dot source instead.
"""

from __future__ import annotations

import argparse
import json
import re
import shutil
import subprocess
from pathlib import Path
from typing import Any

from missiontree.cli import add_plugin_flag, plugins_from_args
from missiontree.engine.loader import load_mission
from missiontree.engine.spec import MissionSpec, NodeSpec
from missiontree.errors import ConfigError

_MAX_VALUE = 40
_SPACE = re.compile(r"\s")
_SHAPES = {"composite": "box", "decorator": "hexagon", "leaf": "ellipse"}


def register(subparsers: Any) -> None:
    """Add the ``render`` subcommand."""
    parser = subparsers.add_parser(
        "render", help="draw a mission's tree (text, dot or svg)",
        description="Draw a mission's tree: a unicode tree (default), Graphviz dot source, or SVG "
        "(needs Graphviz's `dot`).",
    )
    parser.add_argument("tree", type=Path, help="the mission file (YAML)")
    parser.add_argument("-f", "--format", choices=("text", "dot", "svg"), default="text",
                        help="output format (default: text)")
    parser.add_argument("-o", "--out", type=Path, help="write to this file instead of stdout")
    parser.add_argument("--allow-outside", action="store_true",
                        help="let subtree includes leave the mission's folder")
    add_plugin_flag(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Load and check the mission, then draw it."""
    spec = load_mission(args.tree, plugins_from_args(args).nodes, allow_outside=args.allow_outside)
    if args.format == "text":
        output: str | bytes = unicode_tree(spec)
    elif args.format == "dot":
        output = dot_source(spec)
    else:
        output = svg(dot_source(spec))
    if args.out is None:
        print(output if isinstance(output, str) else output.decode("utf-8"), end="")
    else:
        if isinstance(output, str):
            args.out.write_text(output, encoding="utf-8")
        else:
            args.out.write_bytes(output)
        print(f"wrote {args.out}")
    return 0


def label(node: NodeSpec) -> str:
    """``name (Type)`` or just ``Type`` when the node has no name of its own."""
    return node.type if node.name == node.type else f"{node.name} ({node.type})"


def params_text(node: NodeSpec) -> str:
    """The parameters and conditions as written, ``key=value`` separated by spaces, long values shortened.

    Text with spaces in it (an expression: ``skip_if="battery < 0.2"``) is quoted.

    Conditions (``skip_if``, ``on_success``, ...) are shown after the parameters: they change what
    the node does, so a drawn tree without them would mislead.
    """
    parts = []
    for key, value in [*node.raw.items(), *node.conditions.items()]:
        shown = f"{{bb: {value['bb']}}}" if isinstance(value, dict) and set(value) == {"bb"} else (
            value if isinstance(value, str) and not _SPACE.search(value) else json.dumps(value, default=str))
        text = str(shown)
        if len(text) > _MAX_VALUE:
            text = text[: _MAX_VALUE - 1] + "…"
        parts.append(f"{key}={text}")
    return " ".join(parts)


def unicode_tree(spec: MissionSpec) -> str:
    """The tree as indented text with box-drawing lines."""
    lines: list[str] = []

    def visit(node: NodeSpec, prefix: str, connector: str, child_prefix: str, parent_file: str) -> None:
        extra = params_text(node)
        origin = f"  [from {node.source.file}]" if node.source.file != parent_file else ""
        lines.append(f"{prefix}{connector}{label(node)}{'  ' + extra if extra else ''}{origin}")
        for i, child in enumerate(node.children):
            last = i == len(node.children) - 1
            visit(child, prefix + child_prefix, "└── " if last else "├── ", "    " if last else "│   ",
                  node.source.file)

    visit(spec.root, "", "", "", spec.root.source.file)
    return "\n".join(lines) + "\n"


def dot_source(spec: MissionSpec) -> str:
    """The tree as Graphviz dot source (composites boxes, decorators hexagons, leaves ellipses)."""
    out = ["digraph mission {", '  graph [rankdir=TB, fontname="Helvetica"];',
           '  node [fontname="Helvetica", fontsize=10];']
    counter = 0

    def visit(node: NodeSpec) -> str:
        nonlocal counter
        ident = f"n{counter}"
        counter += 1
        extra = params_text(node)
        text = _escape(label(node)) + (f"\\n{_escape(extra)}" if extra else "")
        shape = _SHAPES.get(node.category or "leaf", "ellipse")
        out.append(f'  {ident} [label="{text}", shape={shape}];')
        for child in node.children:
            out.append(f"  {ident} -> {visit(child)};")
        return ident

    visit(spec.root)
    out.append("}")
    return "\n".join(out) + "\n"


def svg(dot: str) -> bytes:
    """Render dot source to SVG with Graphviz's ``dot``.

    Raises:
        ConfigError: ``dot`` is not installed (names how to install it, or to use ``--format dot``).
    """
    exe = shutil.which("dot")
    if exe is None:
        raise ConfigError(
            "Graphviz's `dot` program was not found, so SVG cannot be drawn; install Graphviz "
            "(e.g. `sudo apt-get install graphviz`), or use `--format dot` and render the source elsewhere"
        )
    done = subprocess.run([exe, "-Tsvg"], input=dot.encode("utf-8"), capture_output=True, timeout=60,
                          check=False)
    if done.returncode != 0:
        raise ConfigError(f"Graphviz `dot` failed: {done.stderr.decode('utf-8', 'replace').strip()}")
    return done.stdout


def _escape(text: str) -> str:
    return text.replace("\\", "\\\\").replace('"', '\\"')
