"""SimRobot: the simulated TurtleBot behind the Robot protocol, stepped, deterministic, headless.

``spin_until(t)`` steps the physics at a fixed ``physics_dt`` (control, motion with collision
checks, odometry) and produces the sensors at their own rates (lidar 10 Hz, RGB-D 5 Hz by
default; a camera frame is drawn when it is read, :mod:`missiontree.backends.sim.frames`).
Everything random comes from generators seeded by the run seed, so the same seed gives the same
scans, images and trajectory. ``pose()`` is the robot's *estimate* (odometry,
noisy when configured), never the truth; ground truth lives in ``truth`` for evaluation only.

With ``unknown_map`` the robot starts knowing nothing: ``occupancy()`` is the log-odds map
(:class:`~missiontree.mapping.grid.LogOddsGrid`) built from its own scans, each integrated at the
pose estimate of the scan's stamp, in the world raster's frame (every cell unknown at first; the
grid grows if a scan reaches past it), and navigation plans on that map with unknown cells
traversable, as Nav2 does with a SLAM map.

Memory stays flat on long runs: timings keep their recent samples and running totals, the
trajectory is thinned (a point per ``_TRAJECTORY_STEP`` metres or turn, spacing doubled whenever
it outgrows ``_TRAJECTORY_MAX`` points), the ground truth's visibility log is compact.
"""

from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Any

import numpy as np

from missiontree.backends.sim.camera import Camera, Floor
from missiontree.backends.sim.frames import FrameFeed
from missiontree.backends.sim.kinematics import DiffDrive, Odometry
from missiontree.backends.sim.lidar import Lidar
from missiontree.backends.sim.navigation import Navigator, SimNavHandle
from missiontree.backends.sim.people import BODY_RADIUS
from missiontree.backends.sim.raycast import HAVE_NUMBA, Primitives
from missiontree.backends.sim.render import BUMPS_MEANING, Scene, SceneObject, ScenePerson, SceneRoom
from missiontree.backends.sim.schema import RobotProfile
from missiontree.backends.sim.timing import TimingLog
from missiontree.backends.sim.truth import GroundTruth
from missiontree.backends.sim.world import World
from missiontree.mapping.grid import LogOddsGrid, logit
from missiontree.mapping.occupancy import BLOCKED_FROM
from missiontree.robot.commands import Command, LineCommands
from missiontree.robot.history import StampedHistory
from missiontree.robot.sensors import SensorKind, SensorReading, SimSensors
from missiontree.types import LaserScan, Marker, OccupancyGrid, Pose2D, PoseStamped, RGBDFrame, Tolerance

_TIME_EPS = 1e-9
_TRAJECTORY_PERIOD = 0.25   # s between trajectory points at most...
_TRAJECTORY_STEP = 0.05     # ...and only once the robot moved this far (m) or turned 0.2 rad
_CONTACT_GAP = 1.0          # s without a refused move before the next one is a new contact
_CONTACTS_KEPT = 50         # contacts listed with their place in the summary (all are counted)
_TRAJECTORY_MAX = 5_000     # points kept; past it every other point goes and the spacing doubles


class SimRobot:
    """A simulated robot in a :class:`World`; implements Robot and Drawable.

    Attributes:
        truth: Ground truth for scoring and declared oracles — not part of the Robot protocol;
            behaviours must not use it.
        timings: Per-call wall-clock milliseconds of lidar, camera, planner (and mapping in
            unknown-map runs), as :class:`TimingLog` (recent samples, count and totals).
        unknown_map: True when the robot learns its map from its lidar.
    """

    simulated = True

    def __init__(self, world: World, profile: RobotProfile, seed: int = 0, name: str = "sim",
                 unknown_map: bool = False, sensors: list[SensorKind] | None = None) -> None:
        self.name = name
        self.world = world
        self.profile = profile
        self.seed = seed
        streams = np.random.SeedSequence(seed).spawn(3)
        accel = profile.accelerate and HAVE_NUMBA
        self.lidar = Lidar(profile.lidar, np.random.default_rng(streams[0]), accel)
        self.camera = Camera(profile.camera, np.random.default_rng(streams[1]), accel)
        self._base = DiffDrive(world.start, profile.limits)
        self._odom = Odometry(world.start, profile.odometry, np.random.default_rng(streams[2]))
        self.unknown_map = unknown_map
        self._learned: LogOddsGrid | None = None
        self._known: np.ndarray | None = None  # the learned map's trinary cells, kept up to date
        self._occupancy: OccupancyGrid | None = None  # snapshot handed out by occupancy()
        self._nav = self._start_navigation(world, profile, unknown_map)
        self._floor = Floor.build(world.floor_rgb, world.grid.origin.x, world.grid.origin.y,
                            world.grid.resolution, world.ceiling)
        self._start_clock(profile)
        #: Plugin sensors (missiontree.robot.sensors), configured by the world's ``plugins:`` sections.
        self.plugin_sensors = SimSensors(list(sensors or []), world.spec.plugins, seed)
        self.odometer = 0.0  # metres driven (true motion), for plugin sensor models
        self._v = self._w = 0.0
        self.bumps = 0  # physics steps whose move was refused (the body would have hit something)
        #: Contacts: runs of refused moves (no gap over _CONTACT_GAP), each as (t, x, y) of the true
        #: pose where it began (the first _CONTACTS_KEPT); the summary's ``bumps`` reports them.
        self.contacts: list[tuple[float, float, float]] = []
        self.contact_count = 0
        self._last_refused = -math.inf
        self.timings: dict[str, TimingLog] = {"lidar": TimingLog(), "camera": TimingLog(),
                                              "planner": self._nav.plan_ms, "mapping": TimingLog()}
        #: Camera frames, rendered when read (see missiontree.backends.sim.frames).
        self.frames = FrameFeed(self.camera, lambda: self._floor, profile.camera.mount.z, lambda: self.truth,
                                self.timings["camera"], accel and profile.camera_thread)
        self.truth = GroundTruth(world, lambda: self._base.pose, profile.history_horizon,
                                 self.frames.flush_truth)
        self.trajectory: list[tuple[float, float, float]] = []
        self._trajectory_step = _TRAJECTORY_STEP
        self._last_yaw = world.start.yaw
        self._closed = False
        #: The command channel: lines on stdin (read only once a mission asks); tests may replace it.
        self.command_input = LineCommands()
        self._record_pose()
        self._sense()

    def _start_navigation(self, world: World, profile: RobotProfile, unknown_map: bool) -> Navigator:
        """The navigator on the world's map, or on a learned map that starts unknown (``unknown_map``)."""
        if not unknown_map:
            return Navigator(world.grid, profile.body.radius, profile, profile.navigation,
                             clearance=world.clearance)
        g = world.grid
        rows, cols = g.data.shape
        self._learned = LogOddsGrid(g.resolution, cols * g.resolution, rows * g.resolution, g.origin,
                                    sensor_offset=(profile.lidar.mount.x, profile.lidar.mount.y),
                                    accelerate=profile.accelerate)
        self._known = self._learned.trinary()
        start_grid = OccupancyGrid(0.0, g.resolution, g.origin, self._known)
        return Navigator(start_grid, profile.body.radius, profile, profile.navigation, allow_unknown=True)

    def _start_clock(self, profile: RobotProfile) -> None:
        """Time zero: no command, no sensor data yet, empty histories, every sensor publishing."""
        self._steps = 0
        self._t = 0.0
        self._drive: tuple[float, float] | None = None
        self._scan: LaserScan | None = None
        self._poses: StampedHistory[Pose2D] = StampedHistory(profile.history_horizon, maxlen=100_000)
        self._scans: StampedHistory[LaserScan] = StampedHistory(profile.history_horizon)
        self._next_scan = 0.0
        self._next_frame = 0.0
        self._quiet: set[str] = set()

    # -- Robot protocol ----------------------------------------------------------------------------

    def now(self) -> float:
        """Simulated time in seconds."""
        return self._t

    def spin_until(self, t: float) -> None:
        """Step the physics until the clock reaches ``t`` (at most one step past it)."""
        while self._t < t - _TIME_EPS and not self._closed:
            self._step()

    def pose(self) -> PoseStamped | None:
        """The pose estimate now (odometry; noisy when configured)."""
        return PoseStamped(self._t, self._odom.pose)

    def scan(self) -> LaserScan | None:
        """The latest scan (stale when the lidar went quiet)."""
        return self._scan

    def rgbd(self) -> RGBDFrame | None:
        """The latest colour + depth frame (rendered now: frames nobody reads are not drawn)."""
        return self.frames.latest()

    def occupancy(self) -> OccupancyGrid | None:
        """The map: the static one (what map_server would serve), or the one learned so far.

        In unknown-map runs the grid is stamped with the last scan integrated (read-only; a new
        grid after every map update), like a SLAM node's /map.
        """
        if self._learned is not None:
            if self._occupancy is None:
                assert self._known is not None
                data = self._known.copy()
                data.flags.writeable = False
                stamp = self._learned.last_stamp or 0.0
                self._occupancy = OccupancyGrid(stamp, self._learned.resolution, self._learned.origin, data)
            return self._occupancy
        g = self.world.grid
        return OccupancyGrid(self._t, g.resolution, g.origin, g.data)

    def pose_at(self, stamp: float) -> Pose2D | None:
        """The pose estimate at ``stamp``, interpolated within the recent history."""
        pair = self._poses.bracket(stamp)
        if pair is None:
            return None
        (t0, p0), (t1, p1) = pair
        if t1 <= t0:
            return p0
        a = (stamp - t0) / (t1 - t0)
        dyaw = math.remainder(p1.yaw - p0.yaw, 2 * math.pi)
        return Pose2D(p0.x + a * (p1.x - p0.x), p0.y + a * (p1.y - p0.y),
                      math.remainder(p0.yaw + a * dyaw, 2 * math.pi))

    def scan_at(self, stamp: float) -> LaserScan | None:
        """The scan taken closest to ``stamp`` within the recent history."""
        span = self._scans.span()
        if span is None:
            return None
        first, last = span
        period = 1.0 / self.profile.lidar.rate
        if stamp < first - period or stamp > last + period:
            return None
        return self._scans.nearest(stamp)

    def sensor(self, name: str) -> SensorReading | None:
        """The latest reading of a plugin sensor (stale stamp when silenced), None before the first."""
        return self.plugin_sensors.store.get(name)

    def sensor_names(self) -> list[str]:
        """The plugin sensors this robot has."""
        return self.plugin_sensors.store.names()

    def sensor_kind(self, name: str) -> SensorKind:
        """What plugin sensor ``name`` is (UnknownSensorError naming the robot's sensors otherwise)."""
        return self.plugin_sensors.store.kind(name)

    def navigate_to(self, goal: Pose2D, tolerance: Tolerance | None = None) -> SimNavHandle:
        """Send a NavigateToPose goal; planning happens at the next step. Ends a drive() override."""
        self._drive = None
        return self._nav.send(goal, tolerance, self._t)

    def drive(self, v: float, w: float) -> None:
        """Command a body velocity (m/s, rad/s), overriding navigation.

        The command holds until stop(), another drive() or navigate_to().
        """
        self._drive = (float(v), float(w))

    def stop(self) -> None:
        """Cancel navigation and command zero velocity."""
        self._nav.cancel()
        self._drive = None
        self._base.command(0.0, 0.0)

    def close(self) -> None:
        """Stop; further spinning does nothing."""
        self.stop()
        self.frames.finish()
        self._closed = True

    # -- command channel (missiontree.robot.commands.CommandChannel) -------------------------------

    def commands(self) -> list[Command]:
        """Commands received since the last call: lines on stdin, stamped with the simulated time."""
        return self.command_input.poll(self._t)

    def commands_closed(self) -> bool:
        """True once stdin has ended and every line was taken."""
        return self.command_input.closed

    # -- Drawable ----------------------------------------------------------------------------------

    def draw(self, out_dir: Path, markers: list[Marker]) -> list[Path]:
        """Write the top-down picture of the run so far (``<out_dir>/topdown.png``)."""
        from missiontree.backends.sim.render import draw_topdown

        out_dir = Path(out_dir)
        out_dir.mkdir(parents=True, exist_ok=True)
        path = out_dir / "topdown.png"
        draw_topdown(self.scene(), markers, path)
        return [path]

    def bump_report(self) -> dict[str, Any]:
        """Contacts for the run summary: how many, where they began, and what a bump is."""
        return {
            "contacts": self.contact_count,
            "refused_moves": self.bumps,
            "where": [{"t": t, "x": x, "y": y} for t, x, y in self.contacts],
            "meaning": BUMPS_MEANING,
        }

    def scene(self) -> Scene:
        """What the top-down picture shows of the run so far: a plain value (the truth, for pictures)."""
        world, now = self.world, self._t
        step = max(0.2, now / 5000.0)  # people's tracks: at most 5,000 points each
        times = np.arange(0.0, now + 1e-9, step) if now > 0 else np.array([0.0])
        people = []
        for person in world.crowd.people:
            states = [person.state_at(float(t)) for t in times]
            track = np.array([(st.x, st.y) for st in states if st.present], float).reshape(-1, 2)
            state = person.state_at(now)
            people.append(ScenePerson(person.id, track, (state.x, state.y) if state.present else None))
        return Scene(
            name=world.name, bounds=world.bounds(), grid=world.grid, now=now, seed=self.seed,
            bumps=self.contact_count,
            robot_pose=self._base.pose, robot_radius=self.profile.body.radius,
            rooms=[SceneRoom(r.name, r.type, r.polygon) for r in world.rooms],
            walls=list(world.wall_segments),
            objects=[SceneObject(o.id, tuple(int(c) for c in o.rgb), o.footprint(),  # type: ignore[arg-type]
                                 (o.pose.x, o.pose.y - o.size[1] / 2 - 0.12)) for o in world.objects],
            people=people, trajectory=list(self.trajectory), goals=list(self._nav.goals),
            learned=self.occupancy() if self.unknown_map else None)

    # -- simulator controls (not part of the Robot protocol) ---------------------------------------

    def silence(self, sensor: str, quiet: bool = True) -> None:
        """Make ``lidar``, ``camera`` or a plugin sensor stop (or resume) publishing (stale stamps)."""
        if sensor in self.plugin_sensors.store.kinds:
            (self.plugin_sensors.quiet.add if quiet else self.plugin_sensors.quiet.discard)(sensor)
            return
        if sensor not in ("lidar", "camera"):
            known = ", ".join(["lidar", "camera", *self.plugin_sensors.store.names()])
            raise ValueError(f"unknown sensor {sensor!r}; expected one of {known}")
        (self._quiet.add if quiet else self._quiet.discard)(sensor)

    @property
    def goals(self) -> list[Pose2D]:
        """Every navigation goal sent so far, in order (for pictures and evaluation)."""
        return list(self._nav.goals)

    @property
    def true_pose(self) -> Pose2D:
        """The true pose (for evaluation; behaviours use pose())."""
        return self._base.pose

    def dynamic_primitives(self, t: float) -> Primitives:
        """Prisms of what moves at time ``t`` (people)."""
        return self.world.crowd.primitives(t)

    # -- stepping ----------------------------------------------------------------------------------

    @property
    def closed(self) -> bool:
        """True once close() was called (spinning then does nothing)."""
        return self._closed

    def _step(self) -> None:
        """One physics step: move (or be refused), then record the pose and produce due sensor data."""
        self.step_motion()
        self.step_sensing()

    def step_sensing(self) -> None:
        """Record the pose of the step just moved and produce the sensor data due at its time."""
        self._record_pose()
        self._sense()

    def step_motion(self) -> None:
        """Control and motion of one physics step, with the collision check; advances the clock.

        Split from :meth:`step_sensing` so a fleet (:mod:`missiontree.backends.sim.fleet`) can move
        every robot of a step before any of them senses.
        """
        dt = self.profile.physics_dt
        # drive() overrides navigation while commanded; the goal waits (its timers paused)
        command = self._drive
        if command is None:
            command = self._nav.step(self._t, self._odom.pose, self._scan)
        if command is not None:
            self._base.command(*command)
        proposed, v, w = self._base.propose(dt)
        if self._collides(proposed):
            if self.unknown_map:  # the bumper tells the navigator what the lidar could not see
                here = self._base.pose
                dx, dy = proposed.x - here.x, proposed.y - here.y
                step = math.hypot(dx, dy)
                if step > 1e-9:
                    reach = self.profile.body.radius + 0.04
                    est = self._odom.pose
                    c, s = math.cos(est.yaw - here.yaw), math.sin(est.yaw - here.yaw)
                    ux, uy = dx / step, dy / step   # the push direction, turned into the estimate's frame
                    hx, hy = est.x + reach * (c * ux - s * uy), est.y + reach * (s * ux + c * uy)
                    self._nav.mark_hazard(hx, hy, self._t, self._scan, est)
            self._base.halt()
            self.bumps += 1
            if self._t - self._last_refused > _CONTACT_GAP:  # pushing on against the same thing is one
                self.contact_count += 1
                if len(self.contacts) < _CONTACTS_KEPT:
                    here = self._base.pose
                    self.contacts.append((round(self._t, 2), round(here.x, 2), round(here.y, 2)))
            self._last_refused = self._t
            v = w = 0.0
        else:
            self._base.accept(proposed, v, w)
        self.odometer += abs(v) * dt
        self._v, self._w = v, w
        self._odom.update(v, w, dt)
        self._steps += 1
        self._t = self._steps * dt

    def _collides(self, pose: Pose2D) -> bool:
        radius = self.profile.body.radius
        here = self._base.pose
        clear_now = self.world.clearance(here.x, here.y)
        clear_next = self.world.clearance(pose.x, pose.y)
        if clear_next < radius and clear_next < clear_now:  # allow moving out of contact
            return True
        for _, px, py in self.world.crowd.positions(self._t):
            d_next = math.hypot(pose.x - px, pose.y - py)
            if d_next < radius + BODY_RADIUS * 0.6 and d_next < math.hypot(here.x - px, here.y - py):
                return True
        return False

    def _record_pose(self) -> None:
        self._poses.push(self._t, self._odom.pose)
        p = self._base.pose
        self.truth.record_pose(self._t, p)
        traj = self.trajectory
        if traj and self._t - traj[-1][0] < _TRAJECTORY_PERIOD - _TIME_EPS:
            return
        if traj and (math.hypot(p.x - traj[-1][1], p.y - traj[-1][2]) < self._trajectory_step
                     and abs(math.remainder(p.yaw - self._last_yaw, 2 * math.pi)) < 0.2):
            return  # standing or turning in place: nothing to draw
        traj.append((self._t, p.x, p.y))
        self._last_yaw = p.yaw
        if len(traj) > _TRAJECTORY_MAX:  # thin out: keep every other point (the last one too)
            last = traj[-1]
            del traj[1::2]
            if traj[-1] is not last:
                traj.append(last)
            self._trajectory_step *= 2.0

    def _sense(self) -> None:
        t = self._t
        if self.plugin_sensors.kinds:
            p = self._base.pose
            self.plugin_sensors.step(t, (p.x, p.y, p.yaw), self._v, self._w, self.odometer)
        dynamic: Primitives | None = None
        if t >= self._next_scan - _TIME_EPS:
            self._next_scan = self._tick_after(self._next_scan, self.profile.lidar.rate)
            if "lidar" not in self._quiet:
                dynamic = self.dynamic_primitives(t)
                t0 = time.perf_counter()
                self._scan = self.lidar.scan(self._base.pose, t, self.world.static, dynamic)
                self.timings["lidar"].append((time.perf_counter() - t0) * 1000.0)
                self._scans.push(t, self._scan)
                if self._learned is not None:
                    self._learn(self._scan, self._odom.pose)
        if t >= self._next_frame - _TIME_EPS:
            self._next_frame = self._tick_after(self._next_frame, self.profile.camera.rate)
            if "camera" not in self._quiet:
                if dynamic is None:
                    dynamic = self.dynamic_primitives(t)
                self._start_frame(t, dynamic)

    def _tick_after(self, previous: float, rate: float) -> float:
        period = 1.0 / rate
        nxt = previous + period
        while nxt <= self._t + _TIME_EPS:
            nxt += period
        return nxt

    def _start_frame(self, t: float, dynamic: Primitives) -> None:
        """The frame of time ``t`` falls due: its inputs are snapshots (true camera pose, prisms at ``t``)."""
        mount_yaw = math.radians(self.profile.camera.mount.yaw_deg)
        self.frames.fall_due(t, self._camera_pose(self._base.pose, mount_yaw),
                             self.world.static.concat(dynamic), self._camera_pose(self._odom.pose, mount_yaw))

    def _learn(self, scan: LaserScan, pose: Pose2D) -> None:
        """Integrate a scan into the learned map at ``pose`` and tell the navigator what changed."""
        grid, known = self._learned, self._known
        assert grid is not None and known is not None
        t0 = time.perf_counter()
        shape, origin = grid.shape, grid.origin
        grid.integrate(scan, pose)
        self._occupancy = None
        if grid.shape != shape or grid.origin != origin:  # the grid grew: everything moves
            self._known = grid.trinary()
            self._nav.update_map(OccupancyGrid(scan.stamp, grid.resolution, grid.origin, self._known))
        else:
            x0, y0, x1, y1 = _scan_box(scan, pose, grid)
            r0, c0 = grid.world_to_cell(x0, y0)
            r1, c1 = grid.world_to_cell(x1, y1)
            r0, c0 = max(r0, 0), max(c0, 0)
            r1, c1 = min(r1 + 1, shape[0]), min(c1 + 1, shape[1])
            window = grid.logodds[r0:r1, c0:c1]
            fresh = np.full(window.shape, -1, np.int8)
            fresh[window < logit(grid.free_thresh)] = 0
            fresh[window > logit(grid.occupied_thresh)] = 100
            old = known[r0:r1, c0:c1]
            lethal_changed = (fresh >= BLOCKED_FROM) != (old >= BLOCKED_FROM)
            old[...] = fresh
            if lethal_changed.any():
                rows = np.flatnonzero(lethal_changed.any(axis=1))
                cols = np.flatnonzero(lethal_changed.any(axis=0))
                region = (r0 + int(rows[0]), r0 + int(rows[-1]) + 1,
                          c0 + int(cols[0]), c0 + int(cols[-1]) + 1)
                self._nav.update_map(OccupancyGrid(scan.stamp, grid.resolution, grid.origin, known), region)
        self.timings["mapping"].append((time.perf_counter() - t0) * 1000.0)

    def _camera_pose(self, base: Pose2D, mount_yaw: float) -> Pose2D:
        m = self.profile.camera.mount
        x, y = base.transform(m.x, m.y)
        return Pose2D(x, y, math.remainder(base.yaw + mount_yaw, 2 * math.pi))


def _scan_box(scan: LaserScan, pose: Pose2D, grid: LogOddsGrid) -> tuple[float, float, float, float]:
    """The map box (x0, y0, x1, y1) holding every cell that integrating ``scan`` at ``pose`` can change.

    The sensor and every beam's end point (a beam without a return at the sensor's range, a return
    ``hit_depth`` beyond its range), widened by two cells: in a room or a corridor the window to
    re-read is theirs, not the lidar's whole range (12 m: a 480-cell square at 5 cm) on every scan.
    """
    sx, sy = pose.transform(*grid.sensor_offset)
    ranges = np.asarray(scan.ranges, np.float64)
    angles = pose.yaw + scan.mount_yaw + scan.angle_min + scan.angle_increment * np.arange(len(ranges))
    limit = scan.range_max if grid.max_range is None else min(scan.range_max, grid.max_range)
    used = ~np.isnan(ranges) & (ranges >= scan.range_min)
    length = np.minimum(ranges[used], limit) + grid.hit_depth
    xs, ys = sx + length * np.cos(angles[used]), sy + length * np.sin(angles[used])
    pad = 2 * grid.resolution
    if not len(xs):
        return sx - pad, sy - pad, sx + pad, sy + pad
    return (min(float(xs.min()), sx) - pad, min(float(ys.min()), sy) - pad,
            max(float(xs.max()), sx) + pad, max(float(ys.max()), sy) + pad)
