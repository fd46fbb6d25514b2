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

Every question is asked of the map's *window* (:meth:`ExplorationPlanner.window`): the box of its
known cells, padded by ``window_margin_m`` and snapped outwards to ``window_step_m``. Frontiers,
goals and gains are the same as on the whole grid (every cell outside the box is unknown, as is
everything beyond a grid's border); path lengths no longer wander through the unknown far from
anything seen. On a 30 x 50 m map at 3 cm the whole grid is 1.7 million cells, and every ranking
flooded all of them, most still unknown.

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
from collections.abc import Sequence
from dataclasses import dataclass, field

import cv2
import numpy as np
from scipy import ndimage

from missiontree.mapping.frontier_goals import Blacklisted, FrontierGoals
from missiontree.mapping.frontiers import find_frontiers, visible_unknown_area
from missiontree.mapping.grid import occupied_mask
from missiontree.mapping.path_lengths import KeptCostmapLengths as KeptCostmapLengths
from missiontree.mapping.path_lengths import PathLengths as PathLengths
from missiontree.mapping.path_lengths import known_window as known_window
from missiontree.mapping.path_lengths import planner_path_lengths as planner_path_lengths
from missiontree.mapping.path_lengths import straight_line_lengths as straight_line_lengths
from missiontree.mapping.scan_points import scan_points
from missiontree.mapping.tour import between_lengths, latency_order
from missiontree.types import OccupancyGrid

STRATEGIES = ("gain", "nearest", "scan_points")

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
class LeftOpen:
    """A frontier given up while the map still shows a way to it: what makes exploring incomplete.

    Attributes:
        entry: The blacklist entry.
        candidate: The goal the planner would offer for it now (ignoring the blacklist).
    """

    entry: Blacklisted
    candidate: Candidate


@dataclass(frozen=True)
class Sliver:
    """A reachable frontier left as not worth a trip: a small enclosed unknown pocket, far for its gain.

    Attributes:
        candidate: The goal that would have been offered for it.
        region: Label of its unknown region in the ranking's map (pockets sharing one count once).
        unknown_m2: Area of that unknown region (m^2).
    """

    candidate: Candidate
    region: int
    unknown_m2: float


@dataclass
class ExplorationPlanner(FrontierGoals):
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
        gain_gap_m: Gaps this narrow (m) between occupied cells let no gain ray through (holes a
            lidar leaves in a wall seen from far or at a grazing angle: else a goal by such a wall
            counted the unknown outside the building as its gain, and drew the robot back there).
        small_frontier_m: Once nothing above the thresholds is left, frontiers down to this length
            (m), ...
        small_unknown_m2: ... onto unknown patches down to this area (m^2), ...
        small_gain_m2: ... revealing at least this (m^2) are offered (:meth:`small_candidates`).
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
        window_margin_m: Unknown margin (m) kept round the known cells' box (:meth:`window`).
        window_step_m: The window's edges are snapped outwards to this step (m), so that it changes
            seldom (the costmap kept between calls starts over when it does).
        room_m2: For ``gain``, a frontier onto an unknown region at least this large (m^2; or one
            open to the unseen rest of the map) is always worth a trip: a room, or a room's part.
        door_m: ... and so is one at least this long (m) onto a region of ``closet_m2`` or more
            that the body fits into (a doorway onto a small room: a closet, a WC).
        worth_m2_per_m: Other frontiers (pockets behind furniture, slivers along walls, corners) are
            worth a trip only when they reveal this much (m^2) per metre of path; the rest are
            left as *slivers* (:attr:`slivers`), counted and named when the exploration ends.
        slivers: The frontiers the last ranking left as not worth a trip (:meth:`candidates`).
        order: For ``gain``, the order the candidates are offered in: ``score`` (the best gain
            against path, one step ahead) or ``tour`` (the first stop of the tour reaching the most
            value soonest, :mod:`missiontree.mapping.tour`; slower on large dev apartments, so not
            the default: see docs/search.md).
        tour_stops: The tour is planned over this many candidates (the best and the nearest).
        tour_stop_m: What each stop costs the tour beside its path (m): stopping, re-planning and
            looking take time, so a small place beside the way is not a free stop.
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
    gain_gap_m: float = 0.35
    small_frontier_m: float = 0.2
    small_unknown_m2: float = 0.2
    small_gain_m2: float = 0.3
    reach_radius: float | None = None
    max_attempts: int = 3
    retry_separation: float = 0.5
    through_m: float = 0.6
    retry_discount: float = 0.5
    path_lengths: PathLengths = field(default_factory=KeptCostmapLengths)
    window_margin_m: float = 1.0
    window_step_m: float = 2.0
    room_m2: float = 4.0
    door_m: float = 0.6
    closet_m2: float = 1.0
    worth_m2_per_m: float = 0.2
    order: str = "score"
    tour_stops: int = 8
    tour_stop_m: float = 3.0
    blacklist: list[Blacklisted] = field(default_factory=list)
    visited: list[tuple[float, float]] = field(default_factory=list)
    failures: list[Blacklisted] = field(default_factory=list)
    slivers: list[Sliver] = field(default_factory=list)

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
                   ignore_blacklist: bool = False, ordered: bool = True) -> list[Candidate]:
        """Reachable, not blacklisted goals, best first (empty: nothing reachable is left to explore).

        ``ignore_blacklist``: offer blacklisted places too (what :meth:`left_open` checks).
        ``ordered``: in :attr:`order` (else by score; a subclass re-scoring them orders them itself).
        """
        if ignore_blacklist:
            kept, self.blacklist = self.blacklist, []
            try:
                return self.candidates(grid, robot_xy)
            finally:
                self.blacklist = kept
        self.slivers = []
        out = self._ranked(grid, robot_xy)
        if not out and self.strategy != "scan_points":
            out = self.small_candidates(grid, robot_xy)
        return self.in_order(grid, robot_xy, out) if ordered else out

    def in_order(self, grid: OccupancyGrid, robot_xy: tuple[float, float],
                 found: list[Candidate]) -> list[Candidate]:
        """``found`` (best score first) in :attr:`order`: for ``tour``, the tour's first stop first.

        The tour runs over the ``tour_stops`` best candidates and the three nearest; each one's
        value is its score without the path's discount (gain, prior, retry discount), so the tour
        weighs the same things the score does, over the whole trip instead of one step.
        """
        if self.order != "tour" or self.strategy != "gain" or len(found) < 2:
            return found
        head = found[: self.tour_stops]
        head += sorted(found[self.tour_stops:], key=lambda c: c.path_m)[:3]
        values = np.array([max(c.score, 0.0) * math.exp(min(self.cost_rate * c.path_m, 50.0)) for c in head])
        start = np.array([c.path_m for c in head], float)
        between = between_lengths(self.window(grid), [(c.x, c.y) for c in head], start) + self.tour_stop_m
        order = [head[i] for i in latency_order(values, start, between)]
        return order + [c for c in found if all(c is not h for h in head)]

    def small_candidates(self, grid: OccupancyGrid, robot_xy: tuple[float, float]) -> list[Candidate]:
        """The candidates the size thresholds left out (``small_*``): the last things to explore.

        Offered once nothing above the thresholds is left: short frontiers onto unknown pockets
        (behind furniture, a room's corner seen past a door jamb) and patches the beams of far
        scans left unknown. Ending "explored" while they were still reachable was ending with area
        unseen (a room seen from its door 79 % known).
        """
        kept = (self.min_frontier_m, self.min_unknown_m2, self.min_gain_m2)
        self.min_frontier_m = min(self.min_frontier_m, self.small_frontier_m)
        self.min_unknown_m2 = min(self.min_unknown_m2, self.small_unknown_m2)
        self.min_gain_m2 = min(self.min_gain_m2, self.small_gain_m2)
        try:
            return self._ranked(grid, robot_xy)
        finally:
            self.min_frontier_m, self.min_unknown_m2, self.min_gain_m2 = kept

    def window(self, grid: OccupancyGrid) -> OccupancyGrid:
        """The part of ``grid`` the planner works on: its known cells' box with an unknown margin.

        The box is padded by ``window_margin_m`` and snapped outwards to ``window_step_m`` (cut at
        the grid's border); the same grid object when that is the whole grid. Kept for the last
        grid given.
        """
        cached = self.__dict__.get("_window")
        if cached is not None and cached[0] is grid:
            return cached[1]
        out = known_window(grid, self.window_margin_m, self.window_step_m)
        self.__dict__["_window"] = (grid, out)
        return out

    def _ranked(self, grid: OccupancyGrid, robot_xy: tuple[float, float]) -> list[Candidate]:
        """Candidates at the current thresholds, best first."""
        grid = self.window(grid)
        raw, grid = grid, self.close_wall_gaps(grid)
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
        lengths = self.path_lengths(grid, robot_xy, [(p[0], p[1]) for p in points], self.nav_radius)
        reachable = [(p, length) for p, length in zip(points, lengths, strict=True) if length is not None]
        if not reachable:
            return []
        xy = np.array([[p[0], p[1]] for p, _ in reachable], np.float64)
        gapped = self.close_wall_gaps(raw, self.gain_gap_m)
        gains = visible_unknown_area(gapped, xy, self.sensor_range,
                                     self.gain_beams) if kind == "frontier" else np.zeros(len(reachable))
        regions = _Regions(gapped, self.nav_radius) if self.strategy == "gain" else None
        out = []
        for (p, length), gain in zip(reachable, gains, strict=True):
            if self.strategy == "gain" and gain < self.min_gain_m2:
                continue
            failed = len(self.tries((p[3], p[4]))) if kind == "frontier" and self.failures else 0
            c = Candidate(p[0], p[1], kind, int(p[2]), float(gain), float(length),
                          self._score(float(gain), float(length), int(p[2]), failed), (p[3], p[4]))
            if regions is not None and not self._worth_trip(c, regions, grid.resolution):
                continue
            out.append(c)
        out.sort(key=lambda c: (-c.score, c.path_m, c.x, c.y))
        return out

    def _worth_trip(self, c: Candidate, regions: _Regions, resolution: float) -> bool:
        """Whether frontier ``c`` is worth a trip (``gain``); a frontier that is not is kept as a sliver.

        Worth it: a frontier onto unknown open to the unseen rest of the map or at least ``room_m2``
        large (a room or a room's part); one at least ``door_m`` long onto a region of ``closet_m2``
        the body fits into (a doorway onto a small room); else one revealing ``worth_m2_per_m`` per
        metre of path (a pocket behind furniture, a sliver along a wall: on the robot's way, or never).
        """
        label, area, fits = regions.behind(c.target)
        if area >= self.room_m2 or (fits and area >= self.closet_m2 and c.size * resolution >= self.door_m):
            return True
        if c.gain_m2 >= self.worth_m2_per_m * max(c.path_m, 1.0):
            return True
        if not any(math.dist(s.candidate.target, c.target) < 1e-6 for s in self.slivers):
            self.slivers.append(Sliver(c, label, area))  # the small pass meets it again
        return False

    def sliver_area(self) -> float:
        """Unknown area (m^2) of the regions behind the slivers the last ranking left (each region once)."""
        seen: dict[int, float] = {}
        loose = 0.0
        for s in self.slivers:
            if s.region == 0:
                loose += s.candidate.gain_m2
            else:
                seen[s.region] = s.unknown_m2
        return loose + sum(seen.values())

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
        blacklist, self.blacklist = self.blacklist, []
        slivers = self.slivers   # those of the robot's own ranking stay
        try:
            out = self.candidates(grid, robot_xy)
            if out and self.strategy != "scan_points":  # the small ones too: they may be blacklisted
                out += self.small_candidates(grid, robot_xy)
            return out
        finally:
            self.footprint_radius, self.blacklist, self.slivers = kept, blacklist, slivers

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
        grid = self.close_wall_gaps(self.window(grid))
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


class _Regions:
    """The unknown regions of one ranking's map: each one's area, whether it is open, whether the body fits.

    ``grid`` is the map with the gain gaps closed (the holes a lidar leaves in walls do not join a
    pocket to the outside). A region touching the map's edge is open (the unseen rest of the map).
    """

    def __init__(self, grid: OccupancyGrid, body_radius: float) -> None:
        self.grid = grid
        unknown = grid.data < 0
        self.labels, n = ndimage.label(unknown, structure=ndimage.generate_binary_structure(2, 1))
        cell = grid.resolution ** 2
        self.area = np.bincount(self.labels.ravel(), minlength=n + 1).astype(np.float64) * cell
        lab = self.labels
        edge = np.unique(np.concatenate([lab[0], lab[-1], lab[:, 0], lab[:, -1]]))
        self.area[edge[edge > 0]] = np.inf
        occupied = occupied_mask(grid)
        clearance = cv2.distanceTransform((~occupied).astype(np.uint8), cv2.DIST_L2, 5) * grid.resolution
        self.fits = np.zeros(n + 1, bool)
        if n:
            best = ndimage.maximum(clearance, self.labels, np.arange(1, n + 1))
            self.fits[1:] = np.asarray(best) >= body_radius

    def behind(self, target: tuple[float, float], reach: int = 2) -> tuple[int, float, bool]:
        """(label, area m^2, body fits) of the largest unknown region within ``reach`` cells of ``target``."""
        r, c = self.grid.world_to_cell(*target)
        h, w = self.labels.shape
        box = self.labels[max(0, r - reach): min(h, r + reach + 1), max(0, c - reach): min(w, c + reach + 1)]
        found = [int(v) for v in np.unique(box) if v]
        if not found:
            return 0, 0.0, False
        label = max(found, key=lambda v: self.area[v])
        return label, float(self.area[label]), bool(self.fits[found].any())
