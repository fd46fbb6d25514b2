"""Scan points: where to stop and look around, as the vision-language object-search report picks them.

The report's scan point generator takes the occupancy grid, makes a binary free-space mask,
erodes it (so points keep away from walls and narrow gaps split the space into rooms), labels
the connected components, and offers the centroids of the largest components, ranked by region
size, as exploration waypoints in map coordinates (through the grid's resolution and origin).

One refinement: the centroid of a non-convex region (an L-shaped room, a ring around an island)
can fall outside the region, even inside a wall. Such a centroid is moved to the nearest cell
of its region, so every scan point is a free cell the robot can stand on.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from missiontree.mapping.grid import free_mask
from missiontree.types import OccupancyGrid

_SQUARE = ndimage.generate_binary_structure(2, 2)


@dataclass(frozen=True)
class ScanPoint:
    """A place to scan from: a free cell in the middle of a large free region.

    Attributes:
        x: Map x (m).
        y: Map y (m).
        area_m2: Area of the (eroded) region it stands for.
        cells: Number of cells of that region.
    """

    x: float
    y: float
    area_m2: float
    cells: int


def disk(radius_cells: int) -> np.ndarray:
    """A filled disk structuring element of the given radius in cells."""
    r = max(0, int(radius_cells))
    yy, xx = np.mgrid[-r:r + 1, -r:r + 1]
    return (xx * xx + yy * yy) <= r * r


def eroded_free(grid: OccupancyGrid, erosion_m: float) -> np.ndarray:
    """The free-space mask eroded by a disk of ``erosion_m`` (unknown and occupied both bound it)."""
    free = free_mask(grid)
    radius = int(round(erosion_m / grid.resolution))
    if radius <= 0:
        return free
    return ndimage.binary_erosion(free, structure=disk(radius), border_value=0)


def scan_points(grid: OccupancyGrid, erosion_m: float = 0.4, min_area_m2: float = 0.25,
                max_points: int | None = None) -> list[ScanPoint]:
    """The report's scan points of ``grid``, largest region first.

    Args:
        grid: The map (-1 unknown, 0 free ... 100 occupied).
        erosion_m: Radius of the erosion (m): at least the robot's radius; larger values cut
            rooms apart at their doors.
        min_area_m2: Regions smaller than this (after erosion) give no point.
        max_points: Keep only this many (None: all).

    Returns:
        Scan points sorted by region size, largest first.
    """
    if erosion_m < 0:
        raise ValueError(f"erosion_m must be >= 0, found {erosion_m}")
    mask = eroded_free(grid, erosion_m)
    labels, count = ndimage.label(mask, structure=_SQUARE)
    if count == 0:
        return []
    ids = np.arange(1, count + 1)
    sizes = ndimage.sum_labels(mask, labels, ids).astype(np.int64)
    centres = ndimage.center_of_mass(mask, labels, ids)
    res, ox, oy = grid.resolution, grid.origin.x, grid.origin.y
    min_cells = min_area_m2 / (res * res)
    points: list[ScanPoint] = []
    for label, size, (r, c) in zip(ids, sizes, centres, strict=True):
        if size < min_cells:
            continue
        row, col = int(np.floor(r + 0.5)), int(np.floor(c + 0.5))  # the cell whose centre is nearest
        if not (0 <= row < labels.shape[0] and 0 <= col < labels.shape[1]) or labels[row, col] != label:
            rr, cc = np.nonzero(labels == label)
            k = int(np.argmin((rr - r) ** 2 + (cc - c) ** 2))
            row, col = int(rr[k]), int(cc[k])
            x, y = ox + (col + 0.5) * res, oy + (row + 0.5) * res
        else:
            x, y = ox + (c + 0.5) * res, oy + (r + 0.5) * res
        points.append(ScanPoint(float(x), float(y), float(size * res * res), int(size)))
    points.sort(key=lambda p: (-p.cells, p.x, p.y))
    return points[:max_points] if max_points is not None else points
