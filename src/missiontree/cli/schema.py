"""``missiontree schema``: print the JSON Schema of mission files, for editor completion and checking.

The schema is generated from the node registry, so node types from installed plugins appear.
Point an editor at it as docs/mission-format.md describes (yaml-language-server's
``# yaml-language-server: $schema=...`` comment or the editor's schema settings).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from missiontree.cli import add_plugin_flag, plugins_from_args
from missiontree.engine.schema import mission_schema


def register(subparsers: Any) -> None:
    """Add the ``schema`` subcommand."""
    parser = subparsers.add_parser(
        "schema", help="print the JSON Schema of mission files",
        description="Print the JSON Schema (draft 2020-12) of mission files, including every registered "
        "node type's parameters, for editors to complete and check missions.",
    )
    parser.add_argument("-o", "--out", type=Path, help="write the schema to this file instead of stdout")
    add_plugin_flag(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Print (or write) the schema."""
    text = json.dumps(mission_schema(plugins_from_args(args).nodes), indent=2, sort_keys=False) + "\n"
    if args.out is not None:
        args.out.write_text(text, encoding="utf-8")
        print(f"wrote {args.out}")
    else:
        print(text, end="")
    return 0
