"""Frontiers: the edges between known free space and the unknown, where exploring pays.

A *frontier cell* is a free cell with an unknown cell among its four neighbours (cells beyond
the grid's border count as unknown: a map that is still growing has more to see there). Frontier
cells that touch each other (eight-connected) form one :class:`Frontier`, described as
explore_lite describes it: its cells, its size in cells and its centroid, plus the frontier
cell nearest that centroid (``goal``) -- the centroid of a curved frontier can lie in unknown
or occupied space, while ``goal`` is always a free cell on the frontier.

Long frontiers (a whole unexplored corridor side) can be split into pieces of at most
``max_size_cells`` so that a goal is never far from the part of the frontier it stands for.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
from scipy import ndimage

from missiontree.mapping.grid import free_mask, occupied_mask, unknown_mask
from missiontree.types import OccupancyGrid

_CROSS = ndimage.generate_binary_structure(2, 1)
_SQUARE = ndimage.generate_binary_structure(2, 2)


@dataclass(frozen=True)
class Frontier:
    """One cluster of frontier cells.

    Attributes:
        cells: (N, 2) int array of (row, col) of its cells.
        size: Number of cells (N).
        centroid: Mean position (x, y) of its cells in the map frame.
        goal: Position (x, y) of the frontier cell nearest the centroid (a free cell).
    """

    cells: np.ndarray
    size: int
    centroid: tuple[float, float]
    goal: tuple[float, float]

    def length_m(self, resolution: float) -> float:
        """Rough length of the frontier in metres (cells times cell size)."""
        return self.size * resolution

    def distance_to(self, x: float, y: float) -> float:
        """Distance (m) from (x, y) to the frontier's goal point."""
        return float(np.hypot(self.goal[0] - x, self.goal[1] - y))


def frontier_mask(grid: OccupancyGrid, min_unknown_cells: int = 1) -> np.ndarray:
    """Bool mask of the frontier cells: free cells with an unknown four-neighbour (or at the border).

    Unknown patches of fewer than ``min_unknown_cells`` cells that do not touch the border (specks
    between far-apart beams, inside space already seen all around) are not counted as unknown.
    """
    unknown = np.pad(unknown_mask(grid), 1, constant_values=True)
    if min_unknown_cells > 1:
        labels, count = ndimage.label(unknown, structure=_SQUARE)
        sizes = np.bincount(labels.ravel(), minlength=count + 1)
        keep = sizes >= min_unknown_cells
        keep[0] = False
        keep[labels[0, 0]] = True  # the padding ring: everything beyond the border
        unknown = keep[labels]
    near_unknown = ndimage.binary_dilation(unknown, structure=_CROSS)[1:-1, 1:-1]
    return free_mask(grid) & near_unknown


def find_frontiers(grid: OccupancyGrid, min_size_cells: int = 5, max_size_cells: int | None = None,
                   min_unknown_cells: int = 1) -> list[Frontier]:
    """The frontiers of ``grid``, largest first.

    Args:
        grid: The map (trinary or scaled values; -1 unknown).
        min_size_cells: Clusters with fewer cells are dropped (noise, gaps between wall cells).
        max_size_cells: Split clusters longer than this into pieces along their main axis
            (None: never split).
        min_unknown_cells: Enclosed unknown patches smaller than this are no frontier's cause
            (see :func:`frontier_mask`).

    Returns:
        The frontiers, sorted by size (largest first), ties by position.
    """
    if min_size_cells < 1:
        raise ValueError(f"min_size_cells must be >= 1, found {min_size_cells}")
    if max_size_cells is not None and max_size_cells < min_size_cells:
        raise ValueError(f"max_size_cells ({max_size_cells}) must be >= min_size_cells ({min_size_cells})")
    mask = frontier_mask(grid, min_unknown_cells)
    labels, count = ndimage.label(mask, structure=_SQUARE)
    if count == 0:
        return []
    rows, cols = np.nonzero(labels)
    ids = labels[rows, cols]
    order = np.argsort(ids, kind="stable")
    rows, cols, ids = rows[order], cols[order], ids[order]
    bounds = np.searchsorted(ids, np.arange(1, count + 2))
    frontiers: list[Frontier] = []
    for k in range(count):
        cells = np.stack([rows[bounds[k]:bounds[k + 1]], cols[bounds[k]:bounds[k + 1]]], axis=1)
        for piece in _split(cells, max_size_cells):
            if len(piece) >= min_size_cells:
                frontiers.append(_make(piece, grid))
    frontiers.sort(key=lambda f: (-f.size, f.centroid))
    return frontiers


def _split(cells: np.ndarray, max_size: int | None) -> list[np.ndarray]:
    """Cut a cluster into consecutive pieces of at most ``max_size`` cells along its main axis."""
    if max_size is None or len(cells) <= max_size:
        return [cells]
    pts = cells.astype(np.float64)
    centred = pts - pts.mean(axis=0)
    _, _, vt = np.linalg.svd(centred, full_matrices=False)
    along = centred @ vt[0]
    order = np.argsort(along, kind="stable")
    pieces = int(np.ceil(len(cells) / max_size))
    return [cells[chunk] for chunk in np.array_split(order, pieces)]


def _make(cells: np.ndarray, grid: OccupancyGrid) -> Frontier:
    res, ox, oy = grid.resolution, grid.origin.x, grid.origin.y
    # the nearest cell is found in cell units, where ties are exact (a window of the map breaks
    # them the same way as the whole map)
    mr, mc = cells[:, 0].mean(), cells[:, 1].mean()
    nearest = int(np.argmin((cells[:, 0] - mr) ** 2 + (cells[:, 1] - mc) ** 2))
    cx, cy = ox + (float(mc) + 0.5) * res, oy + (float(mr) + 0.5) * res
    goal = (ox + (int(cells[nearest, 1]) + 0.5) * res, oy + (int(cells[nearest, 0]) + 0.5) * res)
    return Frontier(cells=cells, size=len(cells), centroid=(cx, cy), goal=goal)


def close_gaps(grid: OccupancyGrid, gap_m: float) -> OccupancyGrid:
    """The grid with unknown cells in gaps under ``gap_m`` between occupied cells made occupied.

    A wall seen at a grazing angle, or far away between two beams, leaves holes onto the unknown
    beyond it; closed, they are no frontier and let no gain ray through.
    """
    k = math.ceil(math.floor(gap_m / grid.resolution + 1e-9) / 2.0)  # closes gaps of 2k cells
    if k < 1:
        return grid
    occupied = occupied_mask(grid)
    size = 2 * k + 1
    closed = cv2.morphologyEx(occupied.astype(np.uint8), cv2.MORPH_CLOSE, np.ones((size, size), np.uint8),
                              borderType=cv2.BORDER_CONSTANT, borderValue=0).astype(bool)
    fill = closed & unknown_mask(grid)
    if not fill.any():
        return grid
    data = grid.data.copy()
    data[fill] = 100
    return OccupancyGrid(grid.stamp, grid.resolution, grid.origin, data)

def clear_line(occupied: np.ndarray, a: tuple[int, int], b: tuple[int, int]) -> bool:
    """Whether the straight line between cells ``a`` and ``b`` crosses no occupied cell."""
    n = max(abs(b[0] - a[0]), abs(b[1] - a[1])) * 2 + 1
    rows = np.rint(np.linspace(a[0], b[0], n)).astype(np.int64)
    cols = np.rint(np.linspace(a[1], b[1], n)).astype(np.int64)
    return not occupied[rows, cols].any()


def visible_unknown_area(grid: OccupancyGrid, points: np.ndarray, sensor_range: float,
                         beams: int = 48) -> np.ndarray:
    """Unknown area (m^2) a 360° range sensor at each point would see, occupied cells blocking.

    Rays are sampled every cell out to ``sensor_range``; a sample in an unknown cell (or beyond
    the map, which is unknown too) adds the area of its ring sector ``r * dtheta * dr``; the first
    occupied cell ends the ray.
    """
    points = np.asarray(points, np.float64).reshape(-1, 2)
    if len(points) == 0:
        return np.zeros(0)
    res = grid.resolution
    dr = res
    radii = np.arange(1, int(sensor_range / dr) + 1) * dr                          # (S,)
    theta = np.arange(beams) * (2.0 * math.pi / beams)                              # (K,)
    dirs = np.stack([np.cos(theta), np.sin(theta)], axis=1)                         # (K, 2)
    xs = points[:, 0, None, None] + dirs[None, :, 0, None] * radii[None, None, :]   # (P, K, S)
    ys = points[:, 1, None, None] + dirs[None, :, 1, None] * radii[None, None, :]
    cols = np.floor((xs - grid.origin.x) / res).astype(np.int64)
    rows = np.floor((ys - grid.origin.y) / res).astype(np.int64)
    h, w = grid.data.shape
    inside = (rows >= 0) & (rows < h) & (cols >= 0) & (cols < w)
    values = np.full(xs.shape, -1, np.int16)
    values[inside] = grid.data[rows[inside], cols[inside]]
    occupied = occupied_mask(OccupancyGrid(0.0, res, grid.origin, values))
    blocked = np.logical_or.accumulate(occupied, axis=2)
    unknown = unknown_mask(OccupancyGrid(0.0, res, grid.origin, values)) & ~blocked
    weight = radii * (2.0 * math.pi / beams) * dr                                   # (S,)
    return (unknown * weight[None, None, :]).sum(axis=(1, 2))
