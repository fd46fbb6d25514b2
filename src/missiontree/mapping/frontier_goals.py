"""Where to send the robot to see a frontier: the exploration planner's goal placement.

:class:`FrontierGoals` is the part of :class:`missiontree.mapping.exploration.ExplorationPlanner`
that turns the map's frontiers into places to stand: back from the frontier in known free space
(clear of everything not known free by the robot's radius plus a margin, in line of sight of it),
through it after a failed try (a doorway: inside the room), or elsewhere away from the places that
failed; and that tells whether a frontier is still there (:meth:`FrontierGoals.still_frontier`).
Unknown gaps in walls are closed first (:func:`missiontree.mapping.frontiers.close_gaps`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np
from scipy import ndimage

from missiontree.mapping.frontiers import Frontier, clear_line, close_gaps, find_frontiers
from missiontree.mapping.grid import free_mask, occupied_mask, unknown_mask
from missiontree.types import OccupancyGrid


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


class FrontierGoals:
    """Goal placement for frontiers (a mixin of the exploration planner, which holds the settings).

    The attributes are the planner's (see :class:`missiontree.mapping.exploration.ExplorationPlanner`).
    """

    footprint_radius: float
    min_frontier_m: float
    min_unknown_m2: float
    frontier_piece_m: float
    goal_margin: float
    approach_m: float
    wall_gap_m: float
    retry_separation: float
    through_m: float
    blacklist_radius: float
    failures: list[Blacklisted]
    reach_radius: float | None

    @property
    def nav_radius(self) -> float:
        """The footprint paths are judged with: the navigation's (``reach_radius``) where it is larger.

        Path lengths use it, so a goal is offered only where the navigation stack also finds a way
        (with the smaller footprint the planner saw ways between furniture that the navigator refused).
        """
        return max(self.footprint_radius, self.reach_radius or 0.0)

    def _near(self, entries: list[Blacklisted], target: tuple[float, float]) -> list[Blacklisted]:
        r2 = self.blacklist_radius ** 2
        return [b for b in entries if (b.target[0] - target[0]) ** 2 + (b.target[1] - target[1]) ** 2 <= r2]

    def close_wall_gaps(self, grid: OccupancyGrid, gap_m: float | None = None) -> OccupancyGrid:
        """The grid with unknown gaps under ``gap_m`` (default ``wall_gap_m``) between occupied cells closed.

        Kept for the last grid given (one per gap width): every question asked about one version of
        the map closes it once.
        """
        gap = self.wall_gap_m if gap_m is None else gap_m
        cache: dict[float, tuple[OccupancyGrid, OccupancyGrid]] = self.__dict__.setdefault("_closed", {})
        cached = cache.get(gap)
        if cached is not None and cached[0] is grid:
            return cached[1]
        out = close_gaps(grid, gap)
        cache[gap] = (grid, out)
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
                if to_occupied[rows[m], cols[m]] < self.nav_radius:
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
            if clear_line(occupied, (int(sr[j]), int(sc[j])), (int(rows[m]), int(cols[m]))):
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
                if clear_line(occupied, (gr, gc), (r, c)):
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
