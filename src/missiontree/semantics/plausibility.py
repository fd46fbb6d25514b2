"""Whether what a detection's depth shows can be the object the detector named, judged by the map.

A detector fires on a stretch of wall now and then (a refrigerator: a tall plain surface filling the
view from close by, its box cut by the image's top). Its depth support then *is* the wall: the surface
the depth image measured lies on the map's obstacle cells, and right behind it the map shows known
free space (the room on the wall's other side, or the open space beyond a wall's end). A real
refrigerator stands solid on the floor: behind the face the camera sees, its own body fills the map
for at least its depth (half a metre), occupied in a map that holds it, unknown in one that learned
only its front from the lidar, never free.

:func:`thin_support` walks the ray from the camera through the measured surface point over the
robot's :class:`~missiontree.types.OccupancyGrid` (its own map, never the simulator's truth):

- the surface must lie on the map's obstacle (an occupied cell within ``surface_band`` of it along the
  ray), else the map says nothing about it (a newly placed object the map does not hold yet);
- past the occupied run that holds it, ``free_run`` of known-free cells must begin closer behind the
  surface than the class's least depth (:data:`LEAST_DEPTH`) less ``free_run``: then the thing seen
  is thinner than any object of the class, a wall.

Only classes whose body reaches the floor and is deeper than a wall is thick are listed (a sofa or a
bed may stand on legs the lidar sees under, a table is open beneath its top, a bookshelf is as
shallow as a thick wall, a tv hangs flat on one). :func:`plausible` filters a frame's projections.
Pure functions of a grid and projections.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

from missiontree.mapping.grid import FREE_BELOW, OCCUPIED_FROM
from missiontree.perception.projection import Projection
from missiontree.types import OccupancyGrid

#: Least depth of a class's footprint, metres, for classes that stand solid on the floor and are
#: deeper than walls are thick: behind the face a camera sees, at least this much of the object (from
#: appliance catalogues: full-size refrigerators are 0.6-0.8 m deep, compact under-counter ones
#: about 0.5 m; 0.45 m is the least width :data:`~missiontree.perception.footprint.SIZE_PRIORS`
#: gives any refrigerator from any side).
LEAST_DEPTH: dict[str, float] = {
    "refrigerator": 0.45,
}


@dataclass(frozen=True)
class SupportParams:
    """How a detection's depth support is judged against the map (see module docstring).

    Attributes:
        least_depth: Least footprint depth per class, metres; classes not listed are not judged.
            An empty mapping turns the check off.
        surface_band: The measured surface lies on the map's obstacle when an occupied cell lies
            within this distance of it along the ray (depth and pose are a few centimetres off; a
            cell is 5 cm), metres.
        free_run: Known-free stretch behind the obstacle that shows its far side (one free cell may
            be noise: three 5 cm cells), metres.
    """

    least_depth: Mapping[str, float] = field(default_factory=lambda: dict(LEAST_DEPTH))
    surface_band: float = 0.1
    free_run: float = 0.15


def _cell(grid: OccupancyGrid, x: float, y: float) -> int | None:
    """The grid's value at (x, y), None outside it."""
    row, col = grid.world_to_cell(x, y)
    h, w = grid.data.shape[:2]
    if not (0 <= row < h and 0 <= col < w):
        return None
    return int(grid.data[row, col])


def surface_point(p: Projection) -> tuple[float, float]:
    """Map (x, y) of the surface point the projection's depth measured (its position less the offset)."""
    cx, cy = p.camera_pose.x, p.camera_pose.y
    dx, dy = p.position[0] - cx, p.position[1] - cy
    norm = math.hypot(dx, dy)
    if norm <= 0.0:
        return p.position[0], p.position[1]
    return cx + dx * p.range / norm, cy + dy * p.range / norm


def thin_support(
    grid: OccupancyGrid, p: Projection, least_depth: float, surface_band: float = 0.1, free_run: float = 0.15
) -> bool:
    """Whether the map shows the projection's depth support as thinner than ``least_depth`` (a wall).

    Along the ray from the camera through the measured surface point, sampled every half cell: an
    occupied cell within ``surface_band`` of the surface, the occupied run it belongs to, then at
    least ``free_run`` of known-free cells beginning no farther than ``least_depth - free_run``
    behind the surface. Unknown cells or the grid's edge break the free run (no evidence). Cells read
    as every map is read (:mod:`missiontree.mapping.grid`: occupied from ``OCCUPIED_FROM``, free below
    ``FREE_BELOW``, map_server's thresholds), so trinary and scaled maps judge alike.
    """
    cx, cy = p.camera_pose.x, p.camera_pose.y
    sx, sy = surface_point(p)
    dx, dy = sx - cx, sy - cy
    distance = math.hypot(dx, dy)
    if distance <= 0.0 or least_depth <= free_run:
        return False
    ux, uy = dx / distance, dy / distance
    step = grid.resolution / 2.0

    def at(t: float) -> int | None:  # t: metres behind the surface along the ray (negative: before)
        return _cell(grid, sx + ux * t, sy + uy * t)

    # an occupied cell at the surface (nearest first)
    n_band = int(math.ceil(surface_band / step))
    hit = None
    for k in sorted(range(-n_band, n_band + 1), key=abs):
        value = at(k * step)
        if value is not None and value >= OCCUPIED_FROM:
            hit = k * step
            break
    if hit is None:
        return False  # the map holds nothing at the measured surface: no judgement
    # the occupied run it belongs to, then a known-free run starting early enough
    limit = least_depth - free_run
    t = hit
    while t <= limit:
        value = at(t)
        if value is None or value < 0:
            return False  # unknown or off the map: no evidence of a far side
        if value < OCCUPIED_FROM:
            break
        t += step
    else:
        return False  # occupied all through its least depth: deep enough
    end = t + free_run
    while t <= end:
        value = at(t)
        if value is None or not 0 <= value < FREE_BELOW:
            return False
        t += step
    return True


def plausible(
    projections: list[Projection], grid: OccupancyGrid | None, params: SupportParams | None = None
) -> tuple[list[Projection], list[Projection]]:
    """Split a frame's projections into those the map allows and those on a support too thin for their class.

    Without a grid every projection is kept.

    Returns:
        (kept, rejected).
    """
    if grid is None:
        return list(projections), []
    params = params or SupportParams()
    kept: list[Projection] = []
    rejected: list[Projection] = []
    for p in projections:
        depth = params.least_depth.get(p.label)
        if depth is not None and thin_support(grid, p, depth, params.surface_band, params.free_run):
            rejected.append(p)
        else:
            kept.append(p)
    return kept, rejected
