"""How exploration measures path lengths to its goals, and the part of the map it works on.

- :class:`KeptCostmapLengths`: path lengths on an inflated costmap kept between calls (the default);
- :func:`planner_path_lengths`, :func:`straight_line_lengths`: one-shot and straight-line stand-ins;
- :func:`known_window`: the box of a map's known cells with a margin (the planner's working area).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np

from missiontree.mapping.planner import Costmap
from missiontree.types import OccupancyGrid, Pose2D

#: path_lengths(grid, start xy, goals xy, footprint_radius) -> metres or None per goal
PathLengths = Callable[[OccupancyGrid, tuple[float, float], Sequence[tuple[float, float]], float],
                       list[float | None]]


def planner_path_lengths(grid: OccupancyGrid, start: tuple[float, float],
                         goals: Sequence[tuple[float, float]], footprint_radius: float) -> list[float | None]:
    """Path lengths on the inflated costmap (mapping.planner); straight lines if it is not installed."""
    try:
        from missiontree.mapping.planner import path_lengths
    except ImportError:  # pragma: no cover - the planner ships with the package
        return straight_line_lengths(grid, start, goals, footprint_radius)
    return path_lengths(grid, start, list(goals), footprint_radius=footprint_radius, allow_unknown=True)


class KeptCostmapLengths:
    """Path lengths on an inflated costmap kept between calls (one per exploration planner).

    Each call takes the grid it is given as a new version of the map: only the costmap tiles near
    cells that changed are computed again (:meth:`Costmap.update_changed`), where a new costmap
    per call recomputed every tile the search reached -- the whole floor of a large map, every
    replan.
    """

    def __init__(self) -> None:
        self.costmaps: dict[float, Costmap] = {}   # one per footprint radius asked for

    def __call__(self, grid: OccupancyGrid, start: tuple[float, float],
                 goals: Sequence[tuple[float, float]], footprint_radius: float) -> list[float | None]:
        """Length (m) of the best path from ``start`` to each goal; None where unreachable (unknown: free)."""
        costmap = self.costmaps.get(footprint_radius)
        if costmap is None:
            costmap = self.costmaps[footprint_radius] = Costmap(grid, footprint_radius, allow_unknown=True)
        else:
            costmap.update_changed(grid)
        return costmap.path_lengths(start, list(goals))


def straight_line_lengths(grid: OccupancyGrid, start: tuple[float, float],
                          goals: Sequence[tuple[float, float]],
                          footprint_radius: float) -> list[float | None]:
    """Euclidean distances (every goal counts as reachable)."""
    return [math.hypot(g[0] - start[0], g[1] - start[1]) for g in goals]


def known_window(grid: OccupancyGrid, margin_m: float, step_m: float) -> OccupancyGrid:
    """``grid`` cut to the box of its known cells padded by ``margin_m``, edges snapped out to ``step_m``.

    The cut keeps the grid's cells (its origin moves by whole cells); the whole grid when nothing
    is known or the box reaches every border.
    """
    known = grid.data >= 0
    rows, cols = np.flatnonzero(known.any(axis=1)), np.flatnonzero(known.any(axis=0))
    if not len(rows):
        return grid
    res = grid.resolution
    h, w = grid.data.shape
    m = int(math.ceil(margin_m / res))
    step = max(1, int(math.ceil(step_m / res)))
    r0 = max(0, (int(rows[0]) - m) // step * step)
    c0 = max(0, (int(cols[0]) - m) // step * step)
    r1 = min(h, -(-(int(rows[-1]) + 1 + m) // step) * step)
    c1 = min(w, -(-(int(cols[-1]) + 1 + m) // step) * step)
    if (r0, c0, r1, c1) == (0, 0, h, w):
        return grid
    origin = Pose2D(grid.origin.x + c0 * res, grid.origin.y + r0 * res, grid.origin.yaw)
    return OccupancyGrid(grid.stamp, res, origin, grid.data[r0:r1, c0:c1])
