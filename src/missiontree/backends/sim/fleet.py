"""Several simulated robots in one world, stepped together: each sees the others and avoids them.

A :class:`SimFleet` holds N :class:`FleetRobot` s in one :class:`World`. Each is a full
:class:`~missiontree.backends.sim.robot.SimRobot` (its own start pose, lidar, camera, odometry,
navigator, random streams and ground truth) and passes the robot conformance suite on its own.
What the fleet adds:

- **One clock.** ``spin_until(t)`` on any robot advances the whole fleet: every physics step first
  moves every robot (in index order, each checked against the others' bodies where they are at
  that moment, so two bodies never overlap), then lets every robot sense. The world every sensor
  sees is therefore the same instant for all robots.
- **Robots are obstacles to each other's sensors.** Each robot's body is an upright cylinder of its
  profile's footprint radius and height and body colour, with its own instance id (kind
  ``robot``); the lidar (its plane at 0.19 m crosses a 0.35 m body) and the camera of every *other*
  robot see it, as they see people. A robot never sees itself.
- **Collisions are refused, as with walls and people.** A move that would bring two bodies closer
  than the sum of their radii is refused and counted as a bump (``bump_report()``), exactly as the
  single robot reports touching a wall or a person.
- **Avoidance comes from the sensors only.** Navigation plans on the static map and its controller
  avoids what its own lidar shows (:class:`~missiontree.backends.sim.nav_scan.ScanView`); no robot
  reads another's true pose.

Determinism: robot ``i`` draws its noise from ``robot_seed(seed, i)`` (robot 0 uses ``seed``
itself, so a fleet of one is the single robot, scan for scan), and stepping order is fixed.

Ground truth, for scoring only: each robot's ``truth`` (as for a single robot; its visibility log
names other robots it saw), and :class:`FleetTruth` (``SimFleet.truth``) over all of them: true
poses, the closest two bodies came, and per-robot reports.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterator, Sequence
from typing import Any

import cv2
import numpy as np

from missiontree.backends.sim.nav_handle import SimNavHandle
from missiontree.backends.sim.raycast import CYLINDER, Primitives
from missiontree.backends.sim.render import Scene, SceneRobot
from missiontree.backends.sim.robot import SimRobot
from missiontree.backends.sim.robot_profiles import load_robot_profile
from missiontree.backends.sim.schema import RobotProfile
from missiontree.backends.sim.truth import GroundTruth
from missiontree.backends.sim.world import InstanceInfo, World, load_world
from missiontree.errors import ConfigError
from missiontree.mapping.occupancy import BLOCKED_FROM
from missiontree.robot.actions import INFRASTRUCTURE, ActionResult, ActionStatus, NavFeedback
from missiontree.robot.sensors import SensorKind
from missiontree.types import Pose2D, Tolerance

_TIME_EPS = 1e-9
#: Most robots one simulated world holds (each costs a lidar cast and a camera frame per period).
MAX_ROBOTS = 16
#: Free space kept between two automatically placed robots' bodies (m).
START_GAP = 0.5
#: Clearance from walls and obstacles beyond the body radius an automatic start keeps (m).
START_WALL_MARGIN = 0.15
#: The kind of a robot's instance id in camera masks and the ground truth's visibility log.
ROBOT_KIND = "robot"


def robot_seed(seed: int, index: int) -> int:
    """The seed of robot ``index`` in a fleet run with ``seed``: robot 0 keeps ``seed`` itself."""
    if index == 0:
        return seed
    return int(np.random.SeedSequence([seed, index]).generate_state(1)[0])


def robot_names(count: int) -> list[str]:
    """``robot1`` ... ``robotN``: the names ROS 2 namespaces would carry (``/robot1/scan``)."""
    return [f"robot{i + 1}" for i in range(count)]


def fleet_starts(world: World, count: int, radius: float) -> list[Pose2D]:
    """Start poses for ``count`` robots: the world's start first, then the nearest free places.

    A place qualifies when its clearance from static obstacles is at least ``radius`` +
    :data:`START_WALL_MARGIN`, it is connected to the world's start through such places (no start
    in a sealed pocket), and it keeps :data:`START_GAP` of free space to every robot placed before.
    Candidates are taken by distance from the world's start (ties by row, column), so the result
    depends on the world only. Every robot faces the world start's heading.

    Raises:
        ConfigError: The world has no room for ``count`` robots.
    """
    starts = [world.start]
    if count == 1:
        return starts
    grid = world.grid
    # the world's clearance (distance to the nearest static obstacle cell) as World computes it
    open_cells = (grid.data < BLOCKED_FROM).astype(np.uint8)
    clearance = cv2.distanceTransform(open_cells, cv2.DIST_L2, 5) * grid.resolution
    free = clearance >= radius + START_WALL_MARGIN
    _, labels = cv2.connectedComponents(free.astype(np.uint8), connectivity=8)
    row0, col0 = grid.world_to_cell(world.start.x, world.start.y)
    h, w = free.shape
    if not (0 <= row0 < h and 0 <= col0 < w) or labels[row0, col0] == 0:
        reachable = free  # the start itself hugs a wall: any free place will do
    else:
        reachable = labels == labels[row0, col0]
    rows, cols = np.nonzero(reachable)
    res = grid.resolution
    xs = grid.origin.x + (cols + 0.5) * res
    ys = grid.origin.y + (rows + 0.5) * res
    order = np.lexsort((cols, rows, np.hypot(xs - world.start.x, ys - world.start.y)))
    spacing = 2.0 * radius + START_GAP
    placed = np.array([[world.start.x, world.start.y]])
    for i in order:
        x, y = float(xs[i]), float(ys[i])
        if np.min(np.hypot(placed[:, 0] - x, placed[:, 1] - y)) < spacing:
            continue
        starts.append(Pose2D(x, y, world.start.yaw))
        placed = np.vstack([placed, [x, y]])
        if len(starts) == count:
            return starts
    raise ConfigError(f"world {world.name!r} has room for {len(starts)} robot(s) "
                      f"({spacing:.2f} m apart, connected to its start), not {count}; "
                      f"give fewer robots or their start poses")


class FleetRobot(SimRobot):
    """One robot of a :class:`SimFleet`: a SimRobot whose clock, sensors and bumps know the others.

    Attributes:
        fleet: The fleet it belongs to.
        index: Its place in the fleet (0 for the first).
        inst: Its body's instance id in the other robots' camera masks.
    """

    def __init__(self, fleet: SimFleet, index: int, world: World, profile: RobotProfile, seed: int,
                 name: str, unknown_map: bool, sensors: list[SensorKind] | None) -> None:
        self.fleet = fleet
        self.index = index
        self.inst = fleet.instance_ids[index]
        #: Physics steps whose move was refused because it pushed into another robot's body.
        self.robot_refusals = 0
        #: Why the robot was killed (:meth:`kill`), "" while it lives.
        self.killed = ""
        self.last_goal: LosableHandle | None = None
        super().__init__(world, profile, seed=seed, name=name, unknown_map=unknown_map, sensors=sensors)

    def spin_until(self, t: float) -> None:
        """Advance the whole fleet until the clock reaches ``t`` (the robots share one world)."""
        self.fleet.spin_until(t)

    def now(self) -> float:
        """Simulated time: the robot's own while it lives, the fleet's after it was killed.

        A dead robot's clock goes on with the world's (its leaves' timeouts still run out and its
        pose grows stale), though the robot itself no longer steps.
        """
        return self.fleet.now() if self.killed else super().now()

    def kill(self, reason: str = "killed") -> None:
        """Fault injection: the robot dies where it stands (an obstacle still), its machinery gone.

        Its goals (the running one and any later) end ABORTED with an
        :data:`~missiontree.robot.actions.INFRASTRUCTURE` result, and its pose is no longer
        updated: what a robot whose navigation server vanished looks like to its leaves.
        """
        if self.killed:
            return
        self.killed = reason
        if self.last_goal is not None:
            self.last_goal.lose(reason)
        self.close()

    def navigate_to(self, goal: Pose2D, tolerance: Tolerance | None = None) -> LosableHandle:  # type: ignore[override]
        """As the single robot, the handle reporting the loss once the robot is killed."""
        if self.killed:
            handle = LosableHandle(None)
            handle.lose(self.killed)
            return handle
        self.last_goal = LosableHandle(super().navigate_to(goal, tolerance))
        return self.last_goal

    def dynamic_primitives(self, t: float) -> Primitives:
        """People at ``t`` and every other robot's body where it is now."""
        return self.world.crowd.primitives(t).concat(self.fleet.bodies(exclude=self.index))

    def bump_report(self) -> dict[str, Any]:
        """The single robot's contacts, plus the refused moves that pushed into another robot."""
        report = super().bump_report()
        report["refused_by_robots"] = self.robot_refusals
        report["meaning"] += ("; in a fleet another robot's body counts as well (refused_by_robots: "
                              "the physics steps refused for one)")
        return report

    def scene(self) -> Scene:
        """The single robot's picture, with the other robots' bodies and paths drawn beside its own."""
        others = [SceneRobot(r.name, r.true_pose, r.profile.body.radius, list(r.trajectory))
                  for r in self.fleet.robots if r is not self]
        return dataclasses.replace(super().scene(), others=others)

    def _collides(self, pose: Pose2D) -> bool:
        if super()._collides(pose):
            return True
        if self.fleet.blocked(self.index, self.true_pose, pose):
            self.robot_refusals += 1
            return True
        return False


class LosableHandle:
    """A fleet robot's goal: the simulator's handle until the robot is killed, then a lost server's.

    A goal still running when its robot is killed (or sent after) reads ABORTED with an
    :data:`~missiontree.robot.actions.INFRASTRUCTURE` result; a goal that ended before keeps its end.
    """

    def __init__(self, inner: SimNavHandle | None) -> None:
        self.inner = inner
        self._lost: ActionResult | None = None

    def lose(self, reason: str) -> None:
        """The robot died: a goal not yet ended now reads ABORTED (INFRASTRUCTURE)."""
        if self._lost is None and (self.inner is None or not self.inner.status().done):
            self._lost = ActionResult(ActionStatus.ABORTED, f"robot lost: {reason}", 0, kind=INFRASTRUCTURE)

    def _check(self) -> ActionResult | None:
        return self._lost

    def status(self) -> ActionStatus:
        """The simulator's status, or ABORTED once the robot is lost mid-goal."""
        lost = self._check()
        if lost is not None or self.inner is None:
            return ActionStatus.ABORTED
        return self.inner.status()

    def feedback(self) -> NavFeedback | None:
        """The simulator's feedback (None for a goal the lost robot never took)."""
        return None if self.inner is None else self.inner.feedback()

    def result(self) -> ActionResult | None:
        """The simulator's result, or the lost server's."""
        lost = self._check()
        if lost is not None or self.inner is None:
            return lost
        return self.inner.result()

    def cancel(self) -> None:
        """Cancel the simulator's goal (nothing to cancel once lost)."""
        if self.inner is not None:
            self.inner.cancel()


@dataclasses.dataclass
class Separation:
    """The closest two robots' bodies came during a run (centre distance minus both radii)."""

    gap: float = math.inf
    t: float = 0.0
    pair: tuple[str, str] = ("", "")


class SimFleet:
    """N simulated robots in one world, stepped together (see the module docstring).

    Args:
        world: The world (the fleet uses a copy whose instance table names the robots).
        profile: The robot profile every robot uses.
        count: How many robots (1 to :data:`MAX_ROBOTS`).
        seed: The run seed; robot ``i`` uses :func:`robot_seed` ``(seed, i)``.
        starts: One start pose per robot (default: :func:`fleet_starts`).
        names: One name per robot (default: :func:`robot_names`).
        unknown_map: Every robot learns its own map from its own lidar.
        sensors: Plugin sensor kinds each robot carries.

    Raises:
        ConfigError: A count out of range, starts or names that do not match the count, a start
            inside an obstacle or two starts whose bodies overlap.
    """

    def __init__(self, world: World, profile: RobotProfile, count: int, seed: int = 0,
                 starts: Sequence[Pose2D] | None = None, names: Sequence[str] | None = None,
                 unknown_map: bool = False, sensors: list[SensorKind] | None = None) -> None:
        if isinstance(count, bool) or not isinstance(count, int) or not 1 <= count <= MAX_ROBOTS:
            raise ConfigError(f"fleet robots: expected a whole number from 1 to {MAX_ROBOTS}, "
                              f"found {count!r}")
        self.radius = profile.body.radius
        self.height = profile.body.height
        self.rgb = tuple(int(c) for c in profile.body.rgb)
        self.starts = list(starts) if starts is not None else fleet_starts(world, count, self.radius)
        self.names = list(names) if names is not None else robot_names(count)
        self._check(world, count)
        first = max(world.instances, default=0) + 1
        self.instance_ids = [first + i for i in range(count)]
        instances = dict(world.instances)
        instances.update({inst: InstanceInfo(inst, ROBOT_KIND, name, ROBOT_KIND)
                          for inst, name in zip(self.instance_ids, self.names, strict=True)})
        self.world = dataclasses.replace(world, instances=instances)
        self.dt = profile.physics_dt
        self._steps = 0
        self.separation = Separation()
        self.robots: list[FleetRobot] = []
        for i in range(count):  # robots not built yet stand at their starts (bodies() and blocked())
            own_world = dataclasses.replace(self.world, start=self.starts[i])
            self.robots.append(FleetRobot(self, i, own_world, profile, robot_seed(seed, i), self.names[i],
                                          unknown_map, sensors))
        self._note_separation()
        self.truth = FleetTruth(self)

    def _check(self, world: World, count: int) -> None:
        """Starts and names match the count; every start is free and no two bodies overlap."""
        if len(self.starts) != count or len(self.names) != count:
            raise ConfigError(f"fleet of {count} robots: found {len(self.starts)} start pose(s) "
                              f"and {len(self.names)} name(s); give one of each per robot")
        if len(set(self.names)) != count:
            raise ConfigError(f"fleet robot names must differ, found {self.names}")
        for name, p in zip(self.names, self.starts, strict=True):
            if world.clearance(p.x, p.y) < self.radius:
                raise ConfigError(f"fleet robot {name}: start ({p.x:.2f}, {p.y:.2f}) is inside an obstacle "
                                  f"or nearer than {self.radius} m to one in world {world.name!r}")
        for i in range(count):
            for j in range(i + 1, count):
                a, b = self.starts[i], self.starts[j]
                if math.hypot(a.x - b.x, a.y - b.y) < 2 * self.radius:
                    raise ConfigError(f"fleet robots {self.names[i]} and {self.names[j]} start with their "
                                      f"bodies overlapping ({a.x:.2f}, {a.y:.2f}) / ({b.x:.2f}, {b.y:.2f})")

    def __len__(self) -> int:
        return len(self.robots)

    def __iter__(self) -> Iterator[FleetRobot]:
        return iter(self.robots)

    def __getitem__(self, key: int | str) -> FleetRobot:
        """A robot by index or by name."""
        if isinstance(key, str):
            for robot in self.robots:
                if robot.name == key:
                    return robot
            raise KeyError(f"no robot {key!r} in the fleet; robots: {', '.join(self.names)}")
        return self.robots[key]

    # -- the shared clock --------------------------------------------------------------------------

    def now(self) -> float:
        """The fleet's simulated time (s)."""
        return self._steps * self.dt

    def spin_until(self, t: float) -> None:
        """Step every open robot until the clock reaches ``t``: all move, then all sense, per step.

        A closed robot stays where it stopped, an obstacle the others still see.
        """
        while self.now() < t - _TIME_EPS:
            live = [r for r in self.robots if not r.closed]
            if not live:
                return
            for robot in live:
                robot.step_motion()
            self._steps += 1
            self._note_separation()
            for robot in live:
                robot.step_sensing()

    def kill(self, name: str, reason: str = "killed") -> None:
        """Kill robot ``name`` (fault injection, :meth:`FleetRobot.kill`); the others go on."""
        self[name].kill(reason)

    def close(self) -> None:
        """Close every robot."""
        for robot in self.robots:
            robot.close()

    # -- what the robots are to each other ---------------------------------------------------------

    def true_poses(self) -> list[Pose2D]:
        """Every robot's true pose now (a robot still being built stands at its start)."""
        return [r.true_pose for r in self.robots] + self.starts[len(self.robots):]

    def bodies(self, exclude: int | None = None) -> Primitives:
        """The robots' bodies as upright cylinders where they are now, but robot ``exclude``."""
        rows = [(CYLINDER, (p.x, p.y, self.radius), 0.0, self.height, self.rgb, inst)
                for i, (p, inst) in enumerate(zip(self.true_poses(), self.instance_ids, strict=True))
                if i != exclude]
        return Primitives.build(rows)  # type: ignore[arg-type]  # rows of the Row shape

    def blocked(self, index: int, here: Pose2D, proposed: Pose2D) -> bool:
        """Whether robot ``index`` moving from ``here`` to ``proposed`` would push into another body.

        The rule the single robot applies to people: refused when the bodies would overlap and
        the move brings them closer (moving apart out of contact is always allowed).
        """
        reach = 2.0 * self.radius
        for j, other in enumerate(self.true_poses()):
            if j == index:
                continue
            d_next = math.hypot(proposed.x - other.x, proposed.y - other.y)
            if d_next < reach and d_next < math.hypot(here.x - other.x, here.y - other.y):
                return True
        return False

    def _note_separation(self) -> None:
        poses = self.true_poses()
        for i in range(len(poses)):
            for j in range(i + 1, len(poses)):
                gap = math.hypot(poses[i].x - poses[j].x, poses[i].y - poses[j].y) - 2.0 * self.radius
                if gap < self.separation.gap:
                    self.separation = Separation(gap, self.now(), (self.names[i], self.names[j]))


class FleetTruth:
    """Ground truth over a whole fleet, for scoring only (never for behaviours).

    Attributes:
        robots: Each robot's own :class:`GroundTruth`, by name.
    """

    def __init__(self, fleet: SimFleet) -> None:
        self._fleet = fleet
        self.robots: dict[str, GroundTruth] = {r.name: r.truth for r in fleet.robots}

    def poses(self) -> dict[str, Pose2D]:
        """Every robot's true pose now, by name."""
        return {r.name: r.true_pose for r in self._fleet.robots}

    @property
    def min_separation(self) -> Separation:
        """The closest two robots' bodies came so far (negative would mean they overlapped)."""
        return self._fleet.separation

    def report(self) -> dict[str, Any]:
        """Per-robot figures for a summary: true pose, distance driven, odometry error, bumps.

        ``min_separation`` is None for a fleet of one (no pair of robots to measure).
        """
        robots = {}
        for r in self._fleet.robots:
            true, est = r.true_pose, r.pose()
            error = math.hypot(true.x - est.pose.x, true.y - est.pose.y) if est is not None else None
            robots[r.name] = {"x": round(true.x, 3), "y": round(true.y, 3), "yaw": round(true.yaw, 3),
                              "driven_m": round(r.odometer, 3),
                              "odometry_error_m": None if error is None else round(error, 3),
                              "bumps": r.bump_report()}
        sep = self._fleet.separation
        closest = None if math.isinf(sep.gap) else {"gap_m": round(sep.gap, 3), "t": sep.t,
                                                    "pair": list(sep.pair)}
        return {"t": self._fleet.now(), "robots": robots, "min_separation": closest}


def create_fleet(world: str | World = "office", robots: int = 2, seed: int = 0, robot: str | None = None,
                 config: dict[str, Any] | None = None, starts: Sequence[Pose2D] | None = None,
                 names: Sequence[str] | None = None, unknown_map: bool = False,
                 sensors: list[SensorKind] | None = None) -> SimFleet:
    """Build a fleet of ``robots`` simulated robots in one world.

    Args:
        world: A shipped world name, a path or a loaded :class:`World`.
        robots: How many robots (1 to :data:`MAX_ROBOTS`).
        seed: The run seed (robot 0 uses it as a single robot would).
        robot: The robot profile (default: the world's).
        config: Overrides merged over the profile, as ``create_robot``'s ``config``.
        starts: One start pose per robot (default: the world's start, then the nearest free places).
        names: One name per robot (default ``robot1`` ... ``robotN``).
        unknown_map: Each robot starts knowing nothing and learns its map from its own lidar.
        sensors: Plugin sensor kinds each robot carries (default none).

    Raises:
        WorldFileError: The world or the profile is broken.
        ConfigError: A bad count, start, name list, or a world with no room for the robots.
    """
    loaded = world if isinstance(world, World) else load_world(world)
    profile = load_robot_profile(robot or loaded.profile_name, dict(config) if config else None)
    return SimFleet(loaded, profile, robots, seed=seed, starts=starts, names=names,
                    unknown_map=unknown_map, sensors=sensors)
