"""``missiontree log export RUN --format btlog|mcap --out FILE``: a run for Groot2 or Foxglove.

``btlog`` writes Groot2's FileLogger2 file as BehaviorTree.CPP 4.x does (see
:mod:`missiontree.runlog.btlog`); ``mcap`` writes JSON channels for ticks, node transitions,
blackboard, events (also as ``foxglove.Log``) and the robot's poses (see
:mod:`missiontree.runlog.mcap_export`). Both are byte-identical for the same run.
``sqlite`` writes (or appends to) a queryable log (:mod:`missiontree.runlog.sqlite_log`;
``missiontree log query``). Registered as an action of ``missiontree log`` (:func:`add_to`).
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from missiontree.errors import ConfigError

FORMATS = ("btlog", "mcap", "sqlite")


def add_to(actions: Any) -> None:
    """Add the ``export`` action to the ``log`` subcommand's actions."""
    parser = actions.add_parser(
        "export",
        help="write the run for Groot2 (.btlog), Foxglove/Lichtblick (.mcap) or SQL (.sqlite)",
        description="Export a run's tick log: --format btlog (Groot2 FileLogger2, as BehaviorTree.CPP 4.x "
        "writes it), --format mcap (JSON channels; needs the viewer extra) or --format sqlite (tables runs, "
        "nodes, transitions, events; an existing file gets the run appended; query it with `missiontree log "
        "query`).",
    )
    parser.add_argument("run_path", metavar="RUN", type=Path, help="a run directory or its ticks.jsonl")
    parser.add_argument("--format", required=True, choices=FORMATS, help="btlog, mcap or sqlite")
    parser.add_argument("--out", required=True, type=Path, help="the file to write (run.btlog, run.mcap)")
    parser.add_argument(
        "--mission", type=Path, help="the mission file, for runs that did not record their tree"
    )
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Write the export; print where it went."""
    from missiontree.runlog.replay import open_run

    if args.out.is_dir():
        raise ConfigError(f"--out {args.out} is a directory; give a file name such as run.{args.format}")
    if not args.out.parent.is_dir():
        raise ConfigError(f"--out {args.out}: the directory {args.out.parent} does not exist")
    if args.format == "sqlite":
        from missiontree.runlog.sqlite_log import add_run, connect

        db = connect(args.out)
        try:
            run_id = add_run(db, args.run_path, mission=args.mission)
            runs = db.execute("SELECT COUNT(*) FROM runs").fetchone()[0]
        finally:
            db.close()
        print(f"wrote run {run_id} into {args.out} ({runs} run(s) in it)")
        return 0
    replay = open_run(args.run_path, args.mission)
    if args.format == "btlog":
        from missiontree.runlog.btlog import write_btlog

        path = write_btlog(replay, args.out)
    else:
        from missiontree.runlog.html import run_map
        from missiontree.runlog.mcap_export import write_mcap

        run_dir = args.run_path if args.run_path.is_dir() else args.run_path.parent
        path = write_mcap(replay, args.out, grid_map=run_map(run_dir))
    print(f"wrote {path} ({path.stat().st_size} bytes, {len(replay)} ticks)")
    return 0
