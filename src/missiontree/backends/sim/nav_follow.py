"""The simulated navigator's controller: the path in hand and the pure-pursuit geometry that drives it.

:class:`Follow` is one goal's path and timers. :class:`PathFollower` answers the follower's geometric
questions: how much path is left, which path point to aim at (the farthest a straight line reaches
without cutting a bend's inside nearer to an obstacle than the path does), the pure-pursuit command
to it, and which slow arc leads back towards the path when the pure-pursuit arc is blocked. The
decisions (drive, wait, back up, abort) stay with :class:`~missiontree.backends.sim.navigation.Navigator`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from missiontree.backends.sim.nav_scan import ScanView
from missiontree.backends.sim.schema import LimitsSpec, NavigationSpec
from missiontree.mapping import planner
from missiontree.mapping.planner import MAX_FREE
from missiontree.types import LaserScan, Pose2D, wrap_angle

__all__ = ["ROTATE_FIRST", "Follow", "PathFollower"]

ROTATE_FIRST = 0.7        # rad of heading error above which the follower turns in place
_COST_SLACK = 12           # costmap units a lookahead line may exceed the path's own cost by (~2 cm)
_SWERVE_SPEEDS = (0.05, 0.1)          # m/s: the arcs tried when the pure-pursuit arc is blocked
_SWERVE_CURVATURES = tuple(np.linspace(-6.0, 6.0, 13).tolist())   # 1/m
_SWERVE_TIME = 0.6         # s: how far along each tried arc its end point is judged
_SHORT_LOOKAHEAD = 0.12    # m: the follower's target when the lookahead line would cut a corner
_CORNER_SAMPLES = np.linspace(0.2, 1.0, 5)


@dataclass
class Follow:
    """The path a goal follows and the goal's timers (the navigator's per-goal state)."""

    path: np.ndarray
    cumulative: np.ndarray = None  # type: ignore[assignment]  # arc length at each path point
    points: list[tuple[float, float]] = None  # type: ignore[assignment]
    cumulative_list: list[float] = None  # type: ignore[assignment]
    costs: np.ndarray | None = None   # costmap cost under each path point
    total: float = 0.0
    index: int = 0
    blocked_since: float | None = None
    last_replan: float = -math.inf
    best_remaining: float = math.inf
    best_time: float = 0.0
    last_step: float = 0.0
    aligning: bool = False
    anchor: tuple[float, float] | None = None   # where the robot was when it last moved
    still_since: float = 0.0
    backing_until: float | None = None
    wary_until: float = -math.inf   # after a recovery: the pure-pursuit line keeps clear of unmapped things
    blocked_recoveries: int = 0   # back-ups made for this goal because the way stayed blocked
    unreachable_since: float | None = None   # learned map: no way to the goal since (waiting for one)
    why: tuple[str, int] = ("", 0)
    tight: bool = False   # the path was planned with the body's own footprint (see nav_plan)

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
        self.costs = None   # filled by the navigator from its costmap when first needed


class PathFollower:
    """The pure-pursuit geometry over the navigator's costmap and the latest scan.

    Args:
        costmap: The navigator's costmap.
        spec: The navigation settings (lookahead, heading gain).
        limits: The robot's velocity limits.
        scan_view: The lidar's geometry around the robot.
    """

    def __init__(self, costmap: planner.Costmap, spec: NavigationSpec, limits: LimitsSpec,
                 scan_view: ScanView) -> None:
        self.costmap = costmap
        self.spec = spec
        self.limits = limits
        self.scan_view = scan_view

    def remaining(self, follow: Follow, pose: Pose2D) -> float:
        """Distance along the path from the robot; moves the progress index to the nearest point ahead."""
        points = follow.points
        best, best_i = math.inf, follow.index
        for i in range(follow.index, min(len(points), follow.index + 40)):
            d = math.hypot(points[i][0] - pose.x, points[i][1] - pose.y)
            if d < best:
                best, best_i = d, i
        follow.index = best_i
        return best + follow.total - follow.cumulative_list[best_i]

    def aim(self, pose: Pose2D, target: tuple[float, float], remaining: float) -> tuple[float, float, float]:
        """Heading error to ``target`` and the pure-pursuit command (v, w) to it (v 0: turn in place)."""
        err = wrap_angle(math.atan2(target[1] - pose.y, target[0] - pose.x) - pose.yaw)
        lim = self.limits
        w = max(-lim.max_w, min(lim.max_w, self.spec.heading_gain * err))
        if abs(err) > ROTATE_FIRST:
            return err, 0.0, w
        return err, lim.max_v * max(0.0, math.cos(err)) * min(1.0, 0.3 + remaining / 0.6), w

    def swerve(self, follow: Follow, pose: Pose2D, scan: LaserScan | None) -> tuple[float, float] | None:
        """When the pure-pursuit arc is blocked: the best free arc back towards the path, or None.

        A small sample of arcs (slow speeds, curvatures both ways, as a DWB-style local planner)
        is swept against the scan; those ending on a cell the robot may not enter are dropped;
        the one ending nearest the path point a lookahead ahead wins. None when no arc is free
        (something stands on the path: the caller waits, turns or replans).
        """
        points = follow.points
        far = follow.index
        while far < len(points) - 1 and math.hypot(points[far][0] - pose.x,
                                                   points[far][1] - pose.y) < self.spec.lookahead:
            far += 1
        fx, fy = points[far]
        now_gap = math.hypot(fx - pose.x, fy - pose.y)
        best: tuple[float, float, float] | None = None
        c, s = math.cos(pose.yaw), math.sin(pose.yaw)
        for v in _SWERVE_SPEEDS:
            for k in _SWERVE_CURVATURES:
                w = v * k
                if abs(w) > self.limits.max_w or self.scan_view.obstacle_ahead(scan, v, w) is not None:
                    continue
                d = v * _SWERVE_TIME
                if abs(k) < 1e-6:
                    lx, ly, yaw = d, 0.0, 0.0
                else:
                    yaw = d * k
                    lx, ly = math.sin(yaw) / k, (1.0 - math.cos(yaw)) / k
                ex, ey = pose.x + c * lx - s * ly, pose.y + s * lx + c * ly
                if self.costmap.cost_at(ex, ey) > MAX_FREE:
                    continue
                gap = math.hypot(fx - ex, fy - ey)
                if gap < now_gap - 0.25 * d and (best is None or gap < best[0]):
                    best = (gap, v, w)
        return None if best is None else (best[1], best[2])

    def target(self, follow: Follow, pose: Pose2D, scan: LaserScan | None = None) -> tuple[float, float]:
        """The pure-pursuit point: the farthest path point in the lookahead a straight line reaches safely.

        The line must not come nearer to obstacles than the path itself does there.
        The straight line to a point past a bend cuts the bend's inside; near a door post or a
        corner that is where the costmap's inflation cost rises. A line whose cost exceeds the path's
        own over that stretch (plus a little slack) would clip the post, so a nearer point is
        taken, down to ``_SHORT_LOOKAHEAD`` (in the open the full lookahead stands). What the map
        lacks has no cost there: given ``scan`` (for a while after a recovery), the
        line must also keep the clearance the arc check keeps from it (or, already nearer, come no
        nearer).
        """
        points = follow.points
        start = follow.index
        stop = start
        while stop < len(points) - 1 and math.hypot(points[stop][0] - pose.x,
                                                    points[stop][1] - pose.y) < self.spec.lookahead:
            stop += 1
        here = self.costmap.cost_at(pose.x, pose.y)
        if here > MAX_FREE:
            return points[stop]   # leaving the inscribed zone: the path itself leads out
        if follow.costs is None:
            follow.costs = self.costmap.costs_along(follow.path)
        chosen = list(range(start, stop + 1))
        ends = follow.path[chosen]
        t = _CORNER_SAMPLES[:, None, None]
        line = (1.0 - t) * np.array([pose.x, pose.y]) + t * ends[None, :, :]     # (samples, K, 2)
        line_cost = self.costmap.costs_along(line.reshape(-1, 2))
        line_cost = line_cost.reshape(len(_CORNER_SAMPLES), -1).max(axis=0)
        path_cost = np.maximum.accumulate(follow.costs[start:stop + 1])
        allowed = np.maximum(path_cost, here) + _COST_SLACK
        clear = self.scan_view.lines_clear(scan, pose, ends)
        for k in range(len(chosen) - 1, -1, -1):
            if line_cost[k] <= allowed[k] and line_cost[k] <= MAX_FREE and clear[k]:
                far_enough = math.hypot(ends[k][0] - pose.x, ends[k][1] - pose.y) >= _SHORT_LOOKAHEAD
                if far_enough or k == len(chosen) - 1:
                    return points[chosen[k]]
                break
        for i in range(start, len(points)):   # nothing safe to aim at: keep to the path close by
            px, py = points[i]
            if math.hypot(px - pose.x, py - pose.y) >= _SHORT_LOOKAHEAD:
                return points[i]
        return points[-1]
