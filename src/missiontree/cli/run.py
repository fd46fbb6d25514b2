"""``missiontree run MISSION``: run a mission through the session and report how it ended.

Values come from, in order of precedence: the command-line flags, the mission's ``run:`` section,
then the defaults (:mod:`missiontree.session.mission`). Exit code 0 when the mission succeeded,
1 when it failed or hit the duration limit, 2 on bad input, 128+N when stopped by signal N.
"""

from __future__ import annotations

import argparse
import dataclasses
from collections.abc import Callable
from pathlib import Path
from typing import Any

from missiontree.cli import add_plugin_flag, plugins_from_args
from missiontree.engine.build import build_tree
from missiontree.engine.faults import VERDICT_WORDS
from missiontree.engine.loader import load_mission
from missiontree.engine.reload import TreeWatcher
from missiontree.engine.runner import RunResult
from missiontree.engine.spec import MissionSpec
from missiontree.engine.substitute import Rule, apply_rules, load_rules, substitute_session
from missiontree.errors import ConfigError
from missiontree.session.fleet import substitute_fleet
from missiontree.session.mission import (
    DEFAULT_BACKEND,
    DEFAULT_SEED,
    DEFAULT_TICK_HZ,
    MissionRequest,
    Session,
)
from missiontree.session.params import parse_assignment
from missiontree.session.rundir import RunDirectory

EPILOG = """\
Defaults: every flag left out is taken from the mission file's `run:` section (backend, world,
robot, models, config, tick_hz, max_duration, seed, realtime, map), then from the built-in defaults
shown above. `--set key=value` replaces a default of the mission's `params:` section; the value is
checked against the type of that default and of every node parameter that reads it, e.g.

  missiontree run trees/patrol.yaml --set laps=3 --set route=scenario_b
  missiontree run trees/find_object.yaml --set target="red backpack" --unknown-map

`--substitute rules.yaml` swaps nodes for stubs without editing the mission (a test with its
perception stubbed; see docs/testing-missions.md):

  missiontree run trees/find_object.yaml --substitute tests/substitutions/find_object.yaml

`--watch` reloads the mission when its file (or a subtree it includes) changes: checked again,
then the running tree is halted (robot stopped), rebuilt and restarted with the blackboard kept; a
broken edit is printed and the old tree goes on. Both are in the tick log (reloaded,
reload_refused).

A progress line (robot time, real-time factor, root status, last event) goes to stderr: redrawn
in place on a terminal, a plain line every 10 s otherwise; --quiet silences it.
"""


def register(subparsers: Any) -> None:
    """Add the ``run`` subcommand."""
    parser = subparsers.add_parser(
        "run", help="run a mission on a robot backend",
        description="Run a mission file on the simulator (default) or ROS 2 and write a run directory "
        "with ticks.jsonl, summary.json and pictures. The mission's `run:` section supplies the "
        "defaults of every flag below.",
        epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("tree", type=Path, help="the mission file (YAML)")
    parser.add_argument("--set", dest="params", action="append", default=[], metavar="KEY=VALUE",
                        help="set one of the mission's params: (repeatable; checked against its type)")
    parser.add_argument("--backend", help=f"robot backend (default: run.backend, else {DEFAULT_BACKEND})")
    parser.add_argument("--world", help="simulator world: a shipped name or a path (default: run.world)")
    parser.add_argument("--robot", help="robot profile: a shipped name (turtlebot4) or a path "
                        "(default: run.robot)")
    parser.add_argument("--config", help="run configuration: a YAML file, handed to the backend and leaves "
                        "(default: run.config)")
    parser.add_argument("--models", help="models config: a shipped name or a path (default: run.models, "
                        "else offline)")
    parser.add_argument("--seed", type=int, help=f"random seed (default: run.seed, else {DEFAULT_SEED})")
    parser.add_argument("--out", type=run_directory, help="run directory (default: runs/<mission name>); "
                        "an earlier run's files in it are replaced, one run at a time")
    parser.add_argument("--max-duration", type=float, metavar="S",
                        help="stop after S seconds on the robot clock (default: run.max_duration, else none)")
    parser.add_argument("--tick-hz", type=float, metavar="H",
                        help=f"tick rate (default: run.tick_hz, else {DEFAULT_TICK_HZ:g})")
    parser.add_argument("--realtime", action="store_true", default=None,
                        help="pace the ticks to wall time (the simulator then runs no faster than life; "
                        "default: run.realtime)")
    parser.add_argument("--unknown-map", action="store_true", default=None,
                        help="start without the world's map: the robot learns it from its lidar "
                        "(default: run.map, else known)")
    parser.add_argument("--quiet", "-q", action="store_true", help="no progress line on stderr")
    parser.add_argument("--view", action="store_true",  # served by missiontree.cli.view (the viewer's owner)
                        help="serve the live viewer on 127.0.0.1:8765 while the mission runs")
    parser.add_argument("--allow-outside", action="store_true",
                        help="let subtree includes leave the mission's folder")
    parser.add_argument("--substitute", type=Path, metavar="RULES",
                        help="a rules file: nodes matched by path or type glob are replaced by stubs "
                        "(fixed status, delay, blackboard writes); recorded in the log and summary")
    parser.add_argument("--watch", action="store_true",
                        help="reload the mission when its file or an included subtree changes (checked "
                        "first; the tree restarts, the blackboard is kept)")
    parser.add_argument("--robots", type=robot_number, metavar="N",
                        help="robots in one simulated world (or, with --backend ros2, one ROS 2 robot per "
                        "namespace /robot1 ... /robotN), the mission's tree run once per robot on one "
                        "clock (default: --set robots=, else run.robots, else 1; docs/fleet.md)")
    parser.add_argument("--kill-robot", dest="kill_robots", action="append", default=[],
                        metavar="NAME@S", help="fleet fault injection: kill robot NAME at S seconds "
                        "(its goals abort as a vanished server's; repeatable)")
    add_plugin_flag(parser)
    parser.set_defaults(func=run)


def robot_number(text: str) -> int:
    """``--robots``' type: a whole number from 1."""
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected a whole number of robots from 1, found {text!r}")
    return value


def run_directory(text: str) -> Path:
    """``--out``'s type: a directory path; an empty one is refused (it would mean the working directory)."""
    if not text.strip():
        raise argparse.ArgumentTypeError("the run directory is an empty path; name a directory")
    return Path(text)


def request_from_args(args: argparse.Namespace) -> MissionRequest:
    """The session request the flags describe (``None`` where a flag was left out)."""
    params: dict[str, str] = {}
    for item in args.params or []:
        key, value = parse_assignment(item)
        params[key] = value
    return MissionRequest(
        mission=args.tree, backend=args.backend, world=args.world, robot=args.robot, models=args.models,
        config=args.config, seed=args.seed, out=args.out, max_duration=args.max_duration,
        tick_hz=args.tick_hz,
        realtime=args.realtime, params=params, unknown_map=args.unknown_map, quiet=bool(args.quiet),
        allow_outside=bool(args.allow_outside), plugins=plugins_from_args(args),
        robots=getattr(args, "robots", None), kill_robots=list(getattr(args, "kill_robots", None) or []))


def run_substituted(request: MissionRequest, rules: list[Rule] | None = None, *,
                    watch: bool = False) -> RunResult:
    """Run a mission through the session (the Python API of ``run --substitute`` and ``--watch``).

    Args:
        request: What to run.
        rules: Substitution rules applied to the tree before it runs (and to every reloaded tree);
            default: the rules of ``request.substitute``, which the session itself applies.
        watch: Reload the mission when its files change (:class:`~missiontree.engine.reload.TreeWatcher`).

    Raises:
        MissionFileError: The mission is broken or a rule matches no node.
    """
    watchers: list[TreeWatcher] = []
    if watch:
        request = dataclasses.replace(request, on_tick=_watching(request.on_tick, watchers))
    if request.substitute and rules is None:  # the session applies them; a reloaded tree needs them too
        rules = load_rules(request.substitute)
    with Session.open(request) as session:
        if rules and not request.substitute:
            if session.fleet is not None:
                substitute_fleet(session, rules)
            else:
                substitute_session(session, rules)
        if watch and session.fleet is not None:
            raise ConfigError("--watch reloads one tree; it is not built for fleet runs (robots > 1) yet")
        if watch:
            watchers.append(TreeWatcher(session.spec, _loader(request, session), _builder(session, rules)))
        return session.run()


def _watching(previous: Callable[[Session], None] | None,
              watchers: list[TreeWatcher]) -> Callable[[Session], None]:
    """The session's per-tick callback: the watcher (once made), then the one asked for."""

    def on_tick(session: Session) -> None:
        for watcher in watchers:
            watcher(session.runner)
        session.root = session.runner.root
        if previous is not None:
            previous(session)

    return on_tick


def _loader(request: MissionRequest, session: Session) -> Callable[[], MissionSpec]:
    mission = Path(request.mission)

    def load() -> MissionSpec:
        return load_mission(mission, session.plugins.nodes, allow_outside=request.allow_outside,
                            params=dict(request.params or {}))

    return load


def _builder(session: Session, rules: list[Rule] | None) -> Callable[[MissionSpec], Any]:
    def build(spec: MissionSpec) -> Any:
        root = build_tree(spec, session.plugins.nodes)
        return apply_rules(spec, root, rules)[0] if rules else root

    return build


def run(args: argparse.Namespace) -> int:
    """Run the mission; print a one-line result and where the run directory is."""
    # read once, here (the file may be a pipe: --substitute /dev/stdin); run_substituted applies them
    rules = load_rules(args.substitute) if getattr(args, "substitute", None) is not None else None

    def run_mission(request: MissionRequest) -> RunResult:
        return run_substituted(request, rules, watch=bool(getattr(args, "watch", False)))

    if getattr(args, "view", False):
        from missiontree.cli.view import run_with_viewer

        request = request_from_args(args)
        # claimed (checked, locked, cleared) before the viewer writes into it; the session's own
        # claim then finds this process's lock and keeps it
        claim = RunDirectory.claim(args.out if args.out is not None else Path("runs") / args.tree.stem)
        try:
            return run_with_viewer(args, request, run_mission, describe)
        finally:
            claim.release()
    result = run_mission(request_from_args(args))
    print(describe(result))
    return result.exit_code


def describe(result: RunResult) -> str:
    """One line: how the run ended and where its directory is."""
    why = {"status": "", "limit": " (duration limit reached)", "error": " (stopped by an error)",
           "signal": f" (stopped by {result.summary.get('signal') or 'a signal'})"}[result.stopped_by]
    if result.plugin_error:
        why += f" ({result.plugin_error})"
    stubs = result.summary.get("substitutions")
    if isinstance(stubs, list) and stubs:  # an outcome reached with stubs is a test's, not the robot's
        why += f" ({len(stubs)} node(s) substituted)"
    fault = result.summary.get("fault")
    if isinstance(fault, dict):  # failed because of an error, not because a condition was false
        why += f" (fault in {fault.get('node')}: {fault.get('error')})"
    where = f"; run directory {result.run_dir}" if result.run_dir is not None else ""
    line = (f"{result.summary.get('mission', 'mission')}: {result.status.name}{why} after {result.ticks} "
            f"ticks, {result.duration:.1f} s on the robot clock{where}")
    said = outcome_text(result.summary)
    return f"{line}\n  {said}" if said else line


#: Longest outcome text printed on the result line (the run directory holds the whole of it).
OUTCOME_CHARS = 400


def outcome_text(summary: dict[str, Any]) -> str:
    """What the mission did in its own words: its leaves' outcome reports, else why it failed.

    A leaf's report (summary.json ``outcome``) may carry a ``text``; a FAILURE is also explained
    by the deepest node whose failure decided the outcome, and when that node only
    wraps its children's failures (a Retry that ran out of attempts), also by a reason of the
    deepest node below it that failed (``log summarize`` has them all, in order).
    """
    texts = [str(section["text"]) for section in (summary.get("outcome") or {}).values()
             if isinstance(section, dict) and section.get("text")]
    if summary.get("status") == "FAILURE":
        reason = _deciding_reason(summary)
        if reason and not any(reason[:60] in text for text in texts):  # not said twice
            texts.append(f"why: {reason}")
    text = "; ".join(texts)
    return text if len(text) <= OUTCOME_CHARS else text[:OUTCOME_CHARS - 1] + "…"


def _deciding_reason(summary: dict[str, Any]) -> str:
    failures = summary.get("failures") or {}
    decided = [path for path, entry in failures.items()
               if isinstance(entry, dict) and entry.get("decided") and entry.get("reasons")]
    if not decided:
        return ""
    node = max(decided, key=lambda path: path.count("/"))
    reason = str(failures[node]["reasons"][-1])
    below = [(path.count("/"), order, path) for order, path in enumerate(summary.get("failure_reasons") or {})
             if path.startswith(node + "/")]
    if below and "; child " not in reason and not reason.startswith(VERDICT_WORDS):
        deepest = max(below)[2]
        reason = f"{reason}; below it: {summary['failure_reasons'][deepest][-1]}"
    return reason
