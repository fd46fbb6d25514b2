"""The simulated navigator's global planning: the costmaps it plans on and how a plan is chosen.

A* runs on :class:`missiontree.mapping.planner.Costmap` (inflated, tiled, updated where the map
changes). On a learned map the footprint is padded by two cells (a learned map's edges are a cell off
the truth), which closes gaps the robot's body fits through (0.44-0.54 m at 5 cm, for a 0.34 m
body), and a doorway at that width flickers open and closed as its jambs are scanned again: the
robot turned back for a way round the house, then back again, until the exploration gave the goal
up ("no progress"). So where the padded plan finds no way or only a detour (much longer than the
straight line), a second costmap with the footprint padded by one cell is asked too, and its plan
is taken when it is much shorter; the follower's scan check keeps the body clear meanwhile, as a
local controller does. A robot standing deep inside an obstacle's inscribed zone plans from the
nearest way out (:func:`~missiontree.backends.sim.nav_costmap.way_out`).
"""

from __future__ import annotations

import math
import time

import numpy as np

from missiontree.backends.sim.nav_costmap import path_length, way_out
from missiontree.backends.sim.nav_scan import SIDE_MARGIN, UNMAPPED_MARGIN, ScanView
from missiontree.backends.sim.schema import NavigationSpec
from missiontree.backends.sim.timing import TimingLog
from missiontree.mapping import planner
from missiontree.mapping.planner import INSCRIBED
from missiontree.types import LaserScan, OccupancyGrid, Pose2D

__all__ = ["NavPlanner"]

_WAY_OUT_REACH = 1.0      # m: a start deep in an obstacle's zone plans from a free point this near
_DETOUR_RATIO, _DETOUR_SLACK = 1.5, 2.0   # a path longer than ratio x (a shorter one) + slack (m) is a detour


class NavPlanner:
    """Plans for the navigator on its costmap (and, on a learned map, on a tighter one).

    Args:
        grid: The map planned on.
        radius: The body's footprint radius (m).
        spec: Inflation settings.
        allow_unknown: A learned map (unknown cells traversable; the footprint padded).
        accelerate: Use the compiled search.
    """

    def __init__(self, grid: OccupancyGrid, radius: float, spec: NavigationSpec, allow_unknown: bool,
                 accelerate: bool) -> None:
        self.body_radius = radius
        padded = radius + (2.0 * grid.resolution if allow_unknown else 0.0)
        self.costmap = planner.Costmap(grid, padded, spec.inflation_radius, spec.cost_scaling, allow_unknown,
                                       accelerate)
        self.tight: planner.Costmap | None = None
        if allow_unknown:
            self.tight = planner.Costmap(grid, radius + grid.resolution, spec.inflation_radius,
                                         spec.cost_scaling, allow_unknown, accelerate)
        self.plan_ms = TimingLog()
        self.escapes = 0   # plans made by way of a point out of an obstacle's zone
        self.tight_plans = 0   # plans taken from the tighter costmap

    def update(self, grid: OccupancyGrid, region: tuple[int, int, int, int] | None) -> None:
        """Take a new version of the map (``region``: the rows/cols that changed)."""
        self.costmap.update(grid, region)
        if self.tight is not None:
            self.tight.update(grid, region)

    def add_lethal(self, points: np.ndarray) -> None:
        """Make discs at ``points`` lethal on every costmap (bumper hits)."""
        self.costmap.add_lethal(points)
        if self.tight is not None:
            self.tight.add_lethal(points)

    def set_lethal(self, points: np.ndarray) -> None:
        """Replace the extra lethal points on every costmap."""
        self.costmap.set_lethal(points)
        if self.tight is not None:
            self.tight.set_lethal(points)

    def costmap_for(self, tight: bool) -> planner.Costmap:
        """The costmap a path was planned on (``tight``: the tighter one, where there is one)."""
        return self.tight if tight and self.tight is not None else self.costmap

    def way(self, pose: Pose2D, goal: Pose2D) -> tuple[np.ndarray | None, bool]:
        """A path from ``pose`` to ``goal`` and whether it is the tighter costmap's (see the module)."""
        path = self.plan(self.costmap, pose, goal)
        if self.tight is None:
            return path, False
        straight = math.hypot(goal.x - pose.x, goal.y - pose.y)
        if path is not None and path_length(path) <= _DETOUR_RATIO * straight + _DETOUR_SLACK:
            return path, False
        tight = self.plan(self.tight, pose, goal)
        if tight is None or (path is not None
                             and path_length(path) <= _DETOUR_RATIO * path_length(tight) + _DETOUR_SLACK):
            return path, False
        self.tight_plans += 1
        return tight, True

    def around(self, scan: LaserScan | None, pose: Pose2D, goal: Pose2D, tight: bool) -> np.ndarray | None:
        """A plan that keeps as clear of what the lidar sees now as the follower will.

        The follower keeps ``UNMAPPED_MARGIN`` beside its radius from what the map does not hold;
        a plan passing closer (the planner's default discs are smaller) is blocked again at once.
        """
        seen = ScanView.world_points(scan, pose)
        costmap = self.costmap_for(tight)
        return self.plan(costmap.with_points(seen, radius=UNMAPPED_MARGIN + SIDE_MARGIN), pose, goal)

    def plan(self, costmap: planner.Costmap, pose: Pose2D, goal: Pose2D) -> np.ndarray | None:
        """A* from the robot to ``goal``; from deep in an obstacle's zone, by way of the nearest way out.

        The planner lets a start leave the inscribed zone only close by; a robot standing deeper in
        it (a niche or gap narrower than the padded footprint) had no plan, waited and aborted goal
        after goal. The way out (:func:`way_out`) is planned from, the line to it put in front.
        """
        t0 = time.perf_counter()
        path = costmap.plan(pose, goal)
        points = None if path is None else path.points
        if points is None and costmap.cost_at(pose.x, pose.y) >= INSCRIBED:
            out = way_out(costmap, pose, _WAY_OUT_REACH, self.body_radius + SIDE_MARGIN)
            rest = None if out is None else costmap.plan(out, goal)
            if rest is not None:
                points = np.vstack([[[pose.x, pose.y]], rest.points])
                self.escapes += 1
        self.plan_ms.append((time.perf_counter() - t0) * 1000.0)
        return points
