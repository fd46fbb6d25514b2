"""Where to stand to look at an object: standoff cells on the map, in sight and reachable.

The geometry under :func:`missiontree.reasoning.intent.plan_candidates` and
:func:`~missiontree.reasoning.intent.other_viewpoint`: the map prepared once per content
(:func:`prepare_space`: obstacles, clearance, the planner's costmap), the free cells near an object
from which it is in sight (:func:`standoff_cells`), how far the camera must stand back to see it
(:func:`view_distance`), path lengths to many cells in one search (:func:`cell_path_lengths`) and
whether an object lies in explored space (:func:`outside_known_map`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np

from missiontree.mapping.occupancy import BLOCKED_FROM
from missiontree.mapping.planner import Costmap, path_lengths
from missiontree.types import OccupancyGrid, Pose2D

#: Occupancy values at or above this are obstacles (as the simulator plans).
OCCUPIED = BLOCKED_FROM
#: Extra clearance a standoff pose keeps beyond the robot's radius (m).
STANDOFF_MARGIN = 0.08
#: How far beyond the object's edge a standoff pose may be (m): the robot stands close to what it fetches.
STANDOFF_REACH = 0.5
#: When no place is free that close (an object in a corner of clutter, behind a chair), rings this wide
#: (m) farther out are searched in turn, up to :data:`MAX_REACH` beyond the edge: from there the camera
#: still sees the object and the robot is still within a metre of it.
RING, MAX_REACH = 0.15, 0.8
#: A ray from a standoff pose must reach this close to the object's edge before hitting anything (m).
SIGHT_SLACK = 0.15
#: Metres of path a standoff pose may cost for each metre closer to the object.
NEAR_WEIGHT = 2.0
#: Clearance from other obstacles a standoff pose should have beyond the robot's radius (m), and the
#: metres of path each missing metre of it costs.
CLEAR_WANTED, CLEAR_WEIGHT = 0.25, 4.0
#: Extra distance beyond the camera's lower view limit (m): the camera sits ahead of the base's centre.
VIEW_MARGIN = 0.12
#: An object whose own cell is unknown is drawn as an outline round an unseen middle when that middle
#: is closed (by obstacles or known cells) within this radius (m); past it, it is unexplored space.
OUTLINE_RADIUS = 1.0
#: An object whose cell and surroundings (this radius, m) are all unknown is outside the known map.
KNOWN_RADIUS = 0.5


@dataclass
class Space:
    """The map prepared for standoff search and path lengths (cached per map content)."""

    grid: OccupancyGrid
    occupied: np.ndarray  # bool, obstacle cells
    known: np.ndarray  # bool, cells that are not unknown
    clearance: np.ndarray  # float, metres from each cell to the nearest obstacle
    inside: np.ndarray  # float, metres from each obstacle cell to the nearest free cell
    costmap: Costmap  # the planner's inflated costmap (path lengths as the navigation stack drives)


_SPACE_CACHE: dict[tuple[Any, ...], Space] = {}


def prepare_space(grid: OccupancyGrid, robot_radius: float, allow_unknown: bool = False) -> Space:
    """Obstacles, clearance and the planner's costmap of ``grid`` for a robot of ``robot_radius``.

    Cached by map content, so a static map is prepared once per process.
    """
    data = np.asarray(grid.data)
    key = (
        data.shape,
        grid.resolution,
        grid.origin.x,
        grid.origin.y,
        round(robot_radius, 4),
        allow_unknown,
        hash(data.tobytes()),
    )
    cached = _SPACE_CACHE.get(key)
    if cached is not None:
        return cached
    res = float(grid.resolution)
    occupied = data >= OCCUPIED
    known = data >= 0
    blocked = occupied | (~known if not allow_unknown else np.zeros_like(occupied))
    clearance = cv2.distanceTransform((~blocked).astype(np.uint8), cv2.DIST_L2, 5) * res
    inside = cv2.distanceTransform(occupied.astype(np.uint8), cv2.DIST_L2, 5) * res
    costmap = Costmap(grid, robot_radius, allow_unknown=allow_unknown)
    space = Space(grid, occupied, known, clearance, inside, costmap)
    if len(_SPACE_CACHE) > 16:
        _SPACE_CACHE.clear()
    _SPACE_CACHE[key] = space
    return space


def object_extent(space: Space, xy: tuple[float, float]) -> float:
    """How far the object's footprint reaches from its position (m): 0 when the cell is free.

    On a map learned as the robot goes, the lidar draws a chair or a sofa as an outline round a
    middle it never saw: the object's own cell is unknown. When that unknown middle is closed within
    :data:`OUTLINE_RADIUS` (:func:`_closed_middle`), the footprint reaches to its far edge, so a look
    across the outline is in sight. An object in unexplored space has no closed middle (the unknown
    runs on), and keeps no footprint: no place to stand is found in sight of it.
    """
    row, col = space.grid.world_to_cell(*xy)
    rows, cols = space.occupied.shape
    if not (0 <= row < rows and 0 <= col < cols):
        return 0.0
    if space.occupied[row, col]:
        return float(space.inside[row, col])
    if not space.known[row, col]:
        return _closed_middle(space, row, col)
    return 0.0


def _closed_middle(space: Space, row: int, col: int) -> float:
    """How far (m) the unknown cells joined to (row, col) reach from it, if they close near it; else 0."""
    res = space.grid.resolution
    reach = int(math.ceil(OUTLINE_RADIUS / res))
    r0, c0 = max(0, row - reach), max(0, col - reach)
    window = ~space.known[r0 : row + reach + 1, c0 : col + reach + 1]
    _, labels = cv2.connectedComponents(window.astype(np.uint8), connectivity=8)
    mine = labels == labels[row - r0, col - c0]
    if mine[0, :].any() or mine[-1, :].any() or mine[:, 0].any() or mine[:, -1].any():
        return 0.0  # the unknown runs on to the window's edge (or the map's): unexplored space
    rr, cc = np.nonzero(mine)
    return float(np.hypot(rr + r0 - row, cc + c0 - col).max() * res + res)


def standoff_cells(
    space: Space, xy: tuple[float, float], robot_radius: float, min_distance: float = 0.0
) -> list[tuple[int, int, float]]:
    """Free cells near the object from which it is in sight: (row, col, penalty in metres).

    A cell qualifies when the robot fits there with a margin, it lies between the object's edge plus
    the robot's radius and :data:`STANDOFF_REACH` beyond, and a ray from it towards the object meets
    no obstacle before coming within :data:`SIGHT_SLACK` of the object's edge (no wall between).
    When no cell qualifies, rings :data:`RING` farther out are searched in turn up to
    :data:`MAX_REACH` (the nearest ring with a place wins). The penalty, added to the path length
    when choosing among them, prefers cells close to the object (what sits on a table is reached
    across its edge) and clear of other obstacles (a goal hugging a wall makes the navigation stack
    stop short). ``min_distance`` keeps the robot at least that far from the object's position (so
    that the camera sees down to it).
    """
    extent = object_extent(space, xy)
    near = max(extent + robot_radius + 0.02, min_distance)
    far = max(extent + robot_radius + STANDOFF_REACH, near + 0.3)
    limit = max(extent + robot_radius + MAX_REACH, far)
    inner = near
    while True:
        found = _ring_cells(space, xy, robot_radius, extent, (inner, far), near)
        if found or far >= limit - 1e-9:
            return found
        inner, far = far, min(limit, far + RING)


def _ring_cells(space: Space, xy: tuple[float, float], robot_radius: float, extent: float,
                band: tuple[float, float], near: float) -> list[tuple[int, int, float]]:
    """The cells of :func:`standoff_cells` whose distance from ``xy`` lies in ``band`` (m)."""
    grid = space.grid
    res = grid.resolution
    rows, cols = space.occupied.shape
    r_c, c_c = grid.world_to_cell(*xy)
    span = int(math.ceil(band[1] / res)) + 1
    r0, r1 = max(0, r_c - span), min(rows, r_c + span + 1)
    c0, c1 = max(0, c_c - span), min(cols, c_c + span + 1)
    if r0 >= r1 or c0 >= c1:
        return []
    rr, cc = np.mgrid[r0:r1, c0:c1]
    cx = grid.origin.x + (cc + 0.5) * res
    cy = grid.origin.y + (rr + 0.5) * res
    d = np.hypot(cx - xy[0], cy - xy[1])
    clear = space.clearance[r0:r1, c0:c1]
    ok = (d >= band[0]) & (d <= band[1]) & (clear >= robot_radius + STANDOFF_MARGIN)
    penalty = NEAR_WEIGHT * (d - near) + CLEAR_WEIGHT * np.maximum(0.0, robot_radius + CLEAR_WANTED - clear)
    found: list[tuple[int, int, float]] = []
    for row, col, cost in zip(rr[ok], cc[ok], penalty[ok], strict=True):
        if _in_sight(space, int(row), int(col), xy, extent):
            found.append((int(row), int(col), float(cost)))
    # every other cell each way is enough choice (10 cm at 5 cm cells) and a quarter of the goals to search
    return [c for c in found if c[0] % 2 == 0 and c[1] % 2 == 0] or found


def _in_sight(space: Space, row: int, col: int, xy: tuple[float, float], extent: float) -> bool:
    grid = space.grid
    x0, y0 = grid.cell_to_world(row, col)
    length = math.hypot(xy[0] - x0, xy[1] - y0)
    steps = max(1, int(length / (grid.resolution * 0.5)))
    for i in range(1, steps + 1):
        t = i / steps
        x, y = x0 + t * (xy[0] - x0), y0 + t * (xy[1] - y0)
        r, c = grid.world_to_cell(x, y)
        if space.occupied[r, c]:
            return (1.0 - t) * length <= extent + SIGHT_SLACK
    return True


def view_distance(camera: tuple[float, float] | None, z: float) -> float:
    """How far the camera must stand for a point ``z`` high to be in view (0: no camera given)."""
    if camera is None or camera[1] <= 0:
        return 0.0
    height, tan_down = camera
    return max(0.0, (height - z) / tan_down) + VIEW_MARGIN


def cell_path_lengths(
    space: Space, robot: Pose2D, cells: Sequence[tuple[int, int, float]]
) -> list[float] | None:
    """Path length from the robot to each (row, col) cell (inf: unreachable); None when boxed in.

    One Dijkstra search of :func:`missiontree.mapping.planner.path_lengths` on the planner's costmap,
    so a length is that of the path the navigation stack would plan.
    """
    goals = [space.grid.cell_to_world(r, c) for r, c, _ in cells]
    lengths = path_lengths(space.costmap, robot, goals)
    if goals and all(v is None for v in lengths):
        return None
    return [math.inf if v is None else float(v) for v in lengths]


def outside_known_map(space: Space, xy: tuple[float, float]) -> str:
    """Why ``xy`` lies outside the known map (beyond its bounds, or no known cell near it); "" inside."""
    grid = space.grid
    rows, cols = space.occupied.shape
    row, col = grid.world_to_cell(*xy)
    if not (0 <= row < rows and 0 <= col < cols):
        x0, y0 = grid.origin.x, grid.origin.y
        x1, y1 = x0 + cols * grid.resolution, y0 + rows * grid.resolution
        return (
            f"outside the known map: ({xy[0]:.2f}, {xy[1]:.2f}) is not in "
            f"[{x0:.2f}, {x1:.2f}] x [{y0:.2f}, {y1:.2f}]"
        )
    reach = int(math.ceil(KNOWN_RADIUS / grid.resolution))
    window = space.known[max(0, row - reach) : row + reach + 1, max(0, col - reach) : col + reach + 1]
    if not window.any():
        return f"outside the known map: ({xy[0]:.2f}, {xy[1]:.2f}) lies in unexplored space"
    return ""
