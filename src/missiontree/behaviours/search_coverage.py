"""What the camera has looked at, and where to go to look at the rest (the search's view coverage).

The lidar maps a large floor long before the camera has looked at it: on a 30 x 15 m depot the
frontiers ran out after 200 s with most of the floor never within the detector's range of the
camera, and a red backpack 4-5 m off the path was never detected. So the search keeps
:class:`ViewCoverage`: the floor cells (``cell`` m squares in map coordinates, so a growing map
does not move them) that a camera frame had in its field of view within ``view_range``, rays
stopped by occupied cells. Once no frontier is left, :func:`view_goals` gives places from which
the unseen reachable floor can be looked at: for each unseen patch, a place beside its cell
nearest the robot (the floor is swept from where the robot is, not crossed back and forth), ranked
by the unseen floor within ``view_range`` of it per metre of path, and gone to in the order of the
tour that brings the most of it into view soonest (:func:`tour_view_goals`). A cell counts as
looked at once ``min_views`` frames had it in view (the semantic map wants a few frames of an
object before it believes in it). A target is reported absent only when the camera has looked at all of the
reachable floor (or what is left could not be reached, or is hidden from every place reached).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from missiontree.mapping.grid import OCCUPIED_FROM, free_mask, occupied_mask
from missiontree.mapping.tour import between_lengths, latency_order
from missiontree.types import OccupancyGrid, Pose2D

#: path_lengths(grid, start, goals, radius) -> metres or None per goal (the exploration planner's).
PathLengths = Callable[
    [OccupancyGrid, tuple[float, float], Sequence[tuple[float, float]], float], list[float | None]
]


@dataclass(frozen=True)
class ViewGoal:
    """A place to look from: the goal (x, y), the unseen patch's centre and area, the path to it."""

    x: float
    y: float
    target: tuple[float, float]
    area_m2: float
    path_m: float
    score: float


class ViewCoverage:
    """The floor the camera has looked at, in square cells of ``cell`` m on the map's axes.

    Args:
        view_range: How far (m) the camera counts as having looked: the range at which the detector
            still finds the small objects searched for.
        cell: Side of a coverage cell (m).
        min_views: Frames that must have had a cell in view before it counts as looked at.
    """

    def __init__(self, view_range: float = 3.0, cell: float = 0.25, min_views: int = 1) -> None:
        self.view_range = view_range
        self.cell = cell
        self.min_views = min_views
        self.views: dict[tuple[int, int], int] = {}
        self.seen: set[tuple[int, int]] = set()
        self.skipped: set[tuple[int, int]] = set()
        #: The whole floor of the last grid asked about: (grid, robot's component cell, cells).
        self._floor: tuple[OccupancyGrid, tuple[int, int], set[tuple[int, int]]] | None = None

    def key(self, x: float, y: float) -> tuple[int, int]:
        """The coverage cell holding (x, y)."""
        return math.floor(x / self.cell), math.floor(y / self.cell)

    def add_view(self, grid: OccupancyGrid, pose: Pose2D, hfov: float) -> int:
        """Mark what a camera at ``pose`` with ``hfov`` (rad) sees of the floor; the cells newly seen.

        Rays (spaced at most half a cell apart at ``view_range``) go out in grid steps and stop at the
        first occupied cell (that cell is seen, what is behind it is not).
        """
        res = grid.resolution
        n_rays = max(2, int(math.ceil(hfov * self.view_range / (self.cell / 2.0))) + 1)
        n_steps = max(1, int(math.ceil(self.view_range / res)))
        angles = pose.yaw + np.linspace(-hfov / 2.0, hfov / 2.0, n_rays)
        dist = (np.arange(1, n_steps + 1) * res)[None, :]
        xs = pose.x + np.cos(angles)[:, None] * dist
        ys = pose.y + np.sin(angles)[:, None] * dist
        rows = np.floor((ys - grid.origin.y) / res).astype(int)
        cols = np.floor((xs - grid.origin.x) / res).astype(int)
        h, w = grid.data.shape
        inside = (rows >= 0) & (rows < h) & (cols >= 0) & (cols < w)
        blocked = np.zeros_like(inside)
        blocked[inside] = grid.data[rows[inside], cols[inside]] >= OCCUPIED_FROM  # the ray's cells only
        # everything up to and including the first occupied cell (or the map's edge) of each ray
        stop = np.cumsum(blocked | ~inside, axis=1)
        visible = (stop == 0) | ((stop == 1) & blocked)
        kx = np.floor(xs[visible] / self.cell).astype(int)
        ky = np.floor(ys[visible] / self.cell).astype(int)
        before = len(self.seen)
        keys = np.unique(np.stack([kx, ky], axis=1), axis=0) if len(kx) else np.zeros((0, 2), int)
        for a, b in keys.tolist():
            k = (a, b)
            n = self.views.get(k, 0) + 1
            self.views[k] = n
            if n >= self.min_views:
                self.seen.add(k)
        return len(self.seen) - before

    def floor(
        self, grid: OccupancyGrid, robot_xy: tuple[float, float], radius: float | None = None
    ) -> set[tuple[int, int]]:
        """The coverage cells of the free floor connected to the robot (most of the cell known free).

        With ``radius`` (m): only the square window of that half-side around the robot, connected
        within it -- a labelling of the whole map cost about the map's size at every choice of a
        goal (1.7 M cells on a warehouse map). The whole floor is kept for the grid last given.
        """
        if radius is not None:
            return self._floor_cells(window(grid, robot_xy, radius), robot_xy)
        cell = grid.world_to_cell(*robot_xy)
        if self._floor is not None and self._floor[0] is grid and self._floor[1] == cell:
            return self._floor[2]
        cells = self._floor_cells(grid, robot_xy)
        self._floor = (grid, cell, cells)
        return cells

    def _floor_cells(self, grid: OccupancyGrid, robot_xy: tuple[float, float]) -> set[tuple[int, int]]:
        free = free_mask(grid)
        n, labels = cv2.connectedComponents(free.astype(np.uint8), connectivity=8)
        r0, c0 = grid.world_to_cell(*robot_xy)
        h, w = free.shape
        if not (0 <= r0 < h and 0 <= c0 < w) or n <= 1:
            return set()
        own = labels[r0, c0]
        if own == 0:  # the robot's own cell is not free on the map: the free component nearest to it
            rr, cc = np.nonzero(labels > 0)
            if not len(rr):
                return set()
            j = int(np.argmin((rr - r0) ** 2 + (cc - c0) ** 2))
            own = labels[rr[j], cc[j]]
        rr, cc = np.nonzero(labels == own)
        xs = grid.origin.x + (cc + 0.5) * grid.resolution
        ys = grid.origin.y + (rr + 0.5) * grid.resolution
        kx = np.floor(xs / self.cell).astype(np.int64)
        ky = np.floor(ys / self.cell).astype(np.int64)
        x0, y0 = int(kx.min()), int(ky.min())
        span = int(ky.max()) - y0 + 1
        counts = np.bincount((kx - x0) * span + (ky - y0))  # free fine cells in each coverage cell
        per_cell = (self.cell / grid.resolution) ** 2
        full = np.nonzero(counts >= 0.5 * per_cell)[0]
        return {(int(i // span) + x0, int(i % span) + y0) for i in full}

    def unseen(
        self, grid: OccupancyGrid, robot_xy: tuple[float, float], radius: float | None = None
    ) -> set[tuple[int, int]]:
        """The reachable floor's cells the camera has not looked at (and not given up); ``radius``: near."""
        return self.floor(grid, robot_xy, radius) - self.seen - self.skipped

    def unseen_near(self, grid: OccupancyGrid, xy: tuple[float, float], radius: float) -> float:
        """Known-free floor (m^2) within ``radius`` of ``xy`` the camera has not looked at (nor given up).

        A local count (a window of the map, not the whole floor): cheap enough for every re-plan.
        """
        part = window(grid, xy, radius)
        if part.data.size == 0:
            return 0.0
        res = part.resolution
        rr, cc = np.nonzero(free_mask(part))
        xs = part.origin.x + (cc + 0.5) * res
        ys = part.origin.y + (rr + 0.5) * res
        near = (xs - xy[0]) ** 2 + (ys - xy[1]) ** 2 <= radius * radius
        if not near.any():
            return 0.0
        keys = np.stack([np.floor(xs[near] / self.cell), np.floor(ys[near] / self.cell)], axis=1).astype(int)
        cells, counts = np.unique(keys, axis=0, return_counts=True)
        seen, skipped = self.seen, self.skipped
        unseen = sum(n for (a, b), n in zip(cells.tolist(), counts.tolist(), strict=True)
                     if (a, b) not in seen and (a, b) not in skipped)
        return unseen * res * res

    def seen_share(self, grid: OccupancyGrid, robot_xy: tuple[float, float]) -> tuple[float, float]:
        """(m^2 of the reachable floor looked at, m^2 of that floor)."""
        floor = self.floor(grid, robot_xy)
        a = self.cell * self.cell
        return len(floor & self.seen) * a, len(floor) * a

    def skip(self, cells: set[tuple[int, int]]) -> None:
        """Give up looking at ``cells`` (no place to look from was reached)."""
        self.skipped |= cells


def window(grid: OccupancyGrid, xy: tuple[float, float], radius: float) -> OccupancyGrid:
    """The part of ``grid`` within ``radius`` (m, a square's half-side) of ``xy``, origin moved to match."""
    res = grid.resolution
    r0, c0 = grid.world_to_cell(*xy)
    k = int(math.ceil(radius / res))
    h, w = grid.data.shape
    rs, re_, cs, ce = max(0, r0 - k), min(h, r0 + k + 1), max(0, c0 - k), min(w, c0 + k + 1)
    if rs >= re_ or cs >= ce:
        rs, re_, cs, ce = 0, 0, 0, 0
    origin = Pose2D(grid.origin.x + cs * res, grid.origin.y + rs * res, grid.origin.yaw)
    return OccupancyGrid(grid.stamp, res, origin, grid.data[rs:re_, cs:ce])


def unseen_patches(
    coverage: ViewCoverage, cells: set[tuple[int, int]], min_cells: int
) -> list[set[tuple[int, int]]]:
    """The unseen cells in 8-connected patches of at least ``min_cells`` cells, largest first."""
    if not cells:
        return []
    keys = np.array(sorted(cells))
    x0, y0 = keys.min(axis=0)
    shape = tuple(keys.max(axis=0) - (x0, y0) + 1)
    img = np.zeros((int(shape[0]), int(shape[1])), np.uint8)
    img[keys[:, 0] - x0, keys[:, 1] - y0] = 1
    n, labels = cv2.connectedComponents(img, connectivity=8)
    patches: list[set[tuple[int, int]]] = []
    for k in range(1, n):
        xs, ys = np.nonzero(labels == k)
        if len(xs) >= min_cells:
            patches.append({(int(a + x0), int(b + y0)) for a, b in zip(xs, ys, strict=True)})
    return sorted(patches, key=len, reverse=True)


def view_goals(
    coverage: ViewCoverage,
    grid: OccupancyGrid,
    robot_xy: tuple[float, float],
    path_lengths: PathLengths,
    robot_radius: float,
    *,
    room: float = 0.35,
    min_area_m2: float = 0.5,
    cost_rate: float = 0.15,
    max_patches: int = 8,
    radius: float | None = None,
) -> tuple[list[ViewGoal], list[set[tuple[int, int]]]]:
    """Places to look at the unseen floor from, best first; and the patches no place was found for.

    Each patch of unseen floor (at least ``min_area_m2``) gets a goal: the free cell with ``room`` m
    of clearance nearest the patch's cell nearest the robot, at most ``view_range`` / 2 from it (the
    floor is swept outward from the robot). Scored by the patch's unseen floor within
    ``view_range`` of the goal over (1 + cost_rate x path length) on the planner's path. With
    ``radius`` only the floor within that window around the robot is looked at (goals placed in it).
    """
    cells = coverage.unseen(grid, robot_xy, radius)
    per = coverage.cell * coverage.cell
    patches = unseen_patches(coverage, cells, max(1, int(math.ceil(min_area_m2 / per))))[:max_patches]
    if not patches:
        return [], []
    near = grid if radius is None else window(grid, robot_xy, radius + coverage.view_range)
    goals, placed, unplaced = _place_goals(coverage, near, patches, robot_xy, room)
    lengths = path_lengths(grid, robot_xy, [g[0] for g in goals], robot_radius) if goals else []
    out: list[ViewGoal] = []
    for (xy, target, gain), patch, length in zip(goals, placed, lengths, strict=True):
        if length is None:
            unplaced.append(patch)
            continue
        out.append(ViewGoal(xy[0], xy[1], target, gain, float(length), gain / (1.0 + cost_rate * length)))
    return sorted(out, key=lambda g: -g.score), unplaced


#: A place to look from, before its path is measured: (goal xy, the patch's anchor xy, unseen m^2 in view).
_Placed = tuple[tuple[float, float], tuple[float, float], float]


def _place_goals(
    coverage: ViewCoverage,
    near: OccupancyGrid,
    patches: list[set[tuple[int, int]]],
    robot_xy: tuple[float, float],
    room: float,
) -> tuple[list[_Placed], list[set[tuple[int, int]]], list[set[tuple[int, int]]]]:
    """A place for each patch (the roomy free cell nearest its cell nearest the robot); placed, unplaced."""
    res = near.resolution
    occupied = occupied_mask(near)
    clear = cv2.distanceTransform((~occupied).astype(np.uint8), cv2.DIST_L2, 5) * res
    rr, cc = np.nonzero(free_mask(near) & (clear >= room))
    if not len(rr):
        return [], [], list(patches)
    wx = near.origin.x + (cc + 0.5) * res
    wy = near.origin.y + (rr + 0.5) * res
    goals: list[_Placed] = []
    placed: list[set[tuple[int, int]]] = []
    unplaced: list[set[tuple[int, int]]] = []
    reach = coverage.view_range / 2.0
    here = np.asarray(robot_xy, dtype=float)
    for patch in patches:
        pts = (np.array(sorted(patch), dtype=float) + 0.5) * coverage.cell
        anchor = pts[int(np.argmin(((pts - here) ** 2).sum(axis=1)))]
        d2 = (wx - anchor[0]) ** 2 + (wy - anchor[1]) ** 2
        j = int(np.argmin(d2))
        if d2[j] > reach * reach:
            unplaced.append(patch)
            continue
        goal = np.array([wx[j], wy[j]])
        within = float(np.count_nonzero(((pts - goal) ** 2).sum(axis=1) <= coverage.view_range**2))
        goals.append(((float(goal[0]), float(goal[1])), (float(anchor[0]), float(anchor[1])),
                      within * coverage.cell * coverage.cell))
        placed.append(patch)
    return goals, placed, unplaced


def tour_view_goals(grid: OccupancyGrid, goals: list[ViewGoal], stop_m: float = 3.0) -> list[ViewGoal]:
    """``goals`` in the order of the tour that brings the most unseen floor into view soonest.

    One step ahead (unseen floor per metre) the robot swept a room's far side and came back for
    the near corner; the tour (:mod:`missiontree.mapping.tour`) weighs the whole sweep, each stop
    (and its look) costing ``stop_m`` beside its path.
    """
    if len(goals) < 2:
        return goals
    start = np.array([g.path_m for g in goals], float)
    between = between_lengths(grid, [(g.x, g.y) for g in goals], start) + stop_m
    order = latency_order(np.array([g.area_m2 for g in goals], float), start, between)
    return [goals[i] for i in order]


def straight_lengths(
    grid: OccupancyGrid, start: tuple[float, float], goals: Sequence[tuple[float, float]], radius: float
) -> list[float | None]:
    """Straight-line distances to ``goals`` (every one counts as reachable): for tests and quick looks."""
    return [math.hypot(g[0] - start[0], g[1] - start[1]) for g in goals]


def known_path_lengths(
    grid: OccupancyGrid, start: tuple[float, float], goals: Sequence[tuple[float, float]], radius: float
) -> list[float | None]:
    """Path lengths on the inflated costmap through known free cells only (None: no such path).

    A place to look at known floor from must be reachable over known floor: a path through unknown
    cells (a wall the lidar has not seen whole) sent the robot at a room beyond a wall, goal after
    goal aborted.
    """
    from missiontree.mapping.planner import path_lengths

    return path_lengths(grid, start, list(goals), footprint_radius=radius, allow_unknown=False)


def unseen_bearings(
    coverage: ViewCoverage, grid: OccupancyGrid, pose: Pose2D, radius: float | None = None
) -> np.ndarray:
    """Bearings (rad, relative to ``pose``'s heading) of the unseen floor within ``radius`` in sight.

    ``radius`` defaults to the view range. A cell counts when the straight line to it crosses no
    occupied cell of ``grid`` (floor behind a wall cannot be looked at from here, turning or not).
    """
    reach = coverage.view_range if radius is None else radius
    cells = coverage.unseen(grid, (pose.x, pose.y), radius=reach + coverage.cell)
    if not cells:
        return np.zeros(0)
    keys = np.array(sorted(cells), dtype=float)
    xs, ys = (keys[:, 0] + 0.5) * coverage.cell, (keys[:, 1] + 0.5) * coverage.cell
    dist = np.hypot(xs - pose.x, ys - pose.y)
    near = (dist <= reach) & (dist > 1e-6)
    xs, ys, dist = xs[near], ys[near], dist[near]
    if not len(xs):
        return np.zeros(0)
    res = grid.resolution
    steps = max(1, int(math.ceil(reach / (res / 2.0))))
    frac = (np.arange(1, steps) / steps)[None, :]
    px = pose.x + (xs - pose.x)[:, None] * frac
    py = pose.y + (ys - pose.y)[:, None] * frac
    rows = np.floor((py - grid.origin.y) / res).astype(int)
    cols = np.floor((px - grid.origin.x) / res).astype(int)
    h, w = grid.data.shape
    inside = (rows >= 0) & (rows < h) & (cols >= 0) & (cols < w)
    blocked = np.zeros_like(inside)
    blocked[inside] = grid.data[rows[inside], cols[inside]] >= OCCUPIED_FROM
    # the cell's own square may hold the obstacle it is floor beside: only the way there counts
    short = np.hypot(px - pose.x, py - pose.y) < (dist[:, None] - coverage.cell)
    clear = ~(blocked & short).any(axis=1)
    angles = np.arctan2(ys[clear] - pose.y, xs[clear] - pose.x) - pose.yaw
    return np.asarray((angles + math.pi) % (2.0 * math.pi) - math.pi)


def look_arc(bearings: np.ndarray, half_fov: float) -> tuple[float, float] | None:
    """The turn that brings every bearing within ``half_fov`` of the camera: (first, then) signed rad.

    ``bearings`` are relative to the heading now. None: all are in view already (no turn). The
    camera turned by a sweeps [-half_fov, a + half_fov], so the floor around the robot is covered
    by the interval of bearings outside their largest gap, reached at its nearer end and swept to
    the other; a full circle is never needed (2 pi - 2 half_fov covers it).
    """
    if not len(bearings) or bool(np.all(np.abs(bearings) <= half_fov)):
        return None
    b = np.sort(np.asarray(bearings, dtype=float))
    gaps = np.diff(np.concatenate([b, [b[0] + 2.0 * math.pi]]))
    i = int(np.argmax(gaps))
    lo = float(b[(i + 1) % len(b)])
    span = 2.0 * math.pi - float(gaps[i])
    if span >= 2.0 * math.pi - 2.0 * half_fov:  # all around: one sweep of the rest of the circle
        return 2.0 * math.pi - 2.0 * half_fov, 0.0
    start, end = lo + half_fov, lo + span - half_fov
    if start >= end:  # one heading shows them all
        mid = lo + span / 2.0
        return _wrap(mid), 0.0
    a, z = _wrap(start), _wrap(end)
    sweep = end - start
    if abs(a) + sweep <= abs(z) + sweep:
        return a, sweep
    return z, -sweep


def _wrap(angle: float) -> float:
    return (angle + math.pi) % (2.0 * math.pi) - math.pi
