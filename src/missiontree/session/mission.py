"""One mission run, wired in one place: load → check → robot → models → context → runner.

The CLI, every benchmark and the batch runner call this; nothing else wires a backend to model
providers::

    request = MissionRequest(mission=Path("trees/patrol.yaml"), params={"laps": "3"})
    with Session.open(request) as session:
        session.robot            # the backend's robot (the simulator's .truth is for scoring only)
        result = session.run()   # engine.runner.RunResult
    result = run_mission(request)

Every value comes from the request (the command-line flags) first, then the mission's ``run:``
section, then the defaults below (:data:`DEFAULT_BACKEND`, :data:`DEFAULT_TICK_HZ`,
:data:`DEFAULT_SEED`; the run directory ``runs/<mission file stem>``).

The run directory is claimed before the robot starts (:mod:`missiontree.session.rundir`): checked,
locked for this run (``run.lock``; exit 2 when another live run holds it) and cleared of an earlier
run's files; the lock goes when the session closes.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType
from typing import Any, TextIO

from missiontree.engine.build import build_tree
from missiontree.engine.context import MissionContext
from missiontree.engine.loader import load_mission
from missiontree.engine.runner import Runner, RunResult
from missiontree.engine.spec import MissionSpec
from missiontree.engine.substitute import load_rules, substitute_session
from missiontree.errors import ConfigError, MissionFileError, ProblemsError
from missiontree.paths import find_config
from missiontree.plugins.manager import Plugins, load_plugins
from missiontree.reasoning.models import Models
from missiontree.robot.envelope import EnvelopedRobot, wrap_robot
from missiontree.session.fleet import (
    FleetWiring,
    Kill,
    fleet_state,
    parse_kill,
    robot_count,
    substitute_fleet,
    wire_fleet,
)
from missiontree.session.models import build_models
from missiontree.session.preflight import check_references, resolve_mission_path
from missiontree.session.process import run_span
from missiontree.session.progress import ProgressLine
from missiontree.session.rundir import RunDirectory

__all__ = ["DEFAULT_BACKEND", "DEFAULT_SEED", "DEFAULT_TICK_HZ", "MissionRequest", "Session",
           "load_run_config", "run_mission"]

DEFAULT_BACKEND = "sim"
DEFAULT_TICK_HZ = 10.0
DEFAULT_SEED = 0


@dataclass
class MissionRequest:
    """What to run and how; ``None`` means: the mission's ``run:`` section, else the default.

    Attributes:
        mission: The mission file.
        backend: Robot backend name (``sim``, ``ros2`` or a plugin's).
        world: Simulator world: a shipped name or a path.
        robot: Robot profile: a shipped name or a path.
        models: Models config: a shipped name, a path, or the config itself as a mapping.
        config: Run configuration: a YAML file (a path or a config/backends name) or a mapping.
        seed: Random seed.
        out: Run directory (default ``runs/<mission file stem>``).
        max_duration: Stop after this many robot-clock seconds.
        tick_hz: Tick rate.
        realtime: Pace the ticks to wall time.
        params: Values for the mission's ``params:`` (text is read as YAML, as ``--set`` gives it).
        unknown_map: Start without the map (the backend learns it); the ``run:`` section's ``map:``.
        quiet: No progress line.
        allow_outside: Let subtree includes leave the mission's folder.
        plugins: Already loaded plugins (default: load them, autoloading as the environment says).
        handle_signals: Stop cleanly on SIGINT/SIGTERM (main thread only).
        on_tick: Called with the session after every tick (scoring that reads the robot between
            ticks); it must return at once.
        progress_stream: Where the progress line goes (default stderr).
        log_stream: Write the tick log here instead of ``<out>/ticks.jsonl``.
        substitute: A substitution rules file (``--substitute``): nodes it matches run as stubs,
            recorded in the tick log and the summary (:mod:`missiontree.engine.substitute`).
        robots: Robots in one world (``--robots``); two or more run the tree once per robot on one
            clock (:mod:`missiontree.session.fleet`).
        kill_robots: Fault injection in a fleet run: ``NAME@SECONDS`` kills that robot then.
    """

    mission: Path
    backend: str | None = None
    world: str | None = None
    robot: str | None = None
    models: str | os.PathLike[str] | Mapping[str, Any] | None = None
    config: str | Mapping[str, Any] | None = None
    seed: int | None = None
    out: Path | None = None
    max_duration: float | None = None
    tick_hz: float | None = None
    realtime: bool | None = None
    params: Mapping[str, Any] | None = None
    unknown_map: bool | None = None
    quiet: bool = True
    allow_outside: bool = False
    plugins: Plugins | None = None
    handle_signals: bool = True
    on_tick: Callable[[Session], None] | None = None
    progress_stream: TextIO | None = None
    log_stream: TextIO | None = None
    substitute: str | os.PathLike[str] | None = None
    robots: int | None = None
    kill_robots: Sequence[str] = ()


def _pick(flag: Any, from_file: Any, default: Any) -> Any:
    if flag is not None:
        return flag
    return from_file if from_file is not None else default


def load_run_config(name: str | Mapping[str, Any] | None) -> dict[str, Any]:
    """Read a run configuration (``--config``: a path or a shipped name under config/backends/)."""
    if name is None:
        return {}
    if isinstance(name, Mapping):
        return dict(name)
    from missiontree.yamlio import load_yaml

    if Path(name).suffix in {".yaml", ".yml"} and not Path(name).is_file():
        raise ConfigError(f"--config file {name!r} does not exist; give a YAML file of run options")
    path = find_config("backends", name)
    document = load_yaml(path, error=ProblemsError)
    if not isinstance(document.data, dict):
        raise ConfigError(f"{path}: a run configuration must be a mapping of options, "
                          f"found {type(document.data).__name__}")
    return dict(document.data)


class Session:
    """A loaded, checked and wired mission, ready to run once. Open with :meth:`open`.

    Attributes:
        request: What was asked.
        plugins: The loaded plugins.
        spec: The checked mission.
        root: The built tree's root.
        robot: The backend's robot.
        models: Providers by role, the call settings and the mission's bound caller.
        context: What the leaves get.
        runner: The runner that will tick the tree.
        run_dir: Where the log, summary and pictures go (None when writing nothing).
        options: The backend factory's options.
        settings: The resolved run settings (backend, seed, tick_hz, ...), for reports.
    """

    def __init__(self, request: MissionRequest) -> None:
        self.request = request
        self.plugins: Plugins = request.plugins if request.plugins is not None else load_plugins()
        self.robot: Any = None
        self.models = Models()
        self.result: RunResult | None = None
        self.progress: ProgressLine | None = None
        self.run_claim: RunDirectory | None = None
        self.fleet: FleetWiring | None = None
        self._closed = False

    @classmethod
    def open(cls, request: MissionRequest) -> Session:
        """Load and check the mission, then build the tree, the robot, the models and the runner.

        Raises:
            ProblemsError: The mission, a config or a models file is broken (every problem located).
            ConfigError: A bad value (``params`` included) or an unknown backend.
        """
        session = cls(request)
        try:
            session._wire()
        except BaseException:
            session.close()
            raise
        return session

    # -- wiring ----------------------------------------------------------------------------------

    def _wire(self) -> None:
        request = self.request
        mission = Path(request.mission)
        overrides = dict(request.params or {})  # read and checked against the params' types while loading
        robots_set = overrides.pop("robots", None)  # --set robots=N is the run setting, as --robots N
        self.spec: MissionSpec = load_mission(
            mission, self.plugins.nodes, allow_outside=request.allow_outside, params=overrides)
        # what the mission references (world, robot, waypoint files, the models config and its model
        # files), checked before the robot is built: a bad one is exit 2 with no robot started
        problems = check_references(self.spec, providers=self.plugins.providers, backend=request.backend,
                                    world=request.world, robot=request.robot, models=request.models)
        if problems:
            raise MissionFileError(problems)
        # the rules file is read before the robot starts; its rules are matched once the tree is built
        rules = load_rules(request.substitute) if request.substitute else None
        run = self.spec.run
        seed = _pick(request.seed, run.seed, DEFAULT_SEED)
        if isinstance(seed, bool) or not isinstance(seed, int):
            raise ConfigError(f"seed: expected a whole number, found {seed!r}")
        backend = str(_pick(request.backend, run.backend, DEFAULT_BACKEND))
        tick_hz = float(_pick(request.tick_hz, run.tick_hz, DEFAULT_TICK_HZ))
        max_duration = _pick(request.max_duration, run.max_duration, None)
        realtime = bool(_pick(request.realtime, run.realtime, False))
        map_from_file = None if run.map is None else run.map == "unknown"
        unknown_map = bool(_pick(request.unknown_map, map_from_file, False))
        config = load_run_config(_pick(request.config, run.config, None))
        models_config = _pick(request.models, None if run.models is None  # beside the mission, as checked
                              else resolve_mission_path(mission, run.models), None)
        self.settings: dict[str, Any] = {
            "backend": backend, "seed": seed, "tick_hz": tick_hz, "max_duration": max_duration,
            "realtime": realtime, "unknown_map": unknown_map, "models": models_config, "params": overrides,
        }
        robots, kills = self._fleet_size(robots_set)
        self._claim_run_dir(mission)

        self.root = build_tree(self.spec, self.plugins.nodes)
        backend_config = {k: v for k, v in config.items() if k != "safety"}  # the envelope is ours
        self.options = self._robot_options(seed, backend_config, unknown_map)
        if robots > 1:
            self._wire_fleet(robots, backend, config, models_config, kills)
            if rules is not None:
                substitute_fleet(self, rules)
            return
        factory = self.plugins.backend(backend)
        self.robot = wrap_robot(factory(self.options), config)  # goals and speeds pass the safety envelope
        self.models = Models(build_models(models_config, providers=self.plugins.providers, seed=seed))
        self.context = MissionContext(robot=self.robot, models=self.models, config=config, seed=seed)
        if isinstance(self.robot, EnvelopedRobot):
            self.robot.emit = self._safety_event
        self._make_runner()
        if rules is not None:  # stubs in place before the first tick; a rule matching nothing is exit 2
            substitute_session(self, rules)

    def _claim_run_dir(self, mission: Path) -> None:
        """The run directory (``--out``, else ``runs/<mission>``), checked, locked and cleared now."""
        request = self.request
        self.mission_name = mission.stem
        self.run_dir: Path | None = None
        if request.log_stream is None:
            self.run_dir = Path(request.out) if request.out is not None else Path("runs") / self.mission_name
        elif request.out is not None:
            self.run_dir = Path(request.out)
        if self.run_dir is not None:  # checked, locked and cleared before the robot starts
            self.run_claim = RunDirectory.claim(self.run_dir)

    def _fleet_size(self, robots_set: Any) -> tuple[int, list[Kill]]:
        """The robot count (``--robots``, ``--set robots=``, ``run: robots:``) and the kills asked for."""
        robots = robot_count(self.request.robots, robots_set, self.spec.run.robots)
        kills = [parse_kill(k) for k in self.request.kill_robots]
        if kills and robots < 2:
            raise ConfigError("--kill-robot needs a fleet (--robots 2 or more)")
        if robots > 1:
            self.settings["robots"] = robots
        return robots, kills

    def _wire_fleet(self, robots: int, backend: str, config: dict[str, Any], models_config: Any,
                    kills: list[Kill]) -> None:
        """N robots, the tree once per robot under one root, one clock (:mod:`missiontree.session.fleet`)."""
        self.models = Models(build_models(models_config, providers=self.plugins.providers,
                                          seed=self.settings["seed"]))
        self.fleet = wire_fleet(self, robots, backend, config, self.options, kills)
        self.robot = self.fleet.clock
        self.root = self.fleet.root
        self._make_runner()
        for _, context, _ in self.fleet.scopes:  # the caller the models bound, shared by every robot
            context.calls = self.context.calls

    def _make_runner(self) -> None:
        """The runner over the built tree and context; then the model services bound, whole.

        The caller and the providers that need the robot are bound before any leaf is set up: leaves
        only use them (``context.calls``).
        """
        request, settings = self.request, self.settings
        if not request.quiet:
            self.progress = ProgressLine(self.mission_name, request.progress_stream)
        self.runner = Runner(
            self.root, self.context, tick_hz=settings["tick_hz"], max_duration=settings["max_duration"],
            run_dir=self.run_dir, mission=self.mission_name, hook=self.plugins.hook, spec=self.spec,
            blackboard=self.spec.blackboard if self.fleet is None else self.fleet.blackboard,
            realtime=settings["realtime"],
            handle_signals=request.handle_signals, log_stream=request.log_stream,
            on_tick=self._on_tick if (self.progress is not None or request.on_tick is not None) else None,
            final_state=self._final_state, **self._fleet_runner_options())
        self.models.bind(self.context, realtime=settings["realtime"])

    def _fleet_runner_options(self) -> dict[str, Any]:
        """The runner's per-robot scopes in a fleet run ({} for one robot)."""
        return {} if self.fleet is None else {"scopes": self.fleet.scopes}

    def _robot_options(self, seed: int, config: dict[str, Any], unknown_map: bool) -> dict[str, Any]:
        """The backend factory's options: ``seed``, and ``world``, ``robot``, ``config`` when given.

        ``unknown_map`` is passed only when true, so a backend without it runs known maps as before.
        """
        run = self.spec.run
        options: dict[str, Any] = {"seed": seed}
        world = _pick(self.request.world, run.world, None)
        robot = _pick(self.request.robot, run.robot, None)
        if world is not None:
            options["world"] = self._resolve_world(world, from_file=self.request.world is None)
        if robot is not None:
            options["robot"] = robot
        if config:
            options["config"] = config
        if unknown_map:
            options["unknown_map"] = True
        if self.plugins.sensors:  # plugin sensors (missiontree.robot.sensors), only when there are some
            options["sensors"] = list(self.plugins.sensors.values())
        return options

    def _resolve_world(self, world: str, from_file: bool) -> str:
        """A world path written in the mission resolves relative to the mission file (as includes do)."""
        if not from_file or not world.endswith((".yaml", ".yml")) or Path(world).is_absolute():
            return world
        beside = Path(self.request.mission).resolve().parent / world
        return str(beside) if beside.is_file() else world

    def _safety_event(self, event: str, /, **fields: Any) -> None:
        """A refusal or cap of the safety envelope, in the tick log (the sink the runner installed)."""
        self.context.events.emit(event, **fields)

    def _on_tick(self, runner: Runner) -> None:
        if self.progress is not None:
            self.progress.update(runner)
        if self.request.on_tick is not None:
            self.request.on_tick(self)

    def _final_state(self) -> dict[str, Any]:
        """The simulator's true final pose and contacts, for the summary (scoring only, unseen by leaves)."""
        if self.fleet is not None:
            return fleet_state(self.fleet)
        truth = getattr(self.robot, "truth", None)
        true_pose = getattr(truth, "robot_pose", None)
        if not callable(true_pose):
            return {}
        pose = true_pose()
        state: dict[str, Any] = {"true_final_pose": {"x": pose.x, "y": pose.y, "yaw": pose.yaw}}
        bump_report = getattr(self.robot, "bump_report", None)
        if callable(bump_report):  # the simulator's contacts: where the body touched something
            state["bumps"] = bump_report()
        return state

    # -- running ---------------------------------------------------------------------------------

    def run(self) -> RunResult:
        """Run the mission to its end (status, limit or signal); the robot is stopped afterwards.

        Raises:
            ConfigError: A node failed to set up, or the session already ran.
        """
        if self.result is not None:
            raise ConfigError("a session runs its mission once; open a new session to run it again")
        try:
            with run_span():  # the heap the session opened, frozen when the application tuned the process
                self.result = self.runner.run()
        finally:
            if self.progress is not None:
                self.progress.close()
        return self.result

    def close(self) -> None:
        """Stop model calls and close the robot (idempotent)."""
        if self._closed:
            return
        self._closed = True
        self.models.close()
        try:
            if self.robot is not None:
                self.robot.close()
        finally:
            if self.run_claim is not None:
                self.run_claim.release()

    def __enter__(self) -> Session:
        return self

    def __exit__(self, kind: type[BaseException] | None, error: BaseException | None,
                 trace: TracebackType | None) -> None:
        self.close()


def run_mission(request: MissionRequest) -> RunResult:
    """Open a session, run it and close it: ``Session.open(request).run()`` with cleanup."""
    with Session.open(request) as session:
        return session.run()
