"""The simulated navigator's whole-grid costmap and planning helpers, for world checks and tests.

The navigator itself plans on :class:`missiontree.mapping.planner.Costmap`'s tiles; the world loader
and generator check a world's start, goals and objects against this dense view of the same costmap.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from missiontree.backends.sim.schema import NavigationSpec
from missiontree.mapping import planner
from missiontree.mapping.planner import LETHAL, MAX_FREE
from missiontree.types import OccupancyGrid, Pose2D

__all__ = ["Costmap", "free_goal_within", "path_length", "plan", "way_out"]


class Costmap:
    """The whole-grid view of a map's costmap (for world checks and tests; planning uses the tiles).

    Args:
        grid: The map.
        robot_radius: Footprint radius (m).
        spec: Inflation settings.
    """

    def __init__(self, grid: OccupancyGrid, robot_radius: float, spec: NavigationSpec,
                 allow_unknown: bool = False) -> None:
        self.grid = grid
        self.radius = robot_radius
        self.spec = spec
        self.tiled = planner.Costmap(grid, robot_radius, spec.inflation_radius, spec.cost_scaling,
                                     allow_unknown)
        self._dense: np.ndarray | None = None

    @property
    def cost(self) -> np.ndarray:
        """The whole cost array (0 free .. 252 inflated, 253 inscribed, 254 lethal), computed once."""
        if self._dense is None:
            self._dense = self.tiled.dense()
        return self._dense

    def cell_cost(self, cost: np.ndarray, x: float, y: float) -> int:
        """Cost at a map point; LETHAL outside the map."""
        row, col = self.grid.world_to_cell(x, y)
        if not (0 <= row < cost.shape[0] and 0 <= col < cost.shape[1]):
            return LETHAL
        return int(cost[row, col])


def plan(costmap: Costmap, cost: np.ndarray, start: Pose2D, goal: Pose2D, accelerate: bool = True,
         cost_weight: float = 3.0) -> np.ndarray | None:
    """A path of map points (N, 2) from ``start`` to ``goal`` on ``costmap``, or None when there is none.

    ``cost`` is accepted for the old signature; the plan runs on the costmap's tiles.
    """
    del cost
    costmap.tiled.accelerate = accelerate and planner.HAVE_NUMBA
    path = costmap.tiled.plan(start, goal, cost_weight)
    return None if path is None else path.points


def path_length(points: np.ndarray) -> float:
    """Length of a polyline."""
    if len(points) < 2:
        return 0.0
    return float(np.hypot(*np.diff(points, axis=0).T).sum())


def free_goal_within(costmap: planner.Costmap, goal: Pose2D, reach: float) -> Pose2D | None:
    """The goal if the robot may stand there, else the nearest point within ``reach`` m where it may; or None.

    As NavFn's ``tolerance``: on a learned map a wall seen late often puts a goal (an exploration
    goal chosen when that wall was still unknown) inside the robot's inscribed zone; the goal counts
    as reached anywhere within its tolerance, so a free cell inside it serves as well, where the
    navigator would otherwise refuse the goal that the exploration planner still sees a way to.
    """
    if costmap.cost_at(goal.x, goal.y) <= MAX_FREE:
        return goal
    res = costmap.grid.resolution
    k = int(math.floor(reach / res))
    if k < 1:
        return None
    row, col = costmap.grid.world_to_cell(goal.x, goal.y)
    dr, dc = np.mgrid[-k:k + 1, -k:k + 1]
    d2 = (dr * dr + dc * dc).ravel()
    for j in np.argsort(d2, kind="stable").tolist():
        if d2[j] > k * k:
            break
        r, c = row + int(dr.ravel()[j]), col + int(dc.ravel()[j])
        if costmap.cell_cost(r, c) > MAX_FREE:
            continue
        x, y = costmap.grid.cell_to_world(r, c)
        if math.hypot(x - goal.x, y - goal.y) <= reach:
            return Pose2D(x, y, goal.yaw)
    return None


def way_out(costmap: planner.Costmap, start: Pose2D, reach: float, clearance: float) -> Pose2D | None:
    """The nearest free point within ``reach`` m that the body reaches in a straight line; or None.

    A robot standing deep in an obstacle's inscribed zone (a niche or a gap narrower than the padded
    footprint, where a late-seen wall put it) has no plan: the planner lets a start leave the zone
    only within its radius (plus 0.1 m). Planning from this point instead, with the straight line to
    it in front, is the way out, as Nav2 plans again once a recovery has moved the robot clear. The
    line keeps ``clearance`` (the body's radius and the follower's side margin) from every lethal cell,
    so the follower can drive it: the nearest free cell itself often lies round a corner.
    """
    res = costmap.grid.resolution
    k = int(math.floor(reach / res))
    if k < 1:
        return None
    pad = int(math.ceil(clearance / res)) + 1
    row, col = costmap.grid.world_to_cell(start.x, start.y)
    n = k + pad
    rr, cc = np.mgrid[row - n:row + n + 1, col - n:col + n + 1]
    centres = np.stack([costmap.grid.origin.x + (cc.ravel() + 0.5) * res,
                        costmap.grid.origin.y + (rr.ravel() + 0.5) * res], axis=1)
    cost = costmap.costs_along(centres).reshape(rr.shape)
    room = cv2.distanceTransform((cost < LETHAL).astype(np.uint8), cv2.DIST_L2, 5) * res
    dr, dc = np.mgrid[-k:k + 1, -k:k + 1]
    dr, dc = dr.ravel(), dc.ravel()
    d2 = dr * dr + dc * dc
    for j in np.argsort(d2, kind="stable").tolist():
        if d2[j] > k * k:
            break
        r, c = n + int(dr[j]), n + int(dc[j])
        if cost[r, c] > MAX_FREE:
            continue
        steps = max(2, int(math.ceil(math.sqrt(float(d2[j])) * 2.0)) + 1)
        t = np.linspace(0.0, 1.0, steps)
        lr = np.rint(n + t * (r - n)).astype(int)
        lc = np.rint(n + t * (c - n)).astype(int)
        if (room[lr[1:], lc[1:]] >= clearance).all():   # the start cell itself may be tight
            return Pose2D(float(centres[r * rr.shape[1] + c, 0]), float(centres[r * rr.shape[1] + c, 1]),
                          start.yaw)
    return None
