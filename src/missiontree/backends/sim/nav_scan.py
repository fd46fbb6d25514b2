"""What the lidar shows around the simulated robot, read for its path follower.

The navigator's controller asks the latest scan four questions: which points lie on the map's own
obstacles (a wall the plan already keeps clear of needs only a small side margin, a person may step
closer), what the footprint would sweep on the arc a command drives within stopping reach (a
controller's collision check), whether straight lines to candidate aim points keep clear of what the
map lacks, and how far the robot can reverse. :class:`ScanView` answers them, caching the scan's end
points per scan, so the follower (:mod:`missiontree.backends.sim.navigation`) holds the decisions
and this module the geometry.
"""

from __future__ import annotations

import math

import numpy as np

from missiontree.backends.sim.schema import NavigationSpec
from missiontree.mapping import planner
from missiontree.mapping.planner import INSCRIBED
from missiontree.types import LaserScan, Pose2D

STOP_TIME = 0.5          # s of travel at the commanded speed kept clear ahead (stopping distance)
CREEP_SPEED = 0.05        # m/s: the slowest approach the speed regulation allows
SIDE_MARGIN = 0.03        # m beside the footprint the swept arc keeps clear of mapped obstacles
UNMAPPED_MARGIN = 0.12    # m it keeps clear of what the map does not hold (people reach past their legs)
CLOSER_SLACK = 0.01       # m a line may come nearer to what the robot is already too close to


class ScanView:
    """The latest scan's geometry around the robot (see the module docstring).

    Args:
        costmap: The navigator's costmap (which scan points lie on mapped obstacles).
        spec: The navigation settings (lookahead, obstacle margin).
        radius: The footprint radius (m).
    """

    def __init__(self, costmap: planner.Costmap, spec: NavigationSpec, radius: float) -> None:
        self.costmap = costmap
        self.spec = spec
        self.radius = radius
        #: The pose the scan being read was taken at (the navigator sets it at each step).
        self.pose = Pose2D(0.0, 0.0, 0.0)
        self._xy_cache: tuple[LaserScan, np.ndarray, np.ndarray] | None = None
        self._trig: tuple[tuple[float, float, int, float], np.ndarray, np.ndarray] | None = None
        self._mapped_cache: tuple[LaserScan, np.ndarray] | None = None

    def xy(self, scan: LaserScan) -> tuple[np.ndarray, np.ndarray]:
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

    def mapped(self, scan: LaserScan) -> np.ndarray:
        """Per scan point: whether it lies on the map's own obstacles (not on something the map lacks)."""
        if self._mapped_cache is None or self._mapped_cache[0] is not scan:
            x, y = self.xy(scan)
            pose = self.pose
            c, s = math.cos(pose.yaw), math.sin(pose.yaw)
            world = np.stack([pose.x + c * x - s * y, pose.y + s * x + c * y], axis=1)
            self._mapped_cache = (scan, self.costmap.costs_along(world) >= INSCRIBED)
        return self._mapped_cache[1]

    @staticmethod
    def world_points(scan: LaserScan | None, pose: Pose2D, max_range: float = 3.0) -> np.ndarray:
        """The scan's returns within ``max_range`` in the map frame, (N, 2), seen from ``pose``."""
        if scan is None:
            return np.zeros((0, 2))
        r = np.asarray(scan.ranges, float)
        ang = scan.angles()
        ok = np.isfinite(r) & (r < max_range)
        x, y = r[ok] * np.cos(ang[ok]), r[ok] * np.sin(ang[ok])
        c, s = math.cos(pose.yaw), math.sin(pose.yaw)
        return np.stack([pose.x + c * x - s * y, pose.y + s * x + c * y], axis=1)

    def rear_room(self, scan: LaserScan | None) -> float:
        """How far the robot can reverse straight before its footprint (and side margin) meets a scan point.

        Infinite without a scan (nothing known behind).
        """
        if scan is None:
            return math.inf
        x, y = self.xy(scan)
        side = self.radius + SIDE_MARGIN
        behind = (x < 0.0) & (np.abs(y) < side)
        if not behind.any():
            return math.inf
        room = -x[behind] - np.sqrt(side * side - y[behind] ** 2)
        return max(0.0, float(room.min()))

    def obstacle_ahead(self, scan: LaserScan | None, v: float,
                       w: float = 0.0) -> tuple[float, float, float] | None:
        """The first scan point the footprint would sweep on the arc ``(v, w)`` within stopping reach.

        The footprint (radius plus a small side margin) is swept along the circular arc the command
        drives (a straight corridor when ``w`` is about 0), as a controller's collision check
        projects its command forward; a point counts when the arc reaches its side within the
        stopping distance ``radius + obstacle_margin + v * 0.5 s``. Returns (arc length to it, x, y)
        in the robot frame, or None.
        """
        if scan is None:
            return None
        x, y = self.xy(scan)
        reach = self.radius + self.spec.obstacle_margin + max(v, CREEP_SPEED) * STOP_TIME
        box = reach + self.radius + UNMAPPED_MARGIN
        near = (np.abs(x) < box) & (np.abs(y) < box)
        if not near.any():
            return None
        x, y = x[near], y[near]
        side = self.radius + np.where(self.mapped(scan)[near], SIDE_MARGIN, UNMAPPED_MARGIN)
        k = w / v if v > 1e-3 else 0.0
        mirrored = k < 0.0
        if abs(k) < 1e-3:
            lateral, along = np.abs(y), x
        else:
            if mirrored:
                y, k = -y, -k   # mirror a right turn into a left one
            r = 1.0 / k
            lateral = np.abs(np.hypot(x, y - r) - r)
            along = np.mod(np.arctan2(x, r - y), 2.0 * math.pi) * r
        hit = (along > 0.0) & (along < reach) & (lateral < side)
        if not hit.any():
            return None
        i = int(np.argmin(np.where(hit, along, np.inf)))
        return float(along[i]), float(x[i]), float(-y[i] if mirrored and abs(k) >= 1e-3 else y[i])

    def lines_clear(self, scan: LaserScan | None, pose: Pose2D, ends: np.ndarray) -> np.ndarray:
        """Per end point (K, 2): whether the straight line to it keeps clear of what the map lacks.

        Clear means the arc check's clearance (radius plus ``UNMAPPED_MARGIN``) from every scan point
        off the map, or for a point already nearer, no nearer than now (less ``CLOSER_SLACK``) and
        never within the side margin (a line out of there is not ruled out before the arc check).
        """
        if scan is None:
            return np.ones(len(ends), bool)
        x, y = self.xy(scan)
        reach = self.spec.lookahead + self.radius + UNMAPPED_MARGIN
        near = (np.abs(x) < reach) & (np.abs(y) < reach) & ~self.mapped(scan)
        if not near.any():
            return np.ones(len(ends), bool)
        c, s = math.cos(pose.yaw), math.sin(pose.yaw)
        qx, qy = pose.x + c * x[near] - s * y[near], pose.y + s * x[near] + c * y[near]
        kept = self.radius + UNMAPPED_MARGIN
        now_gap = np.hypot(x[near], y[near])
        need = np.where(now_gap < kept, np.maximum(self.radius + SIDE_MARGIN, now_gap - CLOSER_SLACK), kept)
        dx, dy = ends[:, 0] - pose.x, ends[:, 1] - pose.y                       # (K,)
        length2 = np.maximum(dx * dx + dy * dy, 1e-12)
        t = ((qx[None, :] - pose.x) * dx[:, None] + (qy[None, :] - pose.y) * dy[:, None]) / length2[:, None]
        t = np.clip(t, 0.0, 1.0)                                                # (K, N)
        gap = np.hypot(pose.x + t * dx[:, None] - qx[None, :], pose.y + t * dy[:, None] - qy[None, :])
        return (gap >= need[None, :]).all(axis=1)
