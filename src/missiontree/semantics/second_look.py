"""Where to stand for a second look at a place: free, with room to turn, at a good distance, in sight.

A detection seen from too close (its box cut by the image's border) or too far and oblique (a
few frames of a cup while the robot turned) stays a candidate; from about 1.5 m, facing it, the
camera sees it whole for a few seconds and the fusion confirms it or finds nothing there. The
stand is chosen on the robot's own map: a free cell at least ``clearance`` from the nearest
obstacle, between ``near`` and ``far`` from the place (as close to ``best`` as the map allows),
whose line of sight to the place is free on the map (its last 0.35 m excepted: the object itself
may be mapped).
"""

from __future__ import annotations

import math

import numpy as np

from missiontree.mapping.clearance import clearance_metres
from missiontree.types import OccupancyGrid

#: Distances (m) from the place: least, best, most.
NEAR, BEST, FAR = 0.9, 1.5, 2.2
#: Least distance (m) of a stand to the nearest obstacle on the map (room to turn).
CLEARANCE = 0.45
#: The line of sight's last stretch (m), not checked: the object itself may be on the map.
OWN_REACH = 0.35


def look_stand(
    grid: OccupancyGrid,
    place: tuple[float, float],
    near: float = NEAR,
    best: float = BEST,
    far: float = FAR,
    clearance: float = CLEARANCE,
) -> tuple[float, float] | None:
    """A stand for looking at ``place`` (see module docstring); None when the map offers none."""
    res = grid.resolution
    free = (grid.data >= 0) & (grid.data < 50)
    reach = int(math.ceil((far + clearance) / res)) + 1
    row, col = grid.world_to_cell(*place)
    r0, r1 = max(row - reach, 0), min(row + reach + 1, free.shape[0])
    c0, c1 = max(col - reach, 0), min(col + reach + 1, free.shape[1])
    if r0 >= r1 or c0 >= c1:
        return None
    window = free[r0:r1, c0:c1].astype(np.uint8)
    room = clearance_metres(window, res)
    rows, cols = np.nonzero(room >= clearance)
    if not len(rows):
        return None
    xs = grid.origin.x + (cols + c0 + 0.5) * res
    ys = grid.origin.y + (rows + r0 + 0.5) * res
    d = np.hypot(xs - place[0], ys - place[1])
    inside = np.nonzero((d >= near) & (d <= far))[0]
    for i in inside[np.argsort(np.abs(d[inside] - best))]:
        stand = (float(xs[i]), float(ys[i]))
        if in_sight(grid, free, stand, place):
            return stand
    return None


def in_sight(
    grid: OccupancyGrid, free: np.ndarray, stand: tuple[float, float], place: tuple[float, float]
) -> bool:
    """Whether ``free`` holds every cell from ``stand`` to ``place`` (the last ``OWN_REACH`` not checked)."""
    length = math.hypot(place[0] - stand[0], place[1] - stand[1])
    stop = max(0.0, 1.0 - OWN_REACH / max(length, 1e-6))
    steps = max(2, int(length / (grid.resolution / 2)))
    for t in np.linspace(0.0, stop, steps):
        row, col = grid.world_to_cell(
            stand[0] + t * (place[0] - stand[0]), stand[1] + t * (place[1] - stand[1])
        )
        if not (0 <= row < free.shape[0] and 0 <= col < free.shape[1]) or not free[row, col]:
            return False
    return True
