"""The scene-graph benchmark's route comes near every wall and piece of furniture (surface_viewpoints)."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import cv2
import numpy as np

from missiontree.types import OccupancyGrid, Pose2D

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
import scene_eval_route as scene_graph_eval  # noqa: E402


def _corridor() -> OccupancyGrid:
    """A 2 x 12 m room walled all round, 5 cm cells."""
    data = np.full((60, 260), 100, dtype=np.int8)
    data[10:50, 10:250] = 0
    return OccupancyGrid(0.0, 0.05, Pose2D(0.0, 0.0), data)


def test_the_route_gets_near_every_wall_of_a_long_room() -> None:
    """From one viewpoint at a long room's end, viewpoints are added until every wall cell is in reach."""
    grid = _corridor()
    free = grid.data == 0
    clearance = cv2.distanceTransform(free.astype(np.uint8), cv2.DIST_L2, 5) * grid.resolution
    start = [(1.5, 1.5)]
    added = scene_graph_eval.surface_viewpoints(grid, free, clearance, start)
    points = start + added
    assert len(added) >= 3
    for x, y in added:
        row, col = grid.world_to_cell(x, y)
        assert free[row, col] and clearance[row, col] >= 0.45  # room to turn
    rows, cols = np.nonzero(free & (clearance <= scene_graph_eval.SURFACE_BAND))
    far = 0
    for row, col in zip(rows[::11], cols[::11], strict=True):
        x, y = grid.cell_to_world(int(row), int(col))
        if min(math.hypot(x - a, y - b) for a, b in points) > scene_graph_eval.SURFACE_RADIUS:
            far += 1
    assert far <= 0.05 * len(rows[::11])
