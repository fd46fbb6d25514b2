"""A fleet run: the simulator's N robots, the mission's tree once per robot, one clock (docs/fleet.md).

The session calls :func:`wire_fleet` instead of building one robot when the robot count
(``--robots N``, ``--set robots=N`` for a mission declaring that parameter, or ``run: robots: N``)
is two or more. It builds :func:`~missiontree.backends.sim.fleet.create_fleet`, each robot inside
the run configuration's safety envelope, the tree once per robot (each copy's blackboard keys under
``/<robot>/``, ``/fleet/`` shared), one :class:`~missiontree.engine.context.MissionContext` per robot
(its own robot; the models, markers, outcome and :class:`~missiontree.engine.fleet.FleetView`
shared), and hangs the copies under a :class:`~missiontree.engine.fleet.FleetRoot`. The runner ticks
that root on the :class:`FleetClock`.

Fault injection for tests and the benchmark: ``kills`` (``--kill-robot robot2@120``) kill a robot
at a time on the fleet's clock (:meth:`~missiontree.backends.sim.fleet.FleetRobot.kill`).

Over ROS 2 (``--backend ros2``) the fleet is one ROS 2 robot per member, robot ``robotN`` under the
namespace ``/robotN`` (``missiontree sim-ros --robots N`` serves such a fleet), on one clock: the ROS
time they share (:class:`Ros2FleetClock`). A robot whose NavigateToPose server vanishes sees its goal
aborted as an infrastructure fault, which is how its leaves lose it (docs/ros2.md).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from missiontree.backends.sim.fleet import MAX_ROBOTS, SimFleet, create_fleet, robot_names
from missiontree.engine.build import build_tree
from missiontree.engine.context import MissionContext
from missiontree.engine.fleet import FleetRoot, FleetView, RobotScope, namespace_tree
from missiontree.engine.substitute import Rule, Substitution, announce, apply_rules
from missiontree.errors import ConfigError
from missiontree.robot.envelope import EnvelopedRobot, wrap_robot
from missiontree.types import Marker

__all__ = ["FleetClock", "FleetWiring", "Kill", "Ros2FleetClock", "fleet_state", "parse_kill", "robot_count",
           "substitute_fleet", "wire_fleet"]

@dataclass(frozen=True)
class Kill:
    """Kill robot ``robot`` when the fleet's clock reaches ``at`` seconds (fault injection)."""

    robot: str
    at: float


def parse_kill(text: str) -> Kill:
    """``robot2@120`` → Kill("robot2", 120.0); ConfigError on anything else."""
    robot, sep, at = text.partition("@")
    try:
        when = float(at)
    except ValueError:
        when = math.nan
    if not sep or not robot.strip() or not math.isfinite(when) or when < 0:
        raise ConfigError(f"--kill-robot expects NAME@SECONDS (e.g. robot2@120), found {text!r}")
    return Kill(robot.strip(), when)


def robot_count(flag: int | None, from_set: Any, from_file: int | None) -> int:
    """The run's robot count: ``--robots``, else ``--set robots=N``, else ``run: robots:``, else 1.

    ``robots`` is a run setting, not a mission parameter: ``--set robots=3`` means ``--robots 3``.
    """
    value: Any = flag
    if value is None and from_set is not None:
        value = from_set.strip() if isinstance(from_set, str) else from_set
        if isinstance(value, str) and value.isdigit():
            value = int(value)
    if value is None:
        value = from_file
    if value is None:
        return 1
    if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= MAX_ROBOTS:
        raise ConfigError(f"robots: expected a whole number from 1 to {MAX_ROBOTS}, found {value!r}")
    return value


class _FleetDriven:
    """What every fleet clock answers the runner alike: no single pose, and stop means every robot."""

    name = "fleet"
    robots: list[Any]

    def pose(self) -> None:
        """No single pose: each robot's is in the summary's ``fleet`` section."""
        return None

    def stop(self) -> None:
        """Stop every robot."""
        for robot in self.robots:
            robot.stop()


class FleetClock(_FleetDriven):
    """What the runner drives in a fleet run: the fleet's one clock, stop, close and picture.

    It is no robot for leaves (they each get their own); ``pose()`` is None so the summary's
    ``final_pose`` stays out, and each robot's end is in the summary's ``fleet`` section.
    """

    simulated = True

    def __init__(self, fleet: SimFleet, robots: list[Any], kills: list[Kill]) -> None:
        self.fleet = fleet
        self.robots = robots
        self.truth = fleet.truth
        names = set(fleet.names)
        for kill in kills:
            if kill.robot not in names:
                raise ConfigError(f"--kill-robot {kill.robot}: no such robot; "
                                  f"robots: {', '.join(fleet.names)}")
        self.kills = sorted(kills, key=lambda k: k.at)
        #: Kills done: {"robot", "t"}.
        self.killed: list[dict[str, Any]] = []

    def now(self) -> float:
        """The fleet's simulated time (s)."""
        return self.fleet.now()

    def spin_until(self, t: float) -> None:
        """Advance every robot to ``t``, killing robots whose time has come on the way."""
        while self.kills and self.kills[0].at <= t:
            kill = self.kills.pop(0)
            self.fleet.spin_until(kill.at)
            self.fleet.kill(kill.robot, f"killed at {kill.at:g} s (--kill-robot)")
            self.killed.append({"robot": kill.robot, "t": self.fleet.now()})
        self.fleet.spin_until(t)

    def close(self) -> None:
        """Close every robot."""
        self.fleet.close()

    def draw(self, out_dir: Path, markers: list[Marker]) -> list[Path]:
        """The first robot's top-down picture, which draws the other robots and their paths too."""
        return list(self.fleet.robots[0].draw(out_dir, markers))


class Ros2FleetClock(_FleetDriven):
    """What the runner drives in a fleet run over ROS 2: the ROS time the robots share, stop, close.

    Every robot follows one clock (wall time, or sim-ros's /clock with ``use_sim_time``), read from
    the first robot's node. There is no ground truth and no picture over ROS 2.
    """

    simulated = False
    truth = None

    def __init__(self, robots: list[Any]) -> None:
        self.robots = robots
        #: Kills done (none: over ROS 2 a robot is killed where it runs, e.g. ``sim-ros --kill-robot``).
        self.killed: list[dict[str, Any]] = []

    def now(self) -> float:
        """ROS time (s)."""
        return float(self.robots[0].now())

    def spin_until(self, t: float) -> None:
        """Wait until ROS time reaches ``t`` (each robot's executor keeps spinning meanwhile)."""
        self.robots[0].spin_until(t)

    def close(self) -> None:
        """Close every robot."""
        for robot in self.robots:
            robot.close()


class _LateEvents:
    """An event sink that forwards to whatever ``context.events`` is when an event comes."""

    def __init__(self, context: MissionContext) -> None:
        self.context = context

    def emit(self, event: str, /, **fields: Any) -> None:
        """Forward to the context's current sink."""
        self.context.events.emit(event, **fields)


@dataclass
class FleetWiring:
    """What :func:`wire_fleet` built: the clock, the root, the per-robot scopes and the shared view."""

    clock: FleetClock | Ros2FleetClock
    root: FleetRoot
    view: FleetView
    scopes: list[tuple[Any, MissionContext, str]]
    blackboard: dict[str, Any]


def wire_fleet(session: Any, count: int, backend: str, config: dict[str, Any],
               options: dict[str, Any], kills: list[Kill]) -> FleetWiring:
    """Build the fleet, its trees and contexts for ``session`` (a Session; its ``root`` is the first copy).

    Raises:
        ConfigError: A backend other than the simulator and ROS 2, a bad count or kill, no room in the
            world.
    """
    names, robots, clock = _fleet_robots(session, count, backend, config, options, kills)
    view = FleetView(names, clock.now)
    markers: list[Marker] = []
    outcome: dict[str, Any] = {}
    started: set[Path] = set()  # one run directory's files: no robot truncates what another began
    seed = options.get("seed", 0)
    session.context = MissionContext(robot=clock, models=session.models, config=config,  # type: ignore[arg-type]
                                     seed=seed, markers=markers, outcome=outcome, fleet=view)
    view.events = _LateEvents(session.context)
    scopes: list[tuple[Any, MissionContext, str]] = []
    blackboard = dict(session.spec.blackboard)
    for i, (name, robot) in enumerate(zip(names, robots, strict=True)):
        tree = session.root if i == 0 else build_tree(session.spec, session.plugins.nodes)
        namespace_tree(tree, name)
        context = MissionContext(robot=robot, models=session.models, config=config, seed=seed,
                                 markers=markers, outcome=outcome, fleet=view, started_files=started)
        if isinstance(robot, EnvelopedRobot):
            robot.emit = _LateEvents(context).emit
        scopes.append((RobotScope(name, tree), context, name))
        for key, value in session.spec.blackboard.items():
            blackboard[f"/{name}/{key.lstrip('/')}"] = value
    by_name = dict(zip(names, robots, strict=True))
    root = FleetRoot([scope for scope, _, _ in scopes], view, stop_robot=lambda n: by_name[n].stop())
    return FleetWiring(clock, root, view, [(s, c, n) for s, c, n in scopes], blackboard)


def _fleet_robots(session: Any, count: int, backend: str, config: dict[str, Any], options: dict[str, Any],
                  kills: list[Kill]) -> tuple[list[str], list[Any], FleetClock | Ros2FleetClock]:
    """The fleet's names, its robots (inside the safety envelope) and the clock the runner drives."""
    if backend == "sim":
        fleet = create_fleet(options.get("world") or "office", robots=count, seed=options.get("seed", 0),
                             robot=options.get("robot"), config=options.get("config"),
                             unknown_map=bool(options.get("unknown_map")), sensors=options.get("sensors"))
        robots = [wrap_robot(r, config) for r in fleet.robots]
        return list(fleet.names), robots, FleetClock(fleet, robots, kills)
    if backend != "ros2":
        raise ConfigError(f"robots: {count} runs on the simulator and on ROS 2 (backend {backend!r}); "
                          f"see docs/fleet.md")
    if kills:
        raise ConfigError("--kill-robot kills simulated robots in this process; over ROS 2 kill the robot "
                          "where it runs (missiontree sim-ros --robots N --kill-robot NAME@S)")
    names, robots = robot_names(count), []
    factory = session.plugins.backend(backend)
    try:
        for name in names:
            robots.append(wrap_robot(factory(ros2_member_options(options, name)), config))
    except BaseException:
        for robot in robots:
            robot.close()
        raise
    return names, robots, Ros2FleetClock(robots)


def ros2_member_options(options: dict[str, Any], name: str) -> dict[str, Any]:
    """The ROS 2 backend's options for fleet member ``name``: its namespace ``/<name>``, its name."""
    config = dict(options.get("config") or {})
    config["ros2"] = {**dict(config.get("ros2") or {}), "namespace": f"/{name}", "name": name}
    return {**options, "config": config}


def fleet_state(wiring: FleetWiring) -> dict[str, Any]:
    """The summary's ``fleet`` section: each robot's end, loss, events and truth; the dispatchers."""
    truth = (wiring.clock.truth.report() if wiring.clock.truth is not None
             else {"robots": {}, "min_separation": None})
    ends = wiring.root.robot_report()
    robots: dict[str, Any] = {}
    for _, context, name in wiring.scopes:
        entry = dict(ends.get(name, {}))
        entry["events"] = dict(sorted(getattr(context.events, "counts", {}).items()))
        entry["truth"] = truth["robots"].get(name)
        robots[name] = entry
    dispatchers = {key: obj.report() for key, obj in wiring.view.shared_items() if hasattr(obj, "report")}
    return {"fleet": {"robots": robots, "count": len(robots), "lost": sorted(wiring.view.lost),
                      "killed": list(wiring.clock.killed), "min_separation": truth["min_separation"],
                      "dispatchers": dispatchers}}


def substitute_fleet(session: Any, rules: list[Rule]) -> list[Substitution]:
    """A fleet run's ``--substitute``: every robot's copy stubbed alike, before the first tick.

    The tick log gets ``substituted`` events as the mission starts and the summary a
    ``substitutions`` list, naming the nodes by their paths in one robot's copy.

    Raises:
        MissionFileError: A rule matches no node.
    """
    wiring: FleetWiring = session.fleet
    substitutions: list[Substitution] = []
    for scope, _, name in wiring.scopes:
        tree, done = apply_rules(session.spec, scope.decorated, rules)
        if tree is not scope.decorated:
            scope.decorated = tree
            scope.children = [tree]
            tree.parent = scope
        namespace_tree(tree, name)  # the stubs' keys under the robot's namespace too
        substitutions = substitutions or done
    announce(session.runner, substitutions)
    return substitutions
