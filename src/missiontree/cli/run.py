"""``missiontree run TREE``: load plugins and the mission, build the robot and models, run, report.

Values come from, in order of precedence: the command-line flags, the mission's ``run:`` section,
then the defaults below. Exit code 0 when the mission succeeded, 1 when it failed or hit the
duration limit, 2 on bad input, 128+N when stopped by signal N.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from missiontree.cli import add_plugin_flag, plugins_from_args
from missiontree.engine.context import MissionContext
from missiontree.engine.runner import Runner, RunResult
from missiontree.errors import ConfigError, ProblemsError
from missiontree.paths import find_config

DEFAULT_BACKEND = "sim"
DEFAULT_TICK_HZ = 10.0
DEFAULT_SEED = 0


def register(subparsers: Any) -> None:
    """Add the ``run`` subcommand."""
    parser = subparsers.add_parser(
        "run", help="run a mission on a robot backend",
        description="Run a mission file on the simulator (default) or ROS 2 and write a run directory "
        "with ticks.jsonl, summary.json and pictures.",
    )
    parser.add_argument("tree", type=Path, help="the mission file (YAML)")
    parser.add_argument("--backend", help=f"robot backend (default: the mission's, else {DEFAULT_BACKEND})")
    parser.add_argument("--world", help="simulator world: a shipped name or a path to a world file")
    parser.add_argument("--robot", help="robot profile: a shipped name (turtlebot4) or a path")
    parser.add_argument("--config", help="run configuration: a YAML file, handed to the backend and leaves")
    parser.add_argument("--models", help="models config: a shipped name or a path")
    parser.add_argument("--seed", type=int, help=f"random seed (default {DEFAULT_SEED})")
    parser.add_argument("--out", type=Path, help="run directory (default: runs/<mission name>)")
    parser.add_argument("--max-duration", type=float, metavar="S", help="stop after S seconds (robot clock)")
    parser.add_argument("--tick-hz", type=float, metavar="H", help=f"tick rate (default {DEFAULT_TICK_HZ:g})")
    parser.add_argument("--realtime", action="store_true", default=None,
                        help="pace the ticks to wall time (the simulator then runs no faster than life)")
    parser.add_argument("--allow-outside", action="store_true",
                        help="let subtree includes leave the mission's folder")
    add_plugin_flag(parser)
    parser.set_defaults(func=run)


def _pick(flag: Any, from_file: Any, default: Any) -> Any:
    if flag is not None:
        return flag
    return from_file if from_file is not None else default


def load_run_config(name: str | None) -> dict[str, Any]:
    """Read the ``--config`` file (a path or a shipped name under config/backends/) into a dict."""
    if name is None:
        return {}
    from missiontree.yamlio import load_yaml

    if Path(name).suffix in {".yaml", ".yml"} and not Path(name).is_file():
        raise ConfigError(f"--config file {name!r} does not exist; give a YAML file of run options")
    path = find_config("backends", name)
    document = load_yaml(path, error=ProblemsError)
    if not isinstance(document.data, dict):
        raise ConfigError(f"{path}: a run configuration must be a mapping of options, "
                          f"found {type(document.data).__name__}")
    return dict(document.data)


def robot_options(
    args: argparse.Namespace, defaults: Any, seed: int, config: dict[str, Any],
) -> dict[str, Any]:
    """The backend factory's options: ``world``, ``robot``, ``seed``, ``config`` (only those given)."""
    options: dict[str, Any] = {"seed": seed}
    world = _pick(args.world, defaults.world, None)
    robot = _pick(args.robot, defaults.robot, None)
    if world is not None:
        options["world"] = world
    if robot is not None:
        options["robot"] = robot
    if config:
        options["config"] = config
    return options


def run(args: argparse.Namespace) -> int:
    """Run the mission; print a one-line result and where the run directory is."""
    from missiontree.engine.build import build_tree
    from missiontree.engine.loader import load_mission
    from missiontree.reasoning.hub import build_models

    plugins = plugins_from_args(args)
    spec = load_mission(args.tree, plugins.nodes, allow_outside=args.allow_outside)
    defaults = spec.run
    backend = _pick(args.backend, defaults.backend, DEFAULT_BACKEND)
    seed = int(_pick(args.seed, defaults.seed, DEFAULT_SEED))
    tick_hz = float(_pick(args.tick_hz, defaults.tick_hz, DEFAULT_TICK_HZ))
    max_duration = _pick(args.max_duration, defaults.max_duration, None)
    config_name = _pick(args.config, defaults.config, None)
    config = load_run_config(config_name)
    mission = args.tree.stem
    run_dir = args.out if args.out is not None else Path("runs") / mission

    root = build_tree(spec, plugins.nodes)
    factory = plugins.backend(backend)
    robot = factory(robot_options(args, defaults, seed, config))
    try:
        models_config = _pick(args.models, defaults.models, None)
        models = build_models(models_config, providers=plugins.providers, seed=seed)
        context = MissionContext(robot=robot, models=models, config=config, seed=seed)
        runner = Runner(root, context, tick_hz=tick_hz, max_duration=max_duration, run_dir=run_dir,
                        mission=mission, hook=plugins.hook, spec=spec, blackboard=spec.blackboard,
                        realtime=bool(_pick(args.realtime, defaults.realtime, False)))
        result = runner.run()
    finally:
        robot.close()
    print(describe(result))
    return result.exit_code


def describe(result: RunResult) -> str:
    """One line: how the run ended and where its directory is."""
    why = {"status": "", "limit": " (duration limit reached)", "error": " (stopped by an error)",
           "signal": f" (stopped by {result.summary.get('signal') or 'a signal'})"}[result.stopped_by]
    where = f"; run directory {result.run_dir}" if result.run_dir is not None else ""
    return (f"{result.summary.get('mission', 'mission')}: {result.status.name}{why} after {result.ticks} "
            f"ticks, {result.duration:.1f} s on the robot clock{where}")
