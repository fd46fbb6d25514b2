"""How much of the place the robot has explored, judged from its own map (no ground truth).

The scene graph only holds what the camera could see, so a mission that builds it reports how much
of the place it saw: the **explored share** is the known free floor the robot can reach over that
floor plus the unknown area still open to it. "Open" unknown is what a frontier bounds: unknown
cells that touch the reachable free floor (a frontier), and the unknown connected to them inside
the extent of the map known so far (the box around every known cell). Unknown behind a known wall
touches no frontier and does not count; an unknown patch smaller than ``min_open`` (a speck the
lidar missed under furniture) cannot hide a room and does not count either.

A map explored to its end reads about 1.0; a room whose doorway was never passed leaves the
unknown behind that doorway open, and the share says how much of the mapped extent it is.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from missiontree.mapping.grid import free_mask, occupied_mask
from missiontree.types import OccupancyGrid

#: Unknown patches smaller than this (m^2) are specks, not unexplored space.
MIN_OPEN = 0.25
#: How far (m) the robot's position may be from a free cell and still pick that cell's floor.
SNAP = 0.5


@dataclass(frozen=True)
class Coverage:
    """The explored share and its parts.

    Attributes:
        known_m2: Free floor the robot can reach (its component of the free cells), m^2.
        open_m2: Unknown area bounded by frontiers of that floor, inside the known map's extent, m^2.
        frontiers: Open unknown patches (each behind one or more frontier cells).
        share: ``known / (known + open)``; 1.0 when nothing is open, 0.0 for an empty map.
    """

    known_m2: float
    open_m2: float
    frontiers: int
    share: float

    def to_dict(self) -> dict[str, float | int]:
        """Plain data for events and files (areas to 0.1 m^2, the share to 0.001)."""
        return {
            "explored_share": round(self.share, 3),
            "known_free_m2": round(self.known_m2, 1),
            "unexplored_m2": round(self.open_m2, 1),
            "open_frontiers": self.frontiers,
        }


def explored_share(
    grid: OccupancyGrid, position: tuple[float, float] | None, min_open: float = MIN_OPEN
) -> Coverage:
    """The explored share of ``grid`` for a robot at ``position`` (None: every free cell counts).

    Args:
        grid: The robot's occupancy map (learned or given).
        position: Where the robot is; its free component is the reachable floor.
        min_open: Unknown patches smaller than this (m^2) are not counted as open.
    """
    free = free_mask(grid)
    known = free | occupied_mask(grid)
    cell_area = grid.resolution**2
    if not free.any():
        return Coverage(0.0, 0.0, 0, 0.0)
    eight = np.ones((3, 3), bool)
    labels, _ = ndimage.label(free, structure=eight)
    floor = free
    if position is not None:
        label = _label_near(grid, labels, position)
        if label:
            floor = labels == label
    rows, cols = np.nonzero(known)
    box = (slice(rows.min(), rows.max() + 1), slice(cols.min(), cols.max() + 1))
    unknown = ~known[box]
    touching = ndimage.binary_dilation(floor[box]) & unknown  # frontier cells (4-neighbours of the floor)
    parts, count = ndimage.label(unknown)
    open_ids = np.unique(parts[touching])
    open_ids = open_ids[open_ids > 0]
    sizes = ndimage.sum_labels(np.ones_like(parts), parts, open_ids) * cell_area if count else np.zeros(0)
    kept = sizes >= min_open
    open_m2 = float(np.sum(sizes[kept]))
    known_m2 = float(np.count_nonzero(floor)) * cell_area
    share = known_m2 / (known_m2 + open_m2) if known_m2 + open_m2 > 0 else 0.0
    return Coverage(known_m2, open_m2, int(np.count_nonzero(kept)), share)


def _label_near(grid: OccupancyGrid, labels: np.ndarray, position: tuple[float, float]) -> int:
    """The free component at ``position``, or of the nearest free cell within ``SNAP``; 0 when none."""
    row, col = grid.world_to_cell(*position)
    reach = int(np.ceil(SNAP / grid.resolution))
    r0, r1 = max(row - reach, 0), min(row + reach + 1, labels.shape[0])
    c0, c1 = max(col - reach, 0), min(col + reach + 1, labels.shape[1])
    if r0 >= r1 or c0 >= c1:
        return 0
    window = labels[r0:r1, c0:c1]
    rr, cc = np.nonzero(window)
    if not len(rr):
        return 0
    d = (rr + r0 - row) ** 2 + (cc + c0 - col) ** 2
    best = int(np.argmin(d))
    if d[best] > reach * reach:
        return 0
    return int(window[rr[best], cc[best]])
