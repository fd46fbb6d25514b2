"""``missiontree validate TREE…``: check mission files whole, report every problem, build nothing that runs.

Each valid file prints one ``ok`` line on stdout. Each problem prints one line on stderr,
``file:line:col: node path: expected …, found … (hint: …)``; the exit code is 2 when any file
has a problem. A valid file is also built (constructors only, no robot) so a plugin whose
factory refuses its parameters is caught here too.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from missiontree.cli import add_plugin_flag, plugins_from_args
from missiontree.engine.build import build_tree
from missiontree.engine.loader import load_mission
from missiontree.engine.registry import NodeRegistry
from missiontree.errors import MissionFileError, Problem

EXIT_OK = 0
EXIT_BAD_INPUT = 2


def register(subparsers: Any) -> None:
    """Add the ``validate`` subcommand."""
    parser = subparsers.add_parser(
        "validate", help="check mission files and report every problem",
        description="Check mission files (and the subtrees they include) against the registered node "
        "types; print every problem as file:line:col: node path: expected ..., found ...; exit 2 if any.",
    )
    parser.add_argument("trees", nargs="+", type=Path, metavar="TREE", help="mission files (YAML)")
    parser.add_argument("--allow-outside", action="store_true",
                        help="let subtree includes leave the mission's folder")
    parser.add_argument("-q", "--quiet", action="store_true", help="print problems only")
    add_plugin_flag(parser)
    parser.set_defaults(func=run)


def check_files(
    paths: list[Path], registry: NodeRegistry, *, allow_outside: bool = False
) -> dict[Path, list[Problem]]:
    """Check each file; return its problems (empty for a valid file)."""
    results: dict[Path, list[Problem]] = {}
    for path in paths:
        try:
            spec = load_mission(path, registry, allow_outside=allow_outside)
            build_tree(spec, registry)
        except MissionFileError as error:
            results[path] = error.problems
        else:
            results[path] = []
    return results


def run(args: argparse.Namespace) -> int:
    """Check every file named; print ok lines and problem lines; exit 2 on any problem."""
    registry = plugins_from_args(args).nodes
    results = check_files(list(args.trees), registry, allow_outside=args.allow_outside)
    total = 0
    for path, problems in results.items():
        if not problems and not args.quiet:
            print(f"ok: {path}")
        for problem in problems:
            print(str(problem), file=sys.stderr)
        total += len(problems)
    if total:
        bad = sum(1 for problems in results.values() if problems)
        print(f"{total} problem{'s' if total != 1 else ''} in {bad} file{'s' if bad != 1 else ''}",
              file=sys.stderr)
        return EXIT_BAD_INPUT
    return EXIT_OK
