"""Choosing where to explore next on a map that is still being learned: the Explore leaf's brain.

:class:`ExplorationPlanner` turns the current map and robot position into ranked
:class:`Candidate` goals, with one of three rules (``strategy``):

- ``gain`` (ours): every frontier (cut into pieces of at most ``frontier_piece_m``) is scored by
  the unknown area it would reveal, ``gain_m2``, against the length of the path to it:
  ``gain_m2 * exp(-cost_rate * path_m)`` (the information-gain-against-cost trade-off of
  next-best-view exploration). The gain is measured by casting rays from the goal over the map
  out to ``sensor_range``: unknown cells count (each weighted by the area its ray sample stands for,
  so the sum is an area in m^2), occupied cells stop the ray -- so unknown space behind a known
  wall, or outside the building, is worth nothing.
- ``nearest``: the frontier with the shortest path, as the classic nearest-frontier rule of
  Yamauchi and explore_lite (with explore_lite's size term off).
- ``scan_points``: the vision-language object-search report's strategy -- the scan points of the
  map (centroids of the largest eroded free regions), largest region first, each visited once.

Path lengths come from :func:`missiontree.mapping.planner.path_lengths` (one Dijkstra from the
robot over the inflated costmap, unknown cells traversable as with a SLAM map); a goal it cannot
reach is no candidate. Goals the robot failed to reach are *blacklisted* (with the reason), and no
candidate within ``blacklist_radius`` of one is offered again. Nothing here talks to a robot: the
Explore leaf (:mod:`missiontree.behaviours.explore`) feeds it maps and poses, and the exploration
benchmark uses it the same way.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy import ndimage

from missiontree.mapping.frontiers import Frontier, find_frontiers
from missiontree.mapping.grid import free_mask, occupied_mask, unknown_mask
from missiontree.mapping.scan_points import scan_points
from missiontree.types import OccupancyGrid

STRATEGIES = ("gain", "nearest", "scan_points")

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


def straight_line_lengths(grid: OccupancyGrid, start: tuple[float, float],
                          goals: Sequence[tuple[float, float]],
                          footprint_radius: float) -> list[float | None]:
    """Euclidean distances (every goal counts as reachable)."""
    return [math.hypot(g[0] - start[0], g[1] - start[1]) for g in goals]


@dataclass(frozen=True)
class Candidate:
    """A place the robot could go to next.

    Attributes:
        x: Goal x (m), a free cell.
        y: Goal y (m).
        kind: ``frontier`` or ``scan_point``.
        size: Cells of the frontier piece or of the scan point's region.
        gain_m2: Unknown area visible from the goal within sensor range (0 when not computed).
        path_m: Length of the path from the robot.
        score: Higher is better (the strategy's rule).
    """

    x: float
    y: float
    kind: str
    size: int
    gain_m2: float
    path_m: float
    score: float


@dataclass(frozen=True)
class Blacklisted:
    """A goal given up, and why."""

    x: float
    y: float
    reason: str


@dataclass
class ExplorationPlanner:
    """Ranks exploration goals on a learned map; keeps the blacklist and the scan points visited.

    Attributes:
        strategy: ``gain``, ``nearest`` or ``scan_points``.
        footprint_radius: Robot radius (m); goals keep at least this (plus ``goal_margin``) from
            obstacles where the frontier allows.
        sensor_range: Range (m) over which a goal's gain is counted.
        min_frontier_m: Frontiers shorter than this (m) are ignored.
        frontier_piece_m: Long frontiers are cut into pieces of at most this length (m).
        cost_rate: Gain discount per metre of path (1/m), for ``gain``.
        blacklist_radius: Candidates this close (m) to a blacklisted goal are not offered.
        visit_radius: A scan point this close (m) to one already visited is not offered again.
        erosion_m: Erosion radius of the scan points (m).
        gain_beams: Rays cast per goal to measure its gain.
        path_lengths: How path lengths are measured (default: the planner).
    """

    strategy: str = "gain"
    footprint_radius: float = 0.2
    sensor_range: float = 4.0
    min_frontier_m: float = 0.3
    frontier_piece_m: float = 2.0
    cost_rate: float = 0.15
    blacklist_radius: float = 0.5
    visit_radius: float = 1.0
    erosion_m: float = 0.4
    goal_margin: float = 0.1
    gain_beams: int = 48
    path_lengths: PathLengths = planner_path_lengths
    blacklist: list[Blacklisted] = field(default_factory=list)
    visited: list[tuple[float, float]] = field(default_factory=list)

    def __post_init__(self) -> None:
        if self.strategy not in STRATEGIES:
            raise ValueError(f"unknown exploration strategy {self.strategy!r}; expected one of "
                             f"{', '.join(STRATEGIES)}")

    # -- bookkeeping -------------------------------------------------------------------------------

    def give_up(self, x: float, y: float, reason: str) -> None:
        """Blacklist the goal (x, y): it proved unreachable."""
        self.blacklist.append(Blacklisted(float(x), float(y), reason))

    def visit(self, x: float, y: float) -> None:
        """Record that the robot stood (and looked) at (x, y)."""
        self.visited.append((float(x), float(y)))

    def is_blacklisted(self, x: float, y: float) -> bool:
        """Whether (x, y) lies within ``blacklist_radius`` of a blacklisted goal."""
        r2 = self.blacklist_radius ** 2
        return any((b.x - x) ** 2 + (b.y - y) ** 2 <= r2 for b in self.blacklist)

    # -- ranking -----------------------------------------------------------------------------------

    def candidates(self, grid: OccupancyGrid, robot_xy: tuple[float, float]) -> list[Candidate]:
        """Reachable, not blacklisted goals, best first (empty: nothing reachable is left to explore)."""
        if self.strategy == "scan_points":
            points = [(p.x, p.y, p.cells) for p in scan_points(grid, self.erosion_m)]
            r2 = self.visit_radius ** 2
            points = [p for p in points if not self.is_blacklisted(p[0], p[1])
                      and all((vx - p[0]) ** 2 + (vy - p[1]) ** 2 > r2 for vx, vy in self.visited)]
            kind = "scan_point"
        else:
            points = [(*g, f.size) for f, g in self.frontier_goals(grid)]
            points = [p for p in points if not self.is_blacklisted(p[0], p[1])]
            kind = "frontier"
        if not points:
            return []
        lengths = self.path_lengths(grid, robot_xy, [(p[0], p[1]) for p in points], self.footprint_radius)
        reachable = [(p, length) for p, length in zip(points, lengths, strict=True) if length is not None]
        if not reachable:
            return []
        xy = np.array([[p[0], p[1]] for p, _ in reachable], np.float64)
        gains = visible_unknown_area(grid, xy, self.sensor_range, self.gain_beams) if kind == "frontier" \
            else np.zeros(len(reachable))
        out = []
        for (p, length), gain in zip(reachable, gains, strict=True):
            out.append(Candidate(p[0], p[1], kind, int(p[2]), float(gain), float(length),
                                 self._score(float(gain), float(length), int(p[2]))))
        out.sort(key=lambda c: (-c.score, c.path_m, c.x, c.y))
        return out

    def _score(self, gain: float, path: float, size: int) -> float:
        if self.strategy == "gain":
            return gain * math.exp(-self.cost_rate * path)
        if self.strategy == "nearest":
            return -path
        return float(size)  # scan points: the report ranks them by region size

    def better(self, best: Candidate, current: Candidate | None, margin: float = 1.3) -> bool:
        """Whether to leave the current goal for ``best`` (hysteresis against dithering)."""
        if current is None:
            return True
        if self.strategy == "gain":
            return best.score > margin * current.score
        if self.strategy == "nearest":
            return best.path_m < current.path_m - 0.5
        return False  # the report's strategy finishes each scan point before choosing the next

    def frontier_goals(self, grid: OccupancyGrid) -> list[tuple[Frontier, tuple[float, float]]]:
        """Frontier pieces with the goal cell chosen for each (clear of obstacles where possible)."""
        res = grid.resolution
        min_cells = max(1, int(math.ceil(self.min_frontier_m / res)))
        piece = max(min_cells, int(math.ceil(self.frontier_piece_m / res)))
        frontiers = find_frontiers(grid, min_size_cells=min_cells, max_size_cells=piece)
        if not frontiers:
            return []
        clearance = ndimage.distance_transform_edt(~occupied_mask(grid)) * res
        want = self.footprint_radius + self.goal_margin
        out = []
        for f in frontiers:
            rows, cols = f.cells[:, 0], f.cells[:, 1]
            clear = clearance[rows, cols]
            xs = grid.origin.x + (cols + 0.5) * res
            ys = grid.origin.y + (rows + 0.5) * res
            d2 = (xs - f.centroid[0]) ** 2 + (ys - f.centroid[1]) ** 2
            ok = clear >= want
            k = int(np.argmin(np.where(ok, d2, np.inf))) if ok.any() else int(np.argmax(clear))
            out.append((f, (float(xs[k]), float(ys[k]))))
        return out

    def still_frontier(self, grid: OccupancyGrid, x: float, y: float, radius: float = 0.3) -> bool:
        """Whether there is still frontier within ``radius`` of (x, y) (else that goal has been seen)."""
        res = grid.resolution
        r0, c0 = grid.world_to_cell(x, y)
        k = int(math.ceil(radius / res))
        h, w = grid.data.shape
        rs, re_, cs, ce = max(0, r0 - k - 1), min(h, r0 + k + 2), max(0, c0 - k - 1), min(w, c0 + k + 2)
        if rs >= re_ or cs >= ce:
            return True  # off the map: unknown, so still worth going
        window = OccupancyGrid(grid.stamp, res, grid.origin, grid.data[rs:re_, cs:ce])
        free = free_mask(window)
        unknown = np.pad(unknown_mask(window), 1, constant_values=False)
        near = ndimage.binary_dilation(unknown, structure=ndimage.generate_binary_structure(2, 1))[1:-1, 1:-1]
        rr, cc = np.nonzero(free & near)
        if len(rr) == 0:
            return False
        d2 = ((rr + rs - r0) ** 2 + (cc + cs - c0) ** 2) * res * res
        return bool((d2 <= radius * radius).any())


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
