"""``missiontree validate FILE…``: check files whole, report every problem, run nothing.

A mission file is checked with everything it references, as ``missiontree run`` would use it: its
subtrees, the world, the robot profile, the models config and its waypoint files
(:func:`missiontree.session.preflight.check_references`); it is also built (constructors only, no
robot) so a plugin whose factory refuses its parameters is caught here too. A world file, a robot
profile, a models config or a waypoint file is recognised by its content and checked alone.

Each valid file prints one ``ok`` line on stdout (naming its kind when it is not a mission). Each
problem prints one line on stderr, ``file:line:col: where: expected …, found … (hint: …)``; the
exit code is 2 when any file has a problem.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from missiontree.cli import add_plugin_flag, plugins_from_args
from missiontree.engine.build import build_tree
from missiontree.engine.loader import check_mission
from missiontree.engine.registry import NodeRegistry
from missiontree.errors import ConfigError, MissionFileError, Problem, ProblemsError
from missiontree.session.worlds import check_robot_file, check_waypoint_file, check_world_file
from missiontree.yamlio import load_yaml

EXIT_OK = 0
EXIT_BAD_INPUT = 2

#: The kinds of file ``validate`` recognises, by their top-level keys.
KINDS = ("mission", "world", "robot", "models", "waypoints")
_ROBOT_KEYS = {"body", "limits", "wheels", "odometry", "lidar", "camera", "navigation", "physics_dt",
               "history_horizon", "accelerate", "camera_thread"}


def register(subparsers: Any) -> None:
    """Add the ``validate`` subcommand."""
    parser = subparsers.add_parser(
        "validate", help="check missions, worlds, robot profiles, models configs and waypoint files",
        description="Check files and report every problem as file:line:col: where: expected ..., found ...; "
        "exit 2 if any. A mission is checked with what it references (subtrees, world, robot, models, "
        "waypoint files); a world, robot profile, models config or waypoint file is recognised by its "
        "content and checked alone.",
    )
    parser.add_argument("trees", nargs="+", type=Path, metavar="FILE", help="files to check (YAML)")
    parser.add_argument("--allow-outside", action="store_true",
                        help="let subtree includes leave the mission's folder")
    parser.add_argument("--backend", help="check a mission as run on this backend (default: the mission's)")
    parser.add_argument("--world", help="check a mission against this world (default: the mission's)")
    parser.add_argument("--robot", help="check a mission with this robot profile")
    parser.add_argument("--models", help="check a mission with this models config")
    parser.add_argument("-q", "--quiet", action="store_true", help="print problems only")
    add_plugin_flag(parser)
    parser.set_defaults(func=run)


def file_kind(data: Any) -> str:
    """What a parsed YAML document is: ``mission``, ``world``, ``robot``, ``models`` or ``waypoints``."""
    if not isinstance(data, Mapping) or "root" in data:
        return "mission"
    keys = set(data)
    if keys & {"roles", "calls"}:
        return "models"
    if keys & {"walls", "map", "people", "rooms", "objects"} or isinstance(data.get("robot"), Mapping):
        return "world"
    if keys & {"waypoints", "routes"}:
        return "waypoints"
    if keys & _ROBOT_KEYS:
        return "robot"
    return "mission"


def check_file(
    path: Path, registry: NodeRegistry, *, allow_outside: bool = False,
    providers: Mapping[str, Any] | None = None, references: Mapping[str, Any] | None = None,
) -> tuple[str, list[Problem]]:
    """Check one file of any kind; return its kind and its problems (empty for a valid file)."""
    try:
        data = load_yaml(path, error=ProblemsError).data
    except ProblemsError as error:
        return "file", error.problems
    kind = file_kind(data)
    try:
        if kind == "mission":
            return kind, _check_mission(path, registry, allow_outside, providers, references or {})
        if kind == "world":
            check_world_file(path)
        elif kind == "robot":
            check_robot_file(path)
        elif kind == "models":
            from missiontree.session.preflight import check_models_file

            return kind, check_models_file(path, providers or {})
        else:
            return kind, check_waypoint_file(path)
    except ProblemsError as error:
        return kind, error.problems
    except ConfigError as error:
        return kind, [Problem(str(path), 0, 0, "", str(error))]
    return kind, []


def _check_mission(path: Path, registry: NodeRegistry, allow_outside: bool,
                   providers: Mapping[str, Any] | None, references: Mapping[str, Any]) -> list[Problem]:
    from missiontree.session.preflight import check_references

    spec, problems = check_mission(path, registry, allow_outside=allow_outside)
    if spec is None:
        return problems
    if not problems:
        try:
            build_tree(spec, registry)
        except MissionFileError as error:
            problems = list(error.problems)
    # what the mission references is checked even when its tree has problems: all reported at once
    more = [p for p in check_references(spec, providers=providers, **references) if p not in problems]
    return sorted([*problems, *more], key=lambda p: (p.file != str(path), p.file, p.line, p.col))


def run(args: argparse.Namespace) -> int:
    """Check every file named; print ok lines and problem lines; exit 2 on any problem."""
    plugins = plugins_from_args(args)
    references = {key: getattr(args, key, None) for key in ("backend", "world", "robot", "models")}
    total = bad = 0
    for path in args.trees:
        kind, problems = check_file(path, plugins.nodes, allow_outside=args.allow_outside,
                                    providers=plugins.providers, references=references)
        if not problems and not args.quiet:
            print(f"ok: {path}" if kind == "mission" else f"ok: {path} ({kind})")
        for problem in problems:
            print(str(problem), file=sys.stderr)
        total += len(problems)
        bad += bool(problems)
    if total:
        print(f"{total} problem{'s' if total != 1 else ''} in {bad} file{'s' if bad != 1 else ''}",
              file=sys.stderr)
        return EXIT_BAD_INPUT
    return EXIT_OK
