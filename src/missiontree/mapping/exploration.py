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

Before frontiers are looked for, unknown gaps narrower than ``wall_gap_m`` between occupied cells
are taken for wall (a wall seen at a grazing angle leaves such holes, and each would otherwise be
a frontier onto the unknown outside the building), and enclosed unknown patches smaller than
``min_unknown_m2`` (specks between far-apart beams, the inside of furniture) are no frontier's
cause. Each frontier's goal stands back from it in known free space, clear of everything not known
free by the robot's radius plus a margin, within ``approach_m`` and in line of sight of it: the
unknown side of a frontier often turns out to be a wall.

Path lengths come from :func:`missiontree.mapping.planner.path_lengths` (one Dijkstra from the
robot over the inflated costmap, unknown cells traversable as with a SLAM map); a goal it cannot
reach is no candidate.

A try that fails is not the end of a frontier. :meth:`ExplorationPlanner.fail` records it, and the
frontier is offered again from another approach: the first try stands back from it as above, the
second goes *through* it (a goal ``through_m`` past the frontier, in the unknown it faces: the path
then leads through the doorway, and the robot sees the room from inside), later ones stand back at
another place, away from the poses that failed. A frontier place is *blacklisted* (no candidate
within ``blacklist_radius`` of it is offered again) only when the map proves it closed (no way to
it, or the goal inside an obstacle: ``give_up(..., proved_closed=True)``), or after
``max_attempts`` failed tries while the map still shows a way (given up *open*).
:meth:`ExplorationPlanner.left_open` lists what was given up open and is still worth going to on
the current map: exploring is complete only when that list is empty. Nothing here talks to a
robot: the Explore leaf (:mod:`missiontree.behaviours.explore`) feeds it maps and poses, and the
exploration benchmark uses it the same way.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import cv2
import numpy as np
from scipy import ndimage

from missiontree.mapping.frontiers import Frontier, find_frontiers
from missiontree.mapping.grid import free_mask, occupied_mask, unknown_mask
from missiontree.mapping.planner import Costmap
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


@dataclass(frozen=True)
class Candidate:
    """A place the robot could go to next.

    Attributes:
        x: Goal x (m), a free cell.
        y: Goal y (m).
        kind: ``frontier`` or ``scan_point``.
        size: Cells of the frontier piece or of the scan point's region.
        target: The place the goal is meant to see: the frontier cell nearest the frontier's
            centroid (for a scan point, the goal itself).
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
    target: tuple[float, float] = (math.nan, math.nan)


@dataclass(frozen=True)
class Blacklisted:
    """A goal given up (or a try that failed), the place it was to see (its frontier), and why.

    Attributes:
        proved_closed: The map showed the frontier closed (no way to it) when it was given up;
            False: given up while the map still showed a way (unexplored, possibly reachable).
    """

    x: float
    y: float
    reason: str
    target: tuple[float, float] = (math.nan, math.nan)
    proved_closed: bool = False


@dataclass(frozen=True)
class LeftOpen:
    """A frontier given up while the map still shows a way to it: what makes exploring incomplete.

    Attributes:
        entry: The blacklist entry.
        candidate: The goal the planner would offer for it now (ignoring the blacklist).
    """

    entry: Blacklisted
    candidate: Candidate


@dataclass
class ExplorationPlanner:
    """Ranks exploration goals on a learned map; keeps the blacklist and the scan points visited.

    Attributes:
        strategy: ``gain``, ``nearest`` or ``scan_points``.
        footprint_radius: Robot radius (m); goals keep at least this (plus ``goal_margin``) from
            every cell not known to be free, where the frontier allows.
        sensor_range: Range (m) over which a goal's gain is counted.
        min_frontier_m: Frontiers shorter than this (m) are ignored.
        min_unknown_m2: Unknown patches enclosed by known cells and smaller than this (m^2) are
            no frontier (specks between far-apart beams).
        frontier_piece_m: Long frontiers are cut into pieces of at most this length (m).
        cost_rate: Gain discount per metre of path (1/m), for ``gain``.
        min_gain_m2: For ``gain``, frontiers revealing less unknown area (m^2) are not worth a trip.
        blacklist_radius: Candidates this close (m) to a blacklisted goal are not offered.
        visit_radius: A scan point this close (m) to one already visited is not offered again.
        erosion_m: Erosion radius of the scan points (m).
        goal_margin: Extra clearance of a goal (m).
        approach_m: How far from a frontier's centroid its goal may stand (m).
        gain_beams: Rays cast per goal to measure its gain.
        wall_gap_m: Unknown gaps this narrow (m) between occupied cells are taken for wall (cells a
            wall seen at a grazing angle left unknown; else every such gap would be a frontier
            onto the unknown outside the building).
        reach_radius: The footprint (m) the navigation stack plans with (None: ``footprint_radius``):
            whether the map still shows a way to a frontier (:meth:`reachable`, :meth:`left_open`) is
            judged with it, so a place the navigation cannot plan to is closed, not left open.
        max_attempts: Failed tries (each from another approach) before a frontier the map still
            shows open is given up.
        retry_separation: A retry's goal stands at least this far (m) from the goals that failed.
        through_m: How far past the frontier (m) the second try's goal lies, in the unknown.
        retry_discount: A frontier's score is multiplied by this per failed try (``gain``), so
            other frontiers go first and the map around it can grow meanwhile.
        path_lengths: How path lengths are measured (default: the planner, on a costmap kept
            between calls and updated where the map changed).
    """

    strategy: str = "gain"
    footprint_radius: float = 0.2
    sensor_range: float = 4.0
    min_frontier_m: float = 0.3
    min_unknown_m2: float = 1.0
    frontier_piece_m: float = 2.0
    cost_rate: float = 0.15
    min_gain_m2: float = 0.5
    blacklist_radius: float = 0.75
    visit_radius: float = 1.0
    erosion_m: float = 0.4
    goal_margin: float = 0.1
    approach_m: float = 1.0
    gain_beams: int = 48
    wall_gap_m: float = 0.1
    reach_radius: float | None = None
    max_attempts: int = 3
    retry_separation: float = 0.5
    through_m: float = 0.6
    retry_discount: float = 0.5
    path_lengths: PathLengths = field(default_factory=KeptCostmapLengths)
    blacklist: list[Blacklisted] = field(default_factory=list)
    visited: list[tuple[float, float]] = field(default_factory=list)
    failures: list[Blacklisted] = field(default_factory=list)

    def __post_init__(self) -> None:
        if self.strategy not in STRATEGIES:
            raise ValueError(f"unknown exploration strategy {self.strategy!r}; expected one of "
                             f"{', '.join(STRATEGIES)}")

    # -- bookkeeping -------------------------------------------------------------------------------

    def give_up(self, x: float, y: float, reason: str,
                target: tuple[float, float] | None = None, proved_closed: bool = False) -> None:
        """Blacklist the goal (x, y) and the frontier place it was to see.

        ``proved_closed``: the map shows no way to it (else it is given up *open*, and exploring
        that leaves it is incomplete, see :meth:`left_open`).
        """
        where = (float(target[0]), float(target[1])) if target is not None else (math.nan, math.nan)
        self.blacklist.append(Blacklisted(float(x), float(y), reason, where, proved_closed))

    def fail(self, x: float, y: float, reason: str, target: tuple[float, float]) -> int:
        """Record a failed try at goal (x, y) for the frontier place ``target``; the tries there so far.

        The frontier stays on offer, from another approach (see :meth:`frontier_goals`).
        """
        self.failures.append(Blacklisted(float(x), float(y), reason, (float(target[0]), float(target[1]))))
        return len(self.tries(target))

    def tries(self, target: tuple[float, float]) -> list[Blacklisted]:
        """Failed tries and blacklist entries for the frontier place ``target`` (``blacklist_radius``)."""
        return self._near(self.failures, target) + self._near(self.blacklist, target)

    def _near(self, entries: list[Blacklisted], target: tuple[float, float]) -> list[Blacklisted]:
        r2 = self.blacklist_radius ** 2
        return [b for b in entries if (b.target[0] - target[0]) ** 2 + (b.target[1] - target[1]) ** 2 <= r2]

    def visit(self, x: float, y: float) -> None:
        """Record that the robot stood (and looked) at (x, y)."""
        self.visited.append((float(x), float(y)))

    def is_blacklisted(self, x: float, y: float, target: tuple[float, float] | None = None) -> bool:
        """Whether goal (x, y) or frontier place ``target`` is within ``blacklist_radius`` of one given up."""
        r2 = self.blacklist_radius ** 2
        for b in self.blacklist:
            if (b.x - x) ** 2 + (b.y - y) ** 2 <= r2:
                return True
            if target is not None and (b.target[0] - target[0]) ** 2 + (b.target[1] - target[1]) ** 2 <= r2:
                return True
        return False

    # -- ranking -----------------------------------------------------------------------------------

    def candidates(self, grid: OccupancyGrid, robot_xy: tuple[float, float],
                   ignore_blacklist: bool = False) -> list[Candidate]:
        """Reachable, not blacklisted goals, best first (empty: nothing reachable is left to explore).

        ``ignore_blacklist``: offer blacklisted places too (what :meth:`left_open` checks).
        """
        if ignore_blacklist:
            kept, self.blacklist = self.blacklist, []
            try:
                return self.candidates(grid, robot_xy)
            finally:
                self.blacklist = kept
        grid = self.close_wall_gaps(grid)
        if self.strategy == "scan_points":
            points = [(p.x, p.y, p.cells, p.x, p.y) for p in scan_points(grid, self.erosion_m)]
            r2 = self.visit_radius ** 2
            points = [p for p in points if not self.is_blacklisted(p[0], p[1])
                      and all((vx - p[0]) ** 2 + (vy - p[1]) ** 2 > r2 for vx, vy in self.visited)]
            kind = "scan_point"
        else:
            points = [(*g, f.size, *f.goal) for f, g in self.frontier_goals(grid)]
            points = [p for p in points if not self.is_blacklisted(p[0], p[1], (p[3], p[4]))]
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
            if self.strategy == "gain" and gain < self.min_gain_m2:
                continue
            failed = len(self.tries((p[3], p[4]))) if kind == "frontier" and self.failures else 0
            out.append(Candidate(p[0], p[1], kind, int(p[2]), float(gain), float(length),
                                 self._score(float(gain), float(length), int(p[2]), failed), (p[3], p[4])))
        out.sort(key=lambda c: (-c.score, c.path_m, c.x, c.y))
        return out

    def _score(self, gain: float, path: float, size: int, failed: int = 0) -> float:
        if self.strategy == "gain":
            return gain * math.exp(-self.cost_rate * path) * self.retry_discount ** failed
        if self.strategy == "nearest":
            return -path - 5.0 * failed  # a frontier tried before waits for the ones not tried yet
        return float(size)  # scan points: the report ranks them by region size

    def reach_candidates(self, grid: OccupancyGrid, robot_xy: tuple[float, float]) -> list[Candidate]:
        """Candidates, blacklisted places too, as the navigation's footprint (``reach_radius``) sees them."""
        kept = self.footprint_radius
        if self.reach_radius is not None:
            self.footprint_radius = max(kept, self.reach_radius)
        try:
            return self.candidates(grid, robot_xy, ignore_blacklist=True)
        finally:
            self.footprint_radius = kept

    def reachable(self, grid: OccupancyGrid, robot_xy: tuple[float, float],
                  target: tuple[float, float]) -> bool:
        """Whether the map still shows a way (at ``reach_radius``) to a goal for the frontier ``target``."""
        r = self.blacklist_radius
        return any(math.dist(c.target, target) <= r for c in self.reach_candidates(grid, robot_xy))

    def opens_onto_space(self, grid: OccupancyGrid, target: tuple[float, float]) -> bool:
        """Whether the frontier at ``target`` opens onto unknown space the robot's body fits into.

        True when a goal *through* it exists (:meth:`_through`, with the navigation's footprint):
        a point past it, clear of every occupied cell by the footprint, in line of sight. The
        unknown inside a piece of furniture or along a wall's far side is no such space (the line
        crosses the far side, or nothing past it is clear), a doorway onto an unseen room is.
        """
        grid = self.close_wall_gaps(grid)
        res = grid.resolution
        min_cells = max(1, int(math.ceil(self.min_frontier_m / res)))
        piece = max(min_cells, int(math.ceil(self.frontier_piece_m / res)))
        near = [f for f in find_frontiers(grid, min_size_cells=min_cells, max_size_cells=piece,
                                          min_unknown_cells=max(1, int(self.min_unknown_m2 / (res * res))))
                if math.dist(f.goal, target) <= self.blacklist_radius]
        if not near:
            return False
        occupied = occupied_mask(grid)
        to_occupied = cv2.distanceTransform((~occupied).astype(np.uint8), cv2.DIST_L2, 5) * res
        kept = self.footprint_radius
        if self.reach_radius is not None:
            self.footprint_radius = max(kept, self.reach_radius)
        try:
            return any(self._through(grid, f, occupied, to_occupied) is not None for f in near)
        finally:
            self.footprint_radius = kept

    def left_open(self, grid: OccupancyGrid, robot_xy: tuple[float, float]) -> list[LeftOpen]:
        """Blacklisted frontier places the map still offers a way to (and that are still worth going to).

        Each pairs its blacklist entry with the candidate the planner would offer for it now,
        ignoring the blacklist: a reachable frontier that would reveal enough unknown area and
        opens onto space the robot fits into (:meth:`opens_onto_space`). An entry given up as
        proved closed shows up here when the map has opened since.
        """
        if not self.blacklist or self.strategy == "scan_points":
            return []
        r2 = self.blacklist_radius ** 2
        out: list[LeftOpen] = []
        for c in self.reach_candidates(grid, robot_xy):
            for b in self.blacklist:
                near_target = (b.target[0] - c.target[0]) ** 2 + (b.target[1] - c.target[1]) ** 2 <= r2
                if near_target or (b.x - c.x) ** 2 + (b.y - c.y) ** 2 <= r2:
                    if all(o.entry is not b for o in out) and self.opens_onto_space(grid, c.target):
                        out.append(LeftOpen(b, c))
                    break
        return out

    def unknown_behind(self, grid: OccupancyGrid, places: Sequence[tuple[float, float]]) -> float:
        """Unknown area (m^2) within ``sensor_range`` of ``places``, connected to them through unknown cells.

        The area a set of frontiers left unexplored would reveal, at most: walls already known
        bound it, the sensor range bounds the rest (each place counted once where they overlap).
        """
        if not places:
            return 0.0
        grid = self.close_wall_gaps(grid)
        res = grid.resolution
        h, w = grid.data.shape
        k = int(math.ceil(self.sensor_range / res))
        cells = [grid.world_to_cell(x, y) for x, y in places]
        r0 = max(0, min(r for r, _ in cells) - k)
        r1 = min(h, max(r for r, _ in cells) + k + 1)
        c0 = max(0, min(c for _, c in cells) - k)
        c1 = min(w, max(c for _, c in cells) + k + 1)
        if r0 >= r1 or c0 >= c1:
            return 0.0
        window = grid.data[r0:r1, c0:c1]
        rr, cc = np.mgrid[r0:r1, c0:c1]
        near = np.zeros(window.shape, bool)
        for r, c in cells:
            near |= (rr - r) ** 2 + (cc - c) ** 2 <= k * k
        unknown = (window < 0) & near
        labels, _ = ndimage.label(unknown, structure=ndimage.generate_binary_structure(2, 1))
        seeds: set[int] = set()
        m = 2
        for r, c in cells:
            r, c = r - r0, c - c0
            box = labels[max(0, r - m): max(0, r + m + 1), max(0, c - m): max(0, c + m + 1)]
            seeds.update(int(v) for v in np.unique(box) if v)
        if not seeds:
            return 0.0
        return float(np.count_nonzero(np.isin(labels, list(seeds)))) * res * res

    def better(self, best: Candidate, current: Candidate | None, margin: float = 1.3) -> bool:
        """Whether to leave the current goal for ``best`` (hysteresis against dithering)."""
        if current is None:
            return True
        if self.strategy == "gain":
            return best.score > margin * current.score
        # nearest and scan points keep their goal until it is reached, seen or given up
        return False

    def close_wall_gaps(self, grid: OccupancyGrid) -> OccupancyGrid:
        """The grid with unknown cells in gaps under ``wall_gap_m`` between occupied cells made occupied."""
        k = math.ceil(math.floor(self.wall_gap_m / grid.resolution + 1e-9) / 2.0)  # closes gaps of 2k cells
        if k < 1:
            return grid
        cached = getattr(self, "_closed", None)
        if cached is not None and cached[0] is grid:
            return cached[1]
        occupied = occupied_mask(grid)
        size = 2 * k + 1
        closed = cv2.morphologyEx(occupied.astype(np.uint8), cv2.MORPH_CLOSE, np.ones((size, size), np.uint8),
                                  borderType=cv2.BORDER_CONSTANT, borderValue=0).astype(bool)
        fill = closed & unknown_mask(grid)
        out = grid
        if fill.any():
            data = grid.data.copy()
            data[fill] = 100
            out = OccupancyGrid(grid.stamp, grid.resolution, grid.origin, data)
        self._closed = (grid, out)
        return out

    def frontier_goals(self, grid: OccupancyGrid) -> list[tuple[Frontier, tuple[float, float]]]:
        """Frontier pieces, each with the place to send the robot to see it.

        The goal is the free cell nearest the frontier's centroid that keeps ``footprint_radius +
        goal_margin`` from every cell not known to be free (the unknown side of a frontier often
        turns out to be a wall), within ``approach_m`` of the centroid and in line of sight of the
        frontier. Where there is none, it is the frontier cell farthest from known obstacles.
        A frontier tried before (:meth:`fail`) gets another approach: after one failed try a goal
        through it (:meth:`_through`), after more a standing place away from the goals that failed.
        """
        res = grid.resolution
        min_cells = max(1, int(math.ceil(self.min_frontier_m / res)))
        piece = max(min_cells, int(math.ceil(self.frontier_piece_m / res)))
        frontiers = find_frontiers(grid, min_size_cells=min_cells, max_size_cells=piece,
                                   min_unknown_cells=max(1, int(self.min_unknown_m2 / (res * res))))
        if not frontiers:
            return []
        free = free_mask(grid)
        occupied = occupied_mask(grid)
        want = self.footprint_radius + self.goal_margin
        # distance (m) to the nearest cell not known free, and to the nearest occupied cell
        to_unfree = cv2.distanceTransform(np.pad(free, 1).astype(np.uint8), cv2.DIST_L2, 5)[1:-1, 1:-1] * res
        to_occupied = cv2.distanceTransform((~occupied).astype(np.uint8), cv2.DIST_L2, 5) * res
        safe = to_unfree >= want
        out = []
        for f in frontiers:
            failed = self._near(self.failures, f.goal) if self.failures else []
            avoid = [(b.x, b.y) for b in failed]
            goal = None
            if len(failed) == 1:
                goal = self._through(grid, f, occupied, to_occupied)
            if goal is None:
                goal = self._stand_back(grid, f, safe, occupied, avoid)
            if goal is None and len(failed) > 1:
                goal = self._through(grid, f, occupied, to_occupied)
            if goal is None:
                rows, cols = f.cells[:, 0], f.cells[:, 1]
                m = int(np.argmax(to_occupied[rows, cols]))
                if to_occupied[rows[m], cols[m]] < self.footprint_radius:
                    continue  # no place to stand near it: leave it
                goal = grid.cell_to_world(int(rows[m]), int(cols[m]))
            out.append((f, (float(goal[0]), float(goal[1]))))
        return out

    def _stand_back(self, grid: OccupancyGrid, f: Frontier, safe: np.ndarray, occupied: np.ndarray,
                    avoid: Sequence[tuple[float, float]]) -> tuple[float, float] | None:
        """The safe free cell nearest the frontier's centroid that sees it, away from ``avoid``; or None."""
        res = grid.resolution
        h, w = grid.data.shape
        k = int(math.ceil(self.approach_m / res))
        rows, cols = f.cells[:, 0], f.cells[:, 1]
        cr = min(h - 1, max(0, int(math.floor((f.centroid[1] - grid.origin.y) / res))))
        cc = min(w - 1, max(0, int(math.floor((f.centroid[0] - grid.origin.x) / res))))
        r0, c0 = max(0, cr - k), max(0, cc - k)
        sr, sc = np.nonzero(safe[r0:cr + k + 1, c0:cc + k + 1])
        if not len(sr):
            return None
        sr, sc = sr + r0, sc + c0
        d2 = (sr - cr) ** 2 + (sc - cc) ** 2
        keep = d2 <= k * k
        if avoid:
            sep = (self.retry_separation / res) ** 2
            for ax, ay in avoid:
                ar, ac = (ay - grid.origin.y) / res - 0.5, (ax - grid.origin.x) / res - 0.5
                keep &= (sr - ar) ** 2 + (sc - ac) ** 2 > sep
        sr, sc, d2 = sr[keep], sc[keep], d2[keep]
        for j in np.argsort(d2, kind="stable")[:8]:  # the nearest few that see the frontier
            m = int(np.argmin((rows - sr[j]) ** 2 + (cols - sc[j]) ** 2))
            if _clear_line(occupied, (int(sr[j]), int(sc[j])), (int(rows[m]), int(cols[m]))):
                return grid.cell_to_world(int(sr[j]), int(sc[j]))
        return None

    def _through(self, grid: OccupancyGrid, f: Frontier, occupied: np.ndarray,
                 to_occupied: np.ndarray) -> tuple[float, float] | None:
        """A goal ``through_m`` past the frontier, in the unknown it faces (a doorway: inside the room).

        The direction is the frontier's normal, from its free side towards its unknown side; the
        goal keeps the robot's radius (plus the margin) from every occupied cell and lies on the
        map, in straight line of sight from the frontier. Slightly shorter, longer or turned
        places are tried when the first is not clear; None when none is.
        """
        res = grid.resolution
        h, w = grid.data.shape
        unknown = np.pad(unknown_mask(grid), 1, constant_values=True)
        rows, cols = f.cells[:, 0] + 1, f.cells[:, 1] + 1
        nr = nc = 0.0
        for dr, dc in ((1, 0), (-1, 0), (0, 1), (0, -1)):
            hits = float(np.count_nonzero(unknown[rows + dr, cols + dc]))
            nr, nc = nr + dr * hits, nc + dc * hits
        norm = math.hypot(nr, nc)
        if norm < 1e-9:
            return None
        base = math.atan2(nr, nc)
        gr, gc = grid.world_to_cell(*f.goal)
        want = self.footprint_radius + self.goal_margin
        for turn in (0.0, 0.35, -0.35, 0.7, -0.7):
            for depth in (self.through_m, self.through_m + 0.3, self.through_m - 0.2):
                r = int(round(gr + math.sin(base + turn) * depth / res))
                c = int(round(gc + math.cos(base + turn) * depth / res))
                if not (0 <= r < h and 0 <= c < w) or to_occupied[r, c] < want:
                    continue
                if _clear_line(occupied, (gr, gc), (r, c)):
                    return grid.cell_to_world(r, c)
        return None

    def still_frontier(self, grid: OccupancyGrid, x: float, y: float, radius: float = 0.3) -> bool:
        """Whether there is still frontier within ``radius`` of (x, y) (else that goal has been seen)."""
        grid = self.close_wall_gaps(grid)
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


def _clear_line(occupied: np.ndarray, a: tuple[int, int], b: tuple[int, int]) -> bool:
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
