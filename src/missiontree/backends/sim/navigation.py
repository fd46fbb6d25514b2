"""A NavigateToPose equivalent: inflated costmap, A* planner, path follower, tolerances, aborts.

Like Nav2: a global costmap holds lethal cells (walls and obstacles), an inscribed zone as wide
as the robot's radius around them (a goal there is unreachable, seed 001 §4.5.8) and an
inflation cost decaying as ``252 * exp(-cost_scaling * (d - radius))`` out to
``inflation_radius``. A* plans over it (8-connected, cost-weighted); a pure-pursuit follower
drives the path; the goal is reached within ``tolerance.xy`` and, unless ``tolerance.yaw`` is a
full turn (seed 001 §3.6), after turning to the goal heading. What the lidar sees ahead (people)
stops the robot; the planner then replans around it, and the goal aborts when the way stays
blocked for ``blocked_timeout`` seconds. Results are values with a reason, never exceptions.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import cv2
import numpy as np

from missiontree.backends.sim.raycast import HAVE_NUMBA
from missiontree.backends.sim.schema import NavigationSpec
from missiontree.robot.actions import ActionResult, ActionStatus, NavFeedback
from missiontree.types import LaserScan, OccupancyGrid, Pose2D, Tolerance, wrap_angle

if TYPE_CHECKING:
    from missiontree.backends.sim.robot import SimRobot

if HAVE_NUMBA:
    import numba

LETHAL = 254
INSCRIBED = 253
#: Nav2-like error codes carried in ActionResult.code.
NO_VALID_PATH, GOAL_IN_OBSTACLE, BLOCKED, NO_PROGRESS, OUT_OF_MAP = 204, 205, 206, 207, 208
_ROTATE_FIRST = 0.7        # rad of heading error above which the follower turns in place
_NO_PROGRESS_TIME = 30.0


class Costmap:
    """A Nav2-style inflated costmap (0 free .. 252 inflated, 253 inscribed, 254 lethal)."""

    def __init__(self, grid: OccupancyGrid, robot_radius: float, spec: NavigationSpec) -> None:
        self.grid = grid
        self.radius = robot_radius
        self.spec = spec
        self.static_lethal = grid.data >= 50
        self.cost = self._inflate(self.static_lethal)

    def _inflate(self, lethal: np.ndarray) -> np.ndarray:
        dist = cv2.distanceTransform((~lethal).astype(np.uint8), cv2.DIST_L2, 5) * self.grid.resolution
        cost = np.zeros(lethal.shape, np.uint8)
        band = (dist <= self.spec.inflation_radius) & (dist >= self.radius)
        cost[band] = (252.0 * np.exp(-self.spec.cost_scaling * (dist[band] - self.radius))).astype(np.uint8)
        cost[dist < self.radius] = INSCRIBED
        cost[lethal] = LETHAL
        return cost

    def with_points(self, points: np.ndarray, radius: float = 0.08) -> np.ndarray:
        """The cost array with extra lethal discs at ``points`` (N, 2) in the map frame."""
        lethal = self.static_lethal.copy()
        r_cells = max(1, int(round(radius / self.grid.resolution)))
        for x, y in points:
            row, col = self.grid.world_to_cell(float(x), float(y))
            if 0 <= row < lethal.shape[0] and 0 <= col < lethal.shape[1]:
                cv2.circle(lethal.view(np.uint8), (col, row), r_cells, 1, -1)
        return self._inflate(lethal)

    def cell_cost(self, cost: np.ndarray, x: float, y: float) -> int:
        """Cost at a map point; LETHAL outside the map."""
        row, col = self.grid.world_to_cell(x, y)
        if not (0 <= row < cost.shape[0] and 0 <= col < cost.shape[1]):
            return LETHAL
        return int(cost[row, col])


def _astar_loops(cost, start, goal, weight):  # noqa: ANN001, ANN202 - compiled by numba when present
    """A* over an 8-connected grid; returns the cell path (goal first), empty when none exists."""
    h, w = cost.shape
    n = h * w
    g = np.full(n, np.inf)
    parent = np.full(n, -1, np.int64)
    closed = np.zeros(n, np.bool_)
    heap_key = np.empty(8 * n + 8)
    heap_val = np.empty(8 * n + 8, np.int64)
    size = 0
    gr, gc = goal // w, goal % w
    g[start] = 0.0
    heap_key[0], heap_val[0], size = 0.0, start, 1
    drs = (-1, -1, -1, 0, 0, 1, 1, 1)
    dcs = (-1, 0, 1, -1, 1, -1, 0, 1)
    while size > 0:
        cur = heap_val[0]
        # pop: move last to root, sift down
        size -= 1
        heap_key[0], heap_val[0] = heap_key[size], heap_val[size]
        i = 0
        while True:
            left = 2 * i + 1
            if left >= size:
                break
            child = left
            if left + 1 < size and heap_key[left + 1] < heap_key[left]:
                child = left + 1
            if heap_key[child] < heap_key[i]:
                heap_key[i], heap_key[child] = heap_key[child], heap_key[i]
                heap_val[i], heap_val[child] = heap_val[child], heap_val[i]
                i = child
            else:
                break
        if closed[cur]:
            continue
        closed[cur] = True
        if cur == goal:
            break
        r, c = cur // w, cur % w
        for k in range(8):
            nr, nc = r + drs[k], c + dcs[k]
            if nr < 0 or nr >= h or nc < 0 or nc >= w:
                continue
            nxt = nr * w + nc
            if closed[nxt] or cost[nr, nc] >= INSCRIBED:
                continue
            step = 1.4142135623730951 if drs[k] != 0 and dcs[k] != 0 else 1.0
            ng = g[cur] + step * (1.0 + weight * cost[nr, nc] / 252.0)
            if ng < g[nxt]:
                g[nxt] = ng
                parent[nxt] = cur
                f = ng + math.sqrt((nr - gr) ** 2 + (nc - gc) ** 2)
                j = size
                heap_key[j], heap_val[j] = f, nxt
                size += 1
                while j > 0:
                    up = (j - 1) // 2
                    if heap_key[up] > heap_key[j]:
                        heap_key[up], heap_key[j] = heap_key[j], heap_key[up]
                        heap_val[up], heap_val[j] = heap_val[j], heap_val[up]
                        j = up
                    else:
                        break
    if parent[goal] < 0 and goal != start:
        return np.zeros(0, np.int64)
    path = [goal]
    cur = goal
    while cur != start:
        cur = parent[cur]
        path.append(cur)
    return np.array(path, dtype=np.int64)


_astar_jit = numba.njit(cache=True)(_astar_loops) if HAVE_NUMBA else _astar_loops


def plan(costmap: Costmap, cost: np.ndarray, start: Pose2D, goal: Pose2D, accelerate: bool = True,
         cost_weight: float = 3.0) -> np.ndarray | None:
    """A path of map points (N, 2) from ``start`` to ``goal``, or None when there is none."""
    grid = costmap.grid
    h, w = cost.shape
    sr, sc = grid.world_to_cell(start.x, start.y)
    gr, gc = grid.world_to_cell(goal.x, goal.y)
    if not (0 <= sr < h and 0 <= sc < w and 0 <= gr < h and 0 <= gc < w):
        return None
    work = cost
    if cost[sr, sc] >= INSCRIBED:
        # the robot stands too close to something (odometry drift, a person stepped up): let it
        # leave through the inscribed zone, never through lethal cells
        work = cost.copy()
        r = int(math.ceil((costmap.radius + 0.1) / grid.resolution))
        sub = work[max(0, sr - r): sr + r + 1, max(0, sc - r): sc + r + 1]
        sub[sub == INSCRIBED] = 252
    fn = _astar_jit if accelerate else _astar_loops
    cells = fn(work, sr * w + sc, gr * w + gc, cost_weight)
    if len(cells) == 0:
        return None
    rows, cols = cells[::-1] // w, cells[::-1] % w
    pts = np.stack([grid.origin.x + (cols + 0.5) * grid.resolution,
                    grid.origin.y + (rows + 0.5) * grid.resolution], axis=1)
    pts[0] = (start.x, start.y)
    pts[-1] = (goal.x, goal.y)
    return pts


def path_length(points: np.ndarray) -> float:
    """Length of a polyline."""
    if len(points) < 2:
        return 0.0
    return float(np.hypot(*np.diff(points, axis=0).T).sum())


class SimNavHandle:
    """The ActionHandle of one simulated NavigateToPose goal."""

    def __init__(self, goal: Pose2D, tolerance: Tolerance, sent: float) -> None:
        self.goal = goal
        self.tolerance = tolerance
        self.sent = sent
        self._status = ActionStatus.ACCEPTED
        self._feedback: NavFeedback | None = None
        self._result: ActionResult | None = None
        self.cancel_requested = False

    def status(self) -> ActionStatus:
        """Current status."""
        return self._status

    def feedback(self) -> NavFeedback | None:
        """Latest feedback (distance remaining along the path), None before the first."""
        return self._feedback

    def result(self) -> ActionResult | None:
        """The result once done."""
        return self._result

    def cancel(self) -> None:
        """Ask to cancel; takes effect at the simulator's next step (idempotent)."""
        if not self._status.done:
            self.cancel_requested = True

    def _finish(self, status: ActionStatus, reason: str = "", code: int = 0) -> None:
        if not self._status.done:
            self._status = status
            self._result = ActionResult(status, reason, code)


@dataclass
class _Follow:
    path: np.ndarray
    cumulative: np.ndarray = None  # type: ignore[assignment]  # arc length at each path point
    points: list[tuple[float, float]] = None  # type: ignore[assignment]
    cumulative_list: list[float] = None  # type: ignore[assignment]
    total: float = 0.0
    index: int = 0
    blocked_since: float | None = None
    last_replan: float = -math.inf
    best_remaining: float = math.inf
    best_time: float = 0.0
    last_step: float = 0.0
    aligning: bool = False

    def __post_init__(self) -> None:
        self.set_path(self.path)

    def set_path(self, path: np.ndarray) -> None:
        """Follow a new path from its start."""
        self.path, self.index = path, 0
        self.points = [(float(x), float(y)) for x, y in path]   # plain floats for the per-step loop
        steps = np.hypot(*np.diff(path, axis=0).T) if len(path) > 1 else np.zeros(0)
        self.cumulative = np.concatenate([[0.0], np.cumsum(steps)])
        self.cumulative_list = self.cumulative.tolist()
        self.total = self.cumulative_list[-1]


class Navigator:
    """Runs at most one goal at a time for a SimRobot; stepped by the robot's physics loop."""

    def __init__(self, robot: SimRobot, spec: NavigationSpec) -> None:
        self.robot = robot
        self.spec = spec
        self.costmap = Costmap(robot.world.grid, robot.profile.body.radius, spec)
        self.handle: SimNavHandle | None = None
        self._follow: _Follow | None = None
        self.plan_ms: list[float] = []
        self.goals: list[Pose2D] = []
        self._xy_cache: tuple[LaserScan, np.ndarray, np.ndarray] | None = None
        self._trig: tuple[tuple[float, float, int, float], np.ndarray, np.ndarray] | None = None
        self._ahead_cache: tuple[LaserScan, tuple[float, float] | None] | None = None

    def send(self, goal: Pose2D, tolerance: Tolerance | None, now: float) -> SimNavHandle:
        """Accept a new goal, preempting the running one."""
        if self.handle is not None:
            self.handle._finish(ActionStatus.CANCELED, "preempted by a new goal")
        tol = tolerance or Tolerance(self.spec.default_xy_tolerance, self.spec.default_yaw_tolerance)
        self.handle = SimNavHandle(goal, tol, now)
        self._follow = None
        self.goals.append(goal)
        return self.handle

    def cancel(self) -> None:
        """Cancel the running goal at once."""
        if self.handle is not None:
            self.handle._finish(ActionStatus.CANCELED, "canceled")
        self.handle, self._follow = None, None

    def step(self, now: float, pose: Pose2D, scan: LaserScan | None) -> tuple[float, float] | None:
        """Advance the running goal; the velocity command, or None when no goal runs."""
        h = self.handle
        if h is None:
            return None
        if h.cancel_requested:
            self.cancel()
            return 0.0, 0.0
        if self._follow is None:
            if not self._start(h, now, pose):
                self.handle = None
                return 0.0, 0.0
        follow = self._follow
        assert follow is not None
        gap = now - follow.last_step - self.robot.profile.physics_dt
        if gap > 1e-6:  # drive() overrode us meanwhile: the goal's timers pause
            follow.best_time += gap
            if follow.blocked_since is not None:
                follow.blocked_since += gap
        follow.last_step = now
        h._status = ActionStatus.RUNNING
        remaining = self._remaining(follow, pose)
        h._feedback = NavFeedback(pose, remaining, now - h.sent, 0)
        if remaining + 0.05 < follow.best_remaining:
            follow.best_remaining, follow.best_time = remaining, now
        elif now - follow.best_time > _NO_PROGRESS_TIME and follow.blocked_since is None:
            return self._abort(ActionStatus.ABORTED, f"no progress for {_NO_PROGRESS_TIME:.0f} s "
                               f"({remaining:.2f} m from the goal)", NO_PROGRESS)
        goal = h.goal
        dist = math.hypot(goal.x - pose.x, goal.y - pose.y)
        if dist <= h.tolerance.xy or follow.aligning:
            follow.aligning = True
            if h.tolerance.yaw >= math.pi:
                return self._succeed()
            err = wrap_angle(goal.yaw - pose.yaw)
            if abs(err) <= h.tolerance.yaw:
                return self._succeed()
            lim = self.robot.profile.limits
            return 0.0, float(np.clip(self.spec.heading_gain * err, -lim.max_w, lim.max_w))
        return self._drive(follow, now, pose, scan, remaining)

    # -- internals ---------------------------------------------------------------------------------

    def _start(self, h: SimNavHandle, now: float, pose: Pose2D) -> bool:
        goal = h.goal
        cost = self.costmap.cost
        c = self.costmap.cell_cost(cost, goal.x, goal.y)
        if c >= INSCRIBED:
            gap = self.robot.world.clearance(goal.x, goal.y)
            what = "outside the map" if gap == 0.0 and c == LETHAL and self._outside(goal) else (
                "inside an obstacle" if c == LETHAL else
                f"inside an obstacle's inscribed zone ({gap:.2f} m from it, robot radius "
                f"{self.costmap.radius:.2f} m)")
            h._finish(ActionStatus.ABORTED, f"goal ({goal.x:.2f}, {goal.y:.2f}) is {what}: unreachable",
                      OUT_OF_MAP if what == "outside the map" else GOAL_IN_OBSTACLE)
            return False
        path = self._plan(cost, pose, goal)
        if path is None:
            h._finish(ActionStatus.ABORTED, f"no valid path to ({goal.x:.2f}, {goal.y:.2f})", NO_VALID_PATH)
            return False
        self._follow = _Follow(path, best_time=now, last_step=now - self.robot.profile.physics_dt)
        return True

    def _outside(self, goal: Pose2D) -> bool:
        row, col = self.costmap.grid.world_to_cell(goal.x, goal.y)
        h, w = self.costmap.cost.shape
        return not (0 <= row < h and 0 <= col < w)

    def _plan(self, cost: np.ndarray, pose: Pose2D, goal: Pose2D) -> np.ndarray | None:
        import time

        t0 = time.perf_counter()
        path = plan(self.costmap, cost, pose, goal, self.robot.profile.accelerate)
        self.plan_ms.append((time.perf_counter() - t0) * 1000.0)
        return path

    def _remaining(self, follow: _Follow, pose: Pose2D) -> float:
        """Distance along the path from the robot; moves the progress index to the nearest point ahead."""
        points = follow.points
        best, best_i = math.inf, follow.index
        for i in range(follow.index, min(len(points), follow.index + 40)):
            d = math.hypot(points[i][0] - pose.x, points[i][1] - pose.y)
            if d < best:
                best, best_i = d, i
        follow.index = best_i
        return best + follow.total - follow.cumulative_list[best_i]

    def _drive(self, follow: _Follow, now: float, pose: Pose2D, scan: LaserScan | None,
               remaining: float) -> tuple[float, float]:
        points = follow.points
        target = points[-1]
        for i in range(follow.index, len(points)):
            px, py = points[i]
            if math.hypot(px - pose.x, py - pose.y) >= self.spec.lookahead:
                target = points[i]
                break
        err = wrap_angle(math.atan2(target[1] - pose.y, target[0] - pose.x) - pose.yaw)
        lim = self.robot.profile.limits
        w = max(-lim.max_w, min(lim.max_w, self.spec.heading_gain * err))
        if abs(err) > _ROTATE_FIRST:
            follow.blocked_since = None
            return 0.0, w
        v = lim.max_v * max(0.0, math.cos(err)) * min(1.0, 0.3 + remaining / 0.6)
        obstacle = self._obstacle_ahead(scan, v)
        if obstacle is None:
            follow.blocked_since = None
            return v, w
        if follow.blocked_since is None:
            follow.blocked_since = now
        if now - follow.blocked_since >= self.spec.blocked_timeout:
            ox, oy = pose.transform(*obstacle)
            return self._abort(ActionStatus.ABORTED, f"path blocked for {self.spec.blocked_timeout:.1f} s by "
                               f"an obstacle at ({ox:.2f}, {oy:.2f})", BLOCKED)
        if now - follow.last_replan >= self.spec.replan_period and now - follow.blocked_since >= 0.5:
            follow.last_replan = now
            points = self._scan_points(scan, pose)
            goal = self.handle.goal if self.handle else None
            path2 = self._plan(self.costmap.with_points(points), pose, goal) if goal else None
            if path2 is not None:
                follow.set_path(path2)
        return 0.0, 0.0

    def _obstacle_ahead(self, scan: LaserScan | None, v: float) -> tuple[float, float] | None:
        """The nearest scan point (robot frame) in the corridor the robot is about to sweep."""
        if scan is None:
            return None
        if self._ahead_cache is None or self._ahead_cache[0] is not scan:
            # nearest point in the robot's swept corridor, once per scan
            x, y = self._scan_xy(scan)
            hit = (x > 0.0) & (np.abs(y) < self.costmap.radius + 0.03)
            nearest = None
            if hit.any():
                i = int(np.argmin(np.where(hit, x, np.inf)))
                nearest = (float(x[i]), float(y[i]))
            self._ahead_cache = (scan, nearest)
        nearest = self._ahead_cache[1]
        reach = self.costmap.radius + self.spec.obstacle_margin + max(v, 0.1) * 0.5
        return nearest if nearest is not None and nearest[0] < reach else None

    def _scan_xy(self, scan: LaserScan) -> tuple[np.ndarray, np.ndarray]:
        """Scan end points in the robot frame (cached per scan)."""
        if self._xy_cache is None or self._xy_cache[0] is not scan:
            layout = (scan.angle_min, scan.angle_increment, len(scan.ranges), scan.mount_yaw)
            if self._trig is None or self._trig[0] != layout:
                ang = scan.angles()
                self._trig = (layout, np.cos(ang), np.sin(ang))
            r = np.asarray(scan.ranges, float)
            ok = np.isfinite(r)
            self._xy_cache = (scan, r[ok] * self._trig[1][ok], r[ok] * self._trig[2][ok])
        return self._xy_cache[1], self._xy_cache[2]

    def _scan_points(self, scan: LaserScan | None, pose: Pose2D) -> np.ndarray:
        if scan is None:
            return np.zeros((0, 2))
        r = np.asarray(scan.ranges, float)
        ang = scan.angles()
        ok = np.isfinite(r) & (r < 3.0)
        x, y = r[ok] * np.cos(ang[ok]), r[ok] * np.sin(ang[ok])
        c, s = math.cos(pose.yaw), math.sin(pose.yaw)
        return np.stack([pose.x + c * x - s * y, pose.y + s * x + c * y], axis=1)

    def _succeed(self) -> tuple[float, float]:
        assert self.handle is not None
        self.handle._finish(ActionStatus.SUCCEEDED)
        self.handle, self._follow = None, None
        return 0.0, 0.0

    def _abort(self, status: ActionStatus, reason: str, code: int) -> tuple[float, float]:
        assert self.handle is not None
        self.handle._finish(status, reason, code)
        self.handle, self._follow = None, None
        return 0.0, 0.0
