"""A NavigateToPose equivalent: inflated costmap, A* planner, path follower, tolerances, aborts.

Like Nav2: a global costmap holds lethal cells (walls and obstacles), an inscribed zone as wide
as the robot's radius around them (a goal there is unreachable, the patrol-robot thesis §4.5.8) and an
inflation cost decaying as ``252 * exp(-cost_scaling * (d - radius))`` out to
``inflation_radius`` (:mod:`missiontree.mapping.planner`: computed tile by tile as plans reach
it, updated where the map changes). A* plans over it (8-connected, cost-weighted); a pure-pursuit
follower drives the path, aiming only as far ahead as a straight line keeps the path's clearance
(no cutting a bend round a door jamb); the arc it drives is swept against the lidar (walls on the
map with a small side margin, anything else with a wider one), its speed regulated down to a creep
as something comes near; when that arc is blocked it tries slower arcs back to the path (as a
DWB-style local planner) or turns in place towards the path, which a round base can always do.
The goal is reached within ``tolerance.xy`` and, unless ``tolerance.yaw``
is a full turn (the thesis §3.6), after turning to the goal heading. What the lidar sees ahead
(people) stops the robot; the planner then replans around it, and the goal aborts when the way
stays blocked for ``blocked_timeout`` seconds. A robot blocked while already inside the clearance it
keeps from something (every arc towards its path sweeps it) first backs away from it as far as the
scan behind allows, Nav2's BackUp recovery, and replans from there; for a while after a recovery the
pure-pursuit line also keeps that clearance from what the map lacks (it no longer cuts the bend round it).

The navigator holds the decisions (start, wait, replan, back up, abort) and the goal's handle; the
parts are apart: planning -- the costmaps, the way out of an inscribed zone, the tighter costmap
for gaps the body fits -- in :class:`~missiontree.backends.sim.nav_plan.NavPlanner`, the path in
hand and the pure-pursuit geometry in :mod:`~missiontree.backends.sim.nav_follow`, the lidar's
geometry (the arc a command sweeps, lines clear of what the map lacks, the room behind) in
:class:`~missiontree.backends.sim.nav_scan.ScanView`. The navigator is built from
what it needs -- the map, the footprint radius, the robot profile's limits and step, the
navigation settings -- not from the robot. On a learned map
(``allow_unknown``, as Nav2 with a SLAM map) unknown cells are traversable; :meth:`Navigator.update_map`
takes each map update, and a path the learned map now blocks is replanned at the next step; the
goal aborts with a reason when it proves unreachable. Results are values with a reason, never
exceptions.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable

import numpy as np

from missiontree.backends.sim.nav_costmap import Costmap, free_goal_within, path_length, plan
from missiontree.backends.sim.nav_follow import ROTATE_FIRST, Follow, PathFollower
from missiontree.backends.sim.nav_handle import SimNavHandle
from missiontree.backends.sim.nav_plan import NavPlanner
from missiontree.backends.sim.nav_scan import CREEP_SPEED, SIDE_MARGIN, STOP_TIME, UNMAPPED_MARGIN, ScanView
from missiontree.backends.sim.schema import NavigationSpec, RobotProfile
from missiontree.mapping.planner import INSCRIBED, LETHAL, MAX_FREE
from missiontree.robot.actions import ActionStatus, NavFeedback
from missiontree.types import LaserScan, OccupancyGrid, Pose2D, Tolerance, wrap_angle

__all__ = ["BLOCKED", "GOAL_IN_OBSTACLE", "INSCRIBED", "LETHAL", "NO_PROGRESS", "NO_VALID_PATH", "OUT_OF_MAP",
           "Costmap", "Navigator", "SimNavHandle", "path_length", "plan"]

#: Nav2-like error codes carried in ActionResult.code.
NO_VALID_PATH, GOAL_IN_OBSTACLE, BLOCKED, NO_PROGRESS, OUT_OF_MAP = 204, 205, 206, 207, 208
_NO_PROGRESS_TIME = 30.0
_PINNED_TIME = 1.0         # s driving forward without moving before backing up
_BACKUP_TIME, _BACKUP_SPEED = 1.0, 0.1
_RECOVER_AFTER = 2.0       # s blocked with something inside the kept clearance before backing away from it
_RECOVERY_BACKUP = 0.25    # m the blocked recovery reverses at most (less when something is behind)
_MAX_RECOVERIES = 3        # blocked recoveries per goal (then the goal aborts when blocked_timeout runs out)
_HAZARD_LIFETIME = 60.0   # s a bumper hit stays in the costmap
_HAZARD_SEEN_RADIUS = 0.2  # m: a lidar return this close to a contact means the lidar sees what was touched
_MAX_HAZARDS = 2_000
_WARY_TIME = 3.0           # s the follower aims round what the map lacks after a recovery (or a blocked arc)
_TURN_WHEN_BLOCKED = 0.15  # rad: blocked with the path this far off the heading, turn in place
_MAX_GOALS_KEPT = 10_000   # goals remembered for pictures (the oldest are dropped on very long runs)
_GOAL_SLACK = 0.05         # m: a learned-map goal in an obstacle's zone moves at most tolerance.xy less this


class Navigator:
    """Runs at most one goal at a time; stepped by the simulator's physics loop.

    Args:
        grid: The map planned on (the static map, or the learned one in unknown-map runs).
        radius: Footprint radius in metres.
        profile: The robot profile (velocity limits, physics step, acceleration switch).
        spec: Costmap, follower and abort settings.
        clearance: Distance from a map point to the nearest obstacle, for abort messages (optional).
        allow_unknown: Unknown cells are traversable (a learned map), as Nav2's ``allow_unknown``.
    """

    def __init__(self, grid: OccupancyGrid, radius: float, profile: RobotProfile, spec: NavigationSpec,
                 clearance: Callable[[float, float], float] | None = None,
                 allow_unknown: bool = False) -> None:
        self.spec = spec
        self.limits = profile.limits
        self.physics_dt = profile.physics_dt
        self.accelerate = profile.accelerate
        self.clearance = clearance
        self.allow_unknown = allow_unknown
        self.body_radius = radius
        # a learned map's edges are a cell off the truth (a wall's end, its thickness): the planner pads
        # the footprint by two cells there, as Nav2's footprint_padding (see nav_plan)
        self.planning = NavPlanner(grid, radius, spec, allow_unknown, profile.accelerate)
        self.costmap = self.planning.costmap
        self.handle: SimNavHandle | None = None
        self._follow: Follow | None = None
        self.plan_ms = self.planning.plan_ms
        self.goals: deque[Pose2D] = deque(maxlen=_MAX_GOALS_KEPT)
        self.replans = 0
        self.recoveries = 0
        self._hazards: deque[tuple[float, float, float]] = deque(maxlen=_MAX_HAZARDS)
        self._map_changed = False
        self.scan_view = ScanView(self.costmap, spec, radius)  # the lidar's geometry for the follower
        self.follower = PathFollower(self.costmap, spec, self.limits, self.scan_view)

    @property
    def escapes(self) -> int:
        """Plans made by way of a point out of an obstacle's inscribed zone."""
        return self.planning.escapes

    @property
    def radius(self) -> float:
        """Footprint radius (m)."""
        return self.body_radius

    def update_map(self, grid: OccupancyGrid, region: tuple[int, int, int, int] | None = None) -> None:
        """Take a new version of the map (``region``: the rows/cols that changed, exclusive ends)."""
        self.planning.update(grid, region)
        self._map_changed = True

    def mark_hazard(self, x: float, y: float, now: float, scan: LaserScan | None = None,
                    pose: Pose2D | None = None) -> None:
        """An obstacle the robot touched (a bumper hit): lethal for a while, the path checked again.

        Low things under the lidar's plane never reach a learned map; like a hazard layer fed by
        the TurtleBot 4's bumper, the costmap keeps them for ``_HAZARD_LIFETIME`` seconds. What the
        lidar sees at the contact (``scan`` taken at ``pose``: a person's legs, a wall) is not marked:
        the lidar already keeps it in view, and a person who walks on must not seal a doorway.
        """
        follow = self._follow
        if follow is not None and follow.backing_until is None:
            follow.backing_until = now + _BACKUP_TIME   # the base's bump reflex: back off first
            self.recoveries += 1
        if scan is not None and pose is not None:
            seen = ScanView.world_points(scan, pose)
            if len(seen) and float(np.min(np.hypot(seen[:, 0] - x, seen[:, 1] - y))) < _HAZARD_SEEN_RADIUS:
                return
        if any(math.hypot(x - hx, y - hy) < 0.05 for _, hx, hy in self._hazards):
            return
        self._hazards.append((now, x, y))
        self.planning.add_lethal(np.array([[x, y]]))
        self._map_changed = True

    def _expire_hazards(self, now: float) -> None:
        if not self._hazards or now - self._hazards[0][0] < _HAZARD_LIFETIME:
            return
        while self._hazards and now - self._hazards[0][0] >= _HAZARD_LIFETIME:
            self._hazards.popleft()
        self.planning.set_lethal(np.array([(x, y) for _, x, y in self._hazards]).reshape(-1, 2))
        self._map_changed = True

    def send(self, goal: Pose2D, tolerance: Tolerance | None, now: float) -> SimNavHandle:
        """Accept a new goal, preempting the running one."""
        if self.handle is not None:
            self.handle.finish(ActionStatus.CANCELED, "preempted by a new goal")
        tol = tolerance or Tolerance(self.spec.default_xy_tolerance, self.spec.default_yaw_tolerance)
        self.handle = SimNavHandle(goal, tol, now)
        self._follow = None
        self.goals.append(goal)
        return self.handle

    def cancel(self) -> None:
        """Cancel the running goal at once."""
        if self.handle is not None:
            self.handle.finish(ActionStatus.CANCELED, "canceled")
        self.handle, self._follow = None, None

    def step(self, now: float, pose: Pose2D, scan: LaserScan | None) -> tuple[float, float] | None:
        """Advance the running goal; the velocity command, or None when no goal runs."""
        self._expire_hazards(now)
        h = self.handle
        if h is None:
            return None
        if h.cancel_requested:
            self.cancel()
            return 0.0, 0.0
        if self._follow is None:
            self._map_changed = False
            if not self._start(h, now, pose):
                self.handle = None
                return 0.0, 0.0
        follow = self._follow
        assert follow is not None
        waiting = follow.unreachable_since is not None
        if self._map_changed or (waiting and now - follow.last_replan >= self.spec.replan_period):
            self._map_changed = False
            stop = self._check_learned_map(follow, pose, now)
            if stop is not None:
                return stop
        if follow.unreachable_since is not None:
            return self._hold(h, follow, now, pose)
        self.scan_view.pose = pose
        gap = now - follow.last_step - self.physics_dt
        if gap > 1e-6:  # drive() overrode us meanwhile: the goal's timers pause
            follow.best_time += gap
            if follow.blocked_since is not None:
                follow.blocked_since += gap
        follow.last_step = now
        remaining = self.follower.remaining(follow, pose)
        h.report(NavFeedback(pose, remaining, now - h.sent, self.recoveries))
        if remaining + 0.05 < follow.best_remaining:
            follow.best_remaining, follow.best_time = remaining, now
        elif now - follow.best_time > _NO_PROGRESS_TIME and follow.blocked_since is None:
            return self._abort(ActionStatus.ABORTED, f"no progress for {_NO_PROGRESS_TIME:.0f} s "
                               f"({remaining:.2f} m from the goal)", NO_PROGRESS)
        if follow.backing_until is not None:
            command, replanned = self._backing(h, follow, now, pose, scan)
            if command is not None:
                return command
            if replanned:
                remaining = self.follower.remaining(follow, pose)
        goal = h.goal
        if math.hypot(goal.x - pose.x, goal.y - pose.y) <= h.tolerance.xy or follow.aligning:
            return self._align(h, follow, pose)
        return self._drive(follow, now, pose, scan, remaining)

    def _hold(self, h: SimNavHandle, follow: Follow, now: float, pose: Pose2D) -> tuple[float, float]:
        """No way on the map learned so far: stand still and wait for one (people move on)."""
        h.report(NavFeedback(pose, math.hypot(h.goal.x - pose.x, h.goal.y - pose.y), now - h.sent,
                             self.recoveries))
        follow.last_step = now
        return 0.0, 0.0

    def _backing(self, h: SimNavHandle, follow: Follow, now: float, pose: Pose2D,
                 scan: LaserScan | None) -> tuple[tuple[float, float] | None, bool]:
        """A back-up under way: (the reverse command, False), or (None, whether it replanned) at its end."""
        until = follow.backing_until
        assert until is not None
        # reverse until the time is up or something comes near behind (people walk there too)
        if now < until and self.scan_view.rear_room(scan) > _BACKUP_SPEED * STOP_TIME:
            return (-_BACKUP_SPEED, 0.0), False
        follow.backing_until = None
        # plan around what the lidar sees as well (as a blocked path's replan does): on the map
        # alone the new path runs into what pinned the robot again, back and forth
        path = self.planning.around(scan, pose, self._target_of(h), follow.tight)
        tight = follow.tight
        if path is None:
            path, tight = self.planning.way(pose, self._target_of(h))
        if path is None:
            return None, False
        follow.set_path(path)
        follow.tight = tight
        return None, True

    def _align(self, h: SimNavHandle, follow: Follow, pose: Pose2D) -> tuple[float, float]:
        """Within the goal's tolerance: done, or turn to the goal heading first."""
        follow.aligning = True
        if h.tolerance.yaw >= math.pi:
            return self._succeed()
        err = wrap_angle(h.goal.yaw - pose.yaw)
        if abs(err) <= h.tolerance.yaw:
            return self._succeed()
        lim = self.limits
        return 0.0, float(np.clip(self.spec.heading_gain * err, -lim.max_w, lim.max_w))

    # -- internals ---------------------------------------------------------------------------------

    def _goal_problem(self, goal: Pose2D) -> tuple[str, int] | None:
        """Why ``goal`` cannot be reached on the current map (reason, code), or None."""
        c = self.costmap.cost_at(goal.x, goal.y)
        if c <= MAX_FREE:
            return None
        if not self.costmap.contains(goal.x, goal.y):
            return "outside the map", OUT_OF_MAP
        if c == LETHAL:
            return "inside an obstacle", GOAL_IN_OBSTACLE
        if self.clearance is not None:
            gap = self.clearance(goal.x, goal.y)
            return (f"inside an obstacle's inscribed zone ({gap:.2f} m from it, robot radius "
                    f"{self.radius:.2f} m)", GOAL_IN_OBSTACLE)
        return f"within the robot radius ({self.radius:.2f} m) of an obstacle", GOAL_IN_OBSTACLE

    def _target_of(self, h: SimNavHandle) -> Pose2D:
        """Where to plan to: the goal; on a learned map, the nearest free point within its tolerance.

        A wall the map learns late can put the goal inside the inscribed zone; the goal is reached
        anywhere within ``tolerance.xy``, so a free point in there serves (NavFn's ``tolerance``).
        """
        if not self.allow_unknown:
            return h.goal
        return free_goal_within(self.costmap, h.goal, h.tolerance.xy - _GOAL_SLACK) or h.goal

    def _start(self, h: SimNavHandle, now: float, pose: Pose2D) -> bool:
        goal = self._target_of(h)
        problem = self._goal_problem(goal)
        if problem is not None and self.allow_unknown and problem[1] != OUT_OF_MAP:
            return self._wait_for_way(now, pose, problem)
        if problem is not None:
            what, code = problem
            learned = " on the learned map" if self.allow_unknown else ""
            h.finish(ActionStatus.ABORTED,
                      f"goal ({goal.x:.2f}, {goal.y:.2f}) is {what}{learned}: unreachable",
                      code)
            return False
        path, tight = self.planning.way(pose, goal)
        if path is None and self.allow_unknown:
            return self._wait_for_way(now, pose, ("no path to it on the map learned so far", NO_VALID_PATH))
        if path is None:
            h.finish(ActionStatus.ABORTED, f"no valid path to ({goal.x:.2f}, {goal.y:.2f})", NO_VALID_PATH)
            return False
        self._follow = Follow(path, best_time=now, last_step=now - self.physics_dt, tight=tight)
        return True

    def _wait_for_way(self, now: float, pose: Pose2D, why: tuple[str, int]) -> bool:
        """Start a learned-map goal with no way yet: hold still and look again (see _check_learned_map)."""
        self._follow = Follow(np.array([[pose.x, pose.y]]), best_time=now, last_step=now - self.physics_dt,
                               last_replan=now, unreachable_since=now, why=why)
        return True

    def _check_learned_map(self, follow: Follow, pose: Pose2D, now: float) -> tuple[float, float] | None:
        """After a map update: replan when the path is blocked; abort when the goal proved unreachable.

        The goal proves unreachable when, for ``blocked_timeout`` seconds, the learned map shows it
        inside an obstacle or offers no path to it (a person standing in a door closes it for a while).
        """
        assert self.handle is not None
        goal = self._target_of(self.handle)
        problem = self._goal_problem(goal)
        if problem is not None and problem[1] == OUT_OF_MAP:
            return self._abort(ActionStatus.ABORTED, f"goal ({goal.x:.2f}, {goal.y:.2f}) is outside the "
                               "learned map: unreachable", OUT_OF_MAP)
        if problem is None and follow.unreachable_since is None:
            ahead = follow.path[follow.index + 1:]
            if not len(ahead) or not self.planning.costmap_for(follow.tight).blocked_along(ahead):
                return None
        path, tight = (None, False) if problem is not None else self.planning.way(pose, goal)
        follow.last_replan = now
        self.replans += 1
        if path is not None:
            follow.set_path(path)
            follow.tight = tight
            follow.best_remaining, follow.best_time = math.inf, now
            follow.unreachable_since = None
            return None
        if problem is not None:
            follow.why = (f"the map shows it {problem[0]}", problem[1])
        else:
            follow.why = ("no path to it on the map learned so far", NO_VALID_PATH)
        if follow.unreachable_since is None:
            follow.unreachable_since = now
        if now - follow.unreachable_since >= self.spec.blocked_timeout:
            what, code = follow.why
            return self._abort(ActionStatus.ABORTED, f"goal ({goal.x:.2f}, {goal.y:.2f}) proved unreachable: "
                               f"{what} (for {self.spec.blocked_timeout:.0f} s)", code)
        return 0.0, 0.0

    def _drive(self, follow: Follow, now: float, pose: Pose2D, scan: LaserScan | None,
               remaining: float) -> tuple[float, float]:
        # after a recovery the pure-pursuit line keeps the clearance the arc check keeps from what
        # the map lacks (round it the line cut the bend, the arc was blocked and swerves crept back
        # in), until the way has been clear for _WARY_TIME
        wary = now < follow.wary_until
        target = self.follower.target(follow, pose, scan if wary else None)
        err, v, w = self.follower.aim(pose, target, remaining)
        if abs(err) > ROTATE_FIRST:
            follow.blocked_since = None
            return 0.0, w
        obstacle = self.scan_view.obstacle_ahead(scan, v, w)
        if obstacle is not None and wary:
            follow.wary_until = now + _WARY_TIME
        if obstacle is not None:
            # regulate the speed to what lidar sees ahead (as Nav2's regulated pure pursuit): creep
            # on while the stopping distance at a lower speed keeps clear of it
            # on the same arc (the curvature kept, as Nav2's regulated pure pursuit scales speed)
            slower = (obstacle[0] - self.radius - self.spec.obstacle_margin - 0.01) / STOP_TIME
            if CREEP_SPEED <= slower < v:
                w *= slower / v
                v = slower
                obstacle = self.scan_view.obstacle_ahead(scan, v, w)
        if obstacle is not None:
            swerve = self.follower.swerve(follow, pose, scan)
            if swerve is not None:
                v, w = swerve
                obstacle = None
        if obstacle is None:
            follow.blocked_since = None
            if self._pinned(follow, now, pose):
                return self._back_up(follow, now)
            return v, w
        if follow.blocked_since is None:
            follow.blocked_since = now
        if now - follow.blocked_since >= self.spec.blocked_timeout:
            ox, oy = pose.transform(*obstacle[1:])
            n = follow.blocked_recoveries
            tried = f" (backed away {n} time{'s' if n > 1 else ''})" if n else ""
            return self._abort(ActionStatus.ABORTED, f"path blocked for {self.spec.blocked_timeout:.1f} s by "
                               f"an obstacle at ({ox:.2f}, {oy:.2f}){tried}", BLOCKED)
        if now - follow.blocked_since >= _RECOVER_AFTER:
            recovery = self._recover(follow, now, scan, obstacle)
            if recovery is not None:
                return recovery
        if now - follow.last_replan >= self.spec.replan_period and now - follow.blocked_since >= 0.5:
            follow.last_replan = now
            goal = self._target_of(self.handle) if self.handle else None
            path2 = self.planning.around(scan, pose, goal, follow.tight) if goal else None
            self.replans += 1
            if path2 is not None:
                follow.set_path(path2)
        if abs(err) > _TURN_WHEN_BLOCKED:
            # what blocks the arc is not where the path leads (a door post on the inside of a turn):
            # a round base turns in place without sweeping anything new, then the arc is checked again
            return 0.0, w
        return 0.0, 0.0

    def _pinned(self, follow: Follow, now: float, pose: Pose2D) -> bool:
        """Whether the robot has been driving forward without moving (pinned against something)."""
        if follow.anchor is None or math.hypot(pose.x - follow.anchor[0], pose.y - follow.anchor[1]) > 0.02:
            follow.anchor, follow.still_since = (pose.x, pose.y), now
            return False
        return now - follow.still_since > _PINNED_TIME

    def _recover(self, follow: Follow, now: float, scan: LaserScan | None,
                 obstacle: tuple[float, float, float]) -> tuple[float, float] | None:
        """Nav2's BackUp recovery for a robot stuck inside the clearance it keeps: the command, or None.

        The follower keeps ``UNMAPPED_MARGIN`` beside its footprint clear of what the map lacks
        (``SIDE_MARGIN`` of the map's own obstacles); a robot already closer than that to
        something (it came in on a swerve, or the thing was put there) finds every arc towards its
        path blocked, and replans there start inside the obstacle's zone too: it would stand still
        until ``blocked_timeout``, goal after goal. When what blocks the arc lies within that
        clearance, it reverses away from it (the blocking point is ahead, so reversing opens the
        gap) by up to ``_RECOVERY_BACKUP``, as far as the scan behind allows; the back-up's end
        replans around what the lidar sees. At most ``_MAX_RECOVERIES`` a goal; the blocked timer
        runs on, so a way that stays shut still aborts.
        """
        if follow.blocked_recoveries >= _MAX_RECOVERIES:
            return None
        ox, oy = self.scan_view.pose.transform(obstacle[1], obstacle[2])
        mapped = self.costmap.cost_at(ox, oy) >= INSCRIBED   # as ScanView.mapped judges scan points
        kept = self.radius + (SIDE_MARGIN if mapped else UNMAPPED_MARGIN)
        if math.hypot(obstacle[1], obstacle[2]) >= kept:
            return None   # an ordinary stop before something: wait, replan, abort as before
        room = min(self.scan_view.rear_room(scan), _RECOVERY_BACKUP)
        if room <= _BACKUP_SPEED * STOP_TIME:
            return None   # boxed in behind as well
        follow.blocked_recoveries += 1
        follow.backing_until = now + room / _BACKUP_SPEED
        follow.wary_until = follow.backing_until + _WARY_TIME
        follow.anchor = None
        self.recoveries += 1
        return -_BACKUP_SPEED, 0.0

    def _back_up(self, follow: Follow, now: float) -> tuple[float, float]:
        """Nav2's BackUp recovery: reverse a little, then plan again from there."""
        follow.backing_until = now + _BACKUP_TIME
        follow.wary_until = follow.backing_until + _WARY_TIME
        follow.anchor = None
        self.recoveries += 1
        return -_BACKUP_SPEED, 0.0

    def _succeed(self) -> tuple[float, float]:
        assert self.handle is not None
        self.handle.finish(ActionStatus.SUCCEEDED)
        self.handle, self._follow = None, None
        return 0.0, 0.0

    def _abort(self, status: ActionStatus, reason: str, code: int) -> tuple[float, float]:
        assert self.handle is not None
        self.handle.finish(status, reason, code)
        self.handle, self._follow = None, None
        return 0.0, 0.0
