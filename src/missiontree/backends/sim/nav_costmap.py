"""The simulated navigator's whole-grid costmap and planning helpers, for world checks and tests.

The navigator itself plans on :class:`missiontree.mapping.planner.Costmap`'s tiles; the world loader
and generator check a world's start, goals and objects against this dense view of the same costmap.
"""

from __future__ import annotations

import numpy as np

from missiontree.backends.sim.schema import NavigationSpec
from missiontree.mapping import planner
from missiontree.mapping.planner import LETHAL
from missiontree.types import OccupancyGrid, Pose2D

__all__ = ["Costmap", "path_length", "plan"]


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
