"""``missiontree batch MISSION``: run a mission over seeds, worlds and parameter values; report rates.

Runs go to a local process pool (default, ``--jobs`` workers) or a Dask cluster (``--dask``); every
run through the session, in its own run directory. Writes ``results.jsonl``, ``summary.json`` and
``junit.xml`` into ``--out`` and prints a table. Exit code 0 when every run succeeded (or the
``--min-success`` rate is met), 1 otherwise or when a run was lost to infrastructure, 2 on bad
input or a missing extra, 130 when interrupted.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path
from typing import Any

from missiontree.cli import add_plugin_flag, plugins_from_args
from missiontree.errors import ConfigError, MissionFileError
from missiontree.evaluation.batch import lock_batch, make_engine, run_batch
from missiontree.evaluation.plan import (
    BatchPlan,
    expand_plan,
    parse_assignments,
    parse_seeds,
    parse_sweeps,
    parse_worlds,
)
from missiontree.evaluation.progress import BatchProgress
from missiontree.evaluation.report import (
    batch_passed,
    format_table,
    summarize,
    write_junit,
    write_results,
)
from missiontree.plugins.manager import DISABLE_ENV

EPILOG = """\
Seeds and worlds take lists and ranges; sweeps make a grid (every combination), e.g.

  missiontree batch trees/patrol.yaml --seeds 0-99 --worlds combined --sweep laps=1,2
  missiontree batch trees/explore.yaml --seeds 0-9 --worlds office,generated:0-49 --unknown-map
  missiontree batch trees/patrol.yaml --seeds 0-999 --dask tcp://scheduler:8786 --min-success 0.95

Each run's seed is its batch seed (the same in every world and for every parameter value, so values
are compared on the same draws); --base-seed B derives them from B instead. Both are recorded.
--resume keeps the complete runs in --out and runs the rest (a killed batch leaves no half runs).
A run whose process crashes is retried once; crashing again it is an infrastructure failure,
counted apart from the mission's results, and fails the batch.
--dask ADDRESS runs on a Dask distributed cluster (default: $DASK_SCHEDULER_ADDRESS); --dask local
starts one on this machine. Needs the 'dask' extra: pip install 'missiontree[dask]'. Workers
write the run directories: on a multi-machine cluster --out must be on a filesystem they share.
--dask local starts its workers without Dask's statistical profiler and without the nanny's
MALLOC_TRIM_THRESHOLD_ (together they made a mission about a quarter slower than in the pool); on
a remote cluster set the same in the workers' Dask config before starting them:
distributed.worker.profile.enabled: false and
distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_: null.
"""


def register(subparsers: Any) -> None:
    """Add the ``batch`` subcommand."""
    parser = subparsers.add_parser(
        "batch", help="run a mission over many seeds, worlds and parameter values",
        description="Run a mission many times (seeds × worlds × parameter grid) on a local process pool "
        "or a Dask cluster; write results.jsonl, summary.json, junit.xml and print success rates with "
        "95 percent Wilson intervals.", epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("tree", type=Path, help="the mission file (YAML)")
    parser.add_argument("--seeds", default="0-9", help="batch seeds: a list and ranges, e.g. 0-999,2000 "
                        "(default: 0-9)")
    parser.add_argument("--worlds", help="worlds: names, paths, ranges of a world source, e.g. "
                        "office,generated:0-49 (default: the mission's own)")
    parser.add_argument("--set", dest="params", action="append", default=[], metavar="KEY=VALUE",
                        help="set one of the mission's params: for every run (repeatable)")
    parser.add_argument("--sweep", action="append", default=[], metavar="KEY=V1,V2",
                        help="one run per value of a param; several sweeps make a grid (repeatable)")
    parser.add_argument("--jobs", "-j", type=int, metavar="N",
                        help=f"worker processes (default: the cores, {os.cpu_count() or 1} here; with "
                        "--dask local the cluster's workers; a remote cluster runs as many as it has)")
    parser.add_argument("--out", type=Path, help="batch directory (default: runs/batch/<mission name>)")
    parser.add_argument("--resume", action="store_true", help="keep complete runs in --out, run the rest")
    parser.add_argument("--min-success", type=_rate, metavar="RATE",
                        help="pass when this share of runs succeeds (0-1, or a percentage like 95%%) "
                        "instead of requiring all")
    parser.add_argument("--dask", metavar="ADDRESS", help="run on Dask: tcp://HOST:8786, or 'local' for a "
                        "LocalCluster (default: $DASK_SCHEDULER_ADDRESS, else the local process pool)")
    parser.add_argument("--base-seed", type=int, metavar="B", help="derive each run's seed from B and its "
                        "batch seed instead of using the batch seed itself")
    parser.add_argument("--backend", help="robot backend (default: the mission's run.backend, else sim)")
    parser.add_argument("--robot", help="robot profile (default: run.robot)")
    parser.add_argument("--models", help="models config (default: run.models, else offline)")
    parser.add_argument("--config", help="run configuration YAML (default: run.config)")
    parser.add_argument("--max-duration", type=float, metavar="S", help="robot-clock limit of each run")
    parser.add_argument("--tick-hz", type=float, metavar="H", help="tick rate (default: run.tick_hz)")
    parser.add_argument("--unknown-map", action="store_true", default=None,
                        help="every run starts without the world's map")
    parser.add_argument("--no-logs", action="store_true", help="do not keep each run's ticks.jsonl")
    parser.add_argument("--log", choices=("sqlite",), help="also write every run's tick log into "
                        "<out>/log.sqlite (appended; query it with `missiontree log query`)")
    parser.add_argument("--quiet", "-q", action="store_true", help="no progress bar")
    parser.add_argument("--allow-outside", action="store_true",
                        help="let subtree includes leave the mission's folder")
    parser.add_argument("--substitute", type=Path, metavar="RULES",
                        help="a rules file: in every run, nodes matched by path or type glob are replaced by "
                        "stubs; recorded in each run's log and summary (checked before any run starts)")
    add_plugin_flag(parser)
    parser.set_defaults(func=run)


def _rate(text: str) -> float:
    value = text.strip()
    try:
        rate = float(value[:-1]) / 100 if value.endswith("%") else float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a rate 0-1 or a percentage, found {text!r}") from None
    if not 0.0 <= rate <= 1.0:
        raise argparse.ArgumentTypeError(f"expected a rate 0-1 or a percentage 0-100%, found {text!r}")
    return rate


def plan_from_args(args: argparse.Namespace) -> BatchPlan:
    """The batch plan the flags describe (checked: see :func:`preflight`)."""
    if getattr(args, "log", None) and args.no_logs:
        raise ConfigError("--log sqlite is written from each run's ticks.jsonl; drop --no-logs")
    if not args.tree.is_file():
        raise ConfigError(f"mission file {str(args.tree)!r} does not exist")
    if args.jobs is not None and args.jobs < 1:
        raise ConfigError(f"--jobs: expected 1 or more workers, found {args.jobs}")
    request = {k: v for k, v in {
        "backend": args.backend, "robot": args.robot, "models": args.models, "config": args.config,
        "max_duration": args.max_duration, "tick_hz": args.tick_hz, "unknown_map": args.unknown_map,
    }.items() if v is not None}
    if args.allow_outside:
        request["allow_outside"] = True
    if getattr(args, "substitute", None) is not None:  # absolute: workers may run in another directory
        if not Path(args.substitute).is_file():  # every run reads it: a pipe would be empty after the first
            raise ConfigError(f"--substitute: {str(args.substitute)!r} is not a file; batch runs read the "
                              "rules file in every run, give a regular file")
        request["substitute"] = str(Path(args.substitute).resolve())
    return expand_plan(
        args.tree, seeds=parse_seeds(args.seeds), worlds=parse_worlds(args.worlds) if args.worlds else None,
        fixed=parse_assignments(args.params), sweeps=parse_sweeps(args.sweep), base_seed=args.base_seed,
        request=request)


def preflight(plan: BatchPlan, plugins: Any) -> None:
    """Check the mission with every parameter combination and every world before any run starts.

    The substitution rules file (``--substitute``) is read and its rules matched against the tree too.

    Raises:
        ProblemsError: The mission, a ``--set``/``--sweep`` value, a world or the rules file is bad (all
            reported).
    """
    from missiontree.engine.build import build_tree
    from missiontree.engine.loader import load_mission
    from missiontree.engine.substitute import apply_rules, load_rules
    from missiontree.session.preflight import check_references

    allow = bool(plan.request.get("allow_outside"))
    combos = list(dict.fromkeys(run.params for run in plan.runs))
    worlds = list(dict.fromkeys(run.world for run in plan.runs))
    spec = None
    for params in combos:
        spec = load_mission(plan.mission, plugins.nodes, allow_outside=allow, params=dict(params))
    substitute = plan.request.get("substitute")
    if substitute is not None and spec is not None:  # a rule matching no node is refused before any run
        apply_rules(spec, build_tree(spec, plugins.nodes), load_rules(substitute))
    problems = []
    for world in worlds:
        problems += check_references(spec,  # type: ignore[arg-type]  # a plan has runs, so spec is loaded
                                     providers=plugins.providers, backend=plan.request.get("backend"),
                                     world=world, robot=plan.request.get("robot"), check_models=False)
    if problems:
        raise MissionFileError(problems)


def run(args: argparse.Namespace) -> int:
    """Run the batch; print the table; return the exit code."""
    plan = plan_from_args(args)
    plugins = plugins_from_args(args)
    if not args.quiet:
        worlds = len({r.world for r in plan.runs})
        combos = len({r.params for r in plan.runs})
        print(f"batch {args.tree.stem}: checking the mission with {combos} parameter set(s) on {worlds} "
              "world(s) before any run", file=sys.stderr)
    preflight(plan, plugins)
    if args.no_plugins:
        os.environ[DISABLE_ENV] = "1"  # workers load plugins as this process did
    out = args.out or Path("runs") / "batch" / args.tree.stem
    with lock_batch(out):  # one batch at a time in --out, results.jsonl included
        return _run_locked(args, plan, out)


def _run_locked(args: argparse.Namespace, plan: BatchPlan, out: Path) -> int:
    """Run the batch into ``out`` (locked by the caller), write its results, print the table."""
    engine = make_engine(args.dask, args.jobs)
    progress = None if args.quiet else BatchProgress(len(plan.runs), label=f"batch {args.tree.stem}")
    started = time.perf_counter()
    try:
        with engine:
            if not args.quiet:
                print(f"batch {args.tree.stem}: {len(plan.runs)} runs on {engine.describe()['name']} "
                      f"({engine.workers} workers) -> {out}", file=sys.stderr)
            records = run_batch(plan, engine, out, resume=args.resume, write_log=not args.no_logs,
                                on_record=progress)
    finally:
        if progress is not None:
            progress.close()
    wall = time.perf_counter() - started
    summary = summarize(records, plan.sweep_keys, mission=str(args.tree), engine=engine.describe(),
                        batch_wall_s=round(wall, 3), min_success=args.min_success)
    passed = batch_passed(summary, args.min_success)
    summary["passed_batch"] = passed
    write_results(records, out / "results.jsonl")
    import json

    (out / "summary.json").write_text(json.dumps(summary, indent=2, sort_keys=True) + "\n", encoding="utf-8")
    write_junit(records, out / "junit.xml", name=f"missiontree.batch.{args.tree.stem}")
    if getattr(args, "log", None) == "sqlite":
        write_sqlite_log(records, out, args.tree)
    print(format_table(summary))
    verdict = "passed" if passed else "FAILED"
    need = f" (needs {100 * args.min_success:.1f}%)" if args.min_success is not None else ""
    print(f"batch {verdict}{need}: {summary['passed']}/{summary['results']} runs succeeded, "
          f"{summary['infra_failures']} lost to infrastructure, {wall:.1f} s; results in {out}")
    return 0 if passed else 1


def write_sqlite_log(records: list[Any], out: Path, mission: Path) -> Path:
    """Append every run of the batch that has a tick log to ``out/log.sqlite``; return its path."""
    from missiontree.runlog.sqlite_log import add_run, connect

    path = out / "log.sqlite"
    db = connect(path)
    try:
        for record in records:
            if record.run_dir is None or not (out / record.run_dir / "ticks.jsonl").is_file():
                continue
            add_run(db, out / record.run_dir, name=record.run_id,
                    extra={"world": record.world, "seed": record.seed, "params": record.params})
    finally:
        db.close()
    return path
