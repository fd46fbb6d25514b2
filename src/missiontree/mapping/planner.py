"""A global planner whose cost follows the path, not the map: A* and Dijkstra on a lazily inflated costmap.

The costmap follows Nav2's conventions: lethal cells (occupancy >= 50) cost 254, the inscribed zone
as wide as the robot's radius around them 253 (a robot centred there touches the obstacle), and an
inflation cost decaying as ``252 * exp(-cost_scaling * (d - radius))`` out to ``inflation_radius``.
Unknown cells (-1) are free when ``allow_unknown`` (as Nav2's planner with a SLAM map) and do not
inflate; otherwise they are blocked (255, Nav2's NO_INFORMATION).

Nothing here is whole-grid. The map is cut into tiles of 64 x 64 cells; a tile's costs are computed
the first time a search reaches it (a distance transform of the tile and a margin around it) and
kept until the map changes there (:meth:`Costmap.update` invalidates only the tiles within the
inflation radius of the changed cells). A search keeps its state (cost so far, length so far, the
step that reached a cell) in tiles allocated as it reaches them, and its open list grows on demand,
so a plan's time and memory grow with the area it explores. The search runs in a numba kernel (a
plain-Python fallback when numba is missing) that hands back to Python whenever it needs a cost
tile or more room, then resumes where it stopped.

A* is guided by a coarse distance: a Dijkstra over blocks of 8 x 8 cells (a block is closed when
it holds an obstacle cell) from the goal until the start's block is reached, so that the search
does not flood every aisle that points at the goal; where that guide says less than the octile
distance, the octile distance is used. The heuristic is weighted by ``HEURISTIC_WEIGHT`` (1.2):
on a 30 x 50 m warehouse at 3 cm the paths came out 1-2 % longer (median) than optimal ones for a
fraction of the expansions (``benchmarks/planner.py``). :meth:`Costmap.path_lengths` is an exact
Dijkstra (no heuristic) to all goals at once; it stops when the last goal is settled.

Use :class:`Costmap` (kept between plans, updated in place) for repeated planning, or the one-shot
functions :func:`plan` and :func:`path_lengths` on an :class:`~missiontree.types.OccupancyGrid`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from missiontree.mapping.grid_search import (
    BLOCK,
    BLOCK_BITS,
    CLOSED,
    FOUND,
    HAVE_NUMBA,
    INSCRIBED,
    LETHAL,
    MAX_FREE,
    NEED_COST,
    NEED_HEAP,
    NEED_STATE,
    NO_INFORMATION,
    S_EXPANDED,
    S_HEAP,
    S_LEFT,
    S_SLOTS,
    S_TILE,
    START,
    TILE,
    TILE_BITS,
    TILE_MASK,
    coarse_jit,
    coarse_loops,
    search_jit,
    search_loops,
    trace_jit,
    trace_loops,
)
from missiontree.mapping.occupancy import BLOCKED_FROM
from missiontree.types import OccupancyGrid, Pose2D

#: Weighted A*: the heuristic counts this much (1.0 is optimal; 1.2 expands ~20x fewer cells on a
#: warehouse map for paths within a few per cent of the optimum's length, never worse than 1.2x its cost).
HEURISTIC_WEIGHT = 1.2
_NO_COARSE = np.full((1, 1), np.inf, np.float32)
_DETOUR_RATIO, _DETOUR_SLACK = 1.3, 1.0   # a guided path longer than this x the straight line + slack (m)


@dataclass(frozen=True)
class Path:
    """A planned path.

    Attributes:
        points: (N, 2) map points from the start to the goal (cell centres in between).
        length: Length of the polyline in metres.
        cost: The search's cost (length weighted by the inflation cost crossed).
        expanded: Cells the search expanded (how much of the map it touched).
    """

    points: np.ndarray
    length: float
    cost: float
    expanded: int


class Costmap:
    """A Nav2-style inflated costmap computed tile by tile when first needed, updated in place.

    Args:
        grid: The occupancy grid (-1 unknown, 0 free .. 100 occupied). Its ``data`` is read, not
            copied: after changing it, call :meth:`update` with the changed region (or the new grid).
        robot_radius: Footprint radius in metres (the inscribed zone).
        inflation_radius: How far inflation cost reaches from an obstacle, metres.
        cost_scaling: How fast inflation cost decays with distance.
        allow_unknown: Unknown cells are free (True, as with a SLAM map) or blocked.
        accelerate: Use the numba kernel when numba is installed.
        extra_lethal: (N, 2) map points made lethal as discs of ``extra_radius`` (people seen by
            the lidar, obstacles not in the map); see :meth:`with_points`.
    """

    def __init__(self, grid: OccupancyGrid, robot_radius: float, inflation_radius: float = 0.45,
                 cost_scaling: float = 3.0, allow_unknown: bool = True, accelerate: bool = True,
                 extra_lethal: np.ndarray | None = None, extra_radius: float = 0.08) -> None:
        self.grid = grid
        self.radius = float(robot_radius)
        self.inflation_radius = float(inflation_radius)
        self.cost_scaling = float(cost_scaling)
        self.allow_unknown = allow_unknown
        self.accelerate = accelerate and HAVE_NUMBA
        self.extra_lethal = np.zeros((0, 2)) if extra_lethal is None else np.asarray(extra_lethal, float)
        self.extra_radius = extra_radius
        self.heuristic_weight = HEURISTIC_WEIGHT
        self._reset_tiles()

    def _reset_tiles(self) -> None:
        h, w = self.grid.data.shape
        self.shape = (h, w)
        self.ntr, self.ntc = (h + TILE - 1) >> TILE_BITS, (w + TILE - 1) >> TILE_BITS
        self._pad = int(math.ceil(max(self.inflation_radius, self.radius) / self.grid.resolution)) + 2
        self.cost_slot = np.full(self.ntr * self.ntc, -1, np.int32)
        self.cost_pool = np.zeros((8, TILE, TILE), np.uint8)
        self._free_slots: list[int] = list(range(7, -1, -1))
        self.tiles_computed = 0
        self._blocks: np.ndarray | None = None  # per 8 x 8 block: holds a lethal cell (A*'s guide)

    def _coarse(self) -> np.ndarray:
        """Blocks of 8 x 8 cells that hold an obstacle (computed once, then kept up to date)."""
        if self._blocks is None:
            h, w = self.shape
            rows, cols = (h + BLOCK - 1) >> BLOCK_BITS, (w + BLOCK - 1) >> BLOCK_BITS
            self._blocks = np.zeros((rows, cols), np.bool_)
            for r0 in range(0, h, 64 * BLOCK):  # in stripes: no whole-grid temporaries
                self._refresh_blocks(r0, min(r0 + 64 * BLOCK, h), 0, w)
        return self._blocks

    def _refresh_blocks(self, r0: int, r1: int, c0: int, c1: int) -> None:
        assert self._blocks is not None
        h, w = self.shape
        br0, bc0 = max(r0, 0) >> BLOCK_BITS, max(c0, 0) >> BLOCK_BITS
        br1, bc1 = (min(r1, h) + BLOCK - 1) >> BLOCK_BITS, (min(c1, w) + BLOCK - 1) >> BLOCK_BITS
        if br1 <= br0 or bc1 <= bc0:
            return
        window = self.grid.data[br0 * BLOCK: br1 * BLOCK, bc0 * BLOCK: bc1 * BLOCK]
        bad = window >= BLOCKED_FROM
        if not self.allow_unknown:
            bad |= window < 0
        ph, pw = (br1 - br0) * BLOCK, (bc1 - bc0) * BLOCK
        if bad.shape != (ph, pw):
            bad = np.pad(bad, ((0, ph - bad.shape[0]), (0, pw - bad.shape[1])))
        self._blocks[br0:br1, bc0:bc1] = bad.reshape(br1 - br0, BLOCK, bc1 - bc0, BLOCK).any(axis=(1, 3))

    # -- the map -----------------------------------------------------------------------------------

    def update(self, grid: OccupancyGrid, region: tuple[int, int, int, int] | None = None) -> None:
        """Take a changed map: recompute only the tiles near ``region`` (row0, row1, col0, col1; ends out).

        A grid of another shape, resolution or origin starts over. Without ``region`` every tile
        is invalidated (computed again when next needed).
        """
        old = self.grid
        self.grid = grid
        if (grid.data.shape != old.data.shape or grid.resolution != old.resolution
                or grid.origin.x != old.origin.x or grid.origin.y != old.origin.y):
            self._reset_tiles()
            return
        if region is None:
            self._invalidate(0, self.shape[0], 0, self.shape[1])
            self._blocks = None
            return
        r0, r1, c0, c1 = region
        self._invalidate(r0 - self._pad, r1 + self._pad, c0 - self._pad, c1 + self._pad)
        if self._blocks is not None:
            self._refresh_blocks(r0, r1, c0, c1)

    def update_changed(self, grid: OccupancyGrid) -> None:
        """Take a new version of the map and find what changed: only the tiles near changed cells recompute.

        Costs depend on which cells are lethal (and, without ``allow_unknown``, unknown); the tiles
        holding a cell whose class changed, and their neighbours within the inflation reach, are
        invalidated. A grid of another shape, resolution or origin starts over. For callers that
        get whole snapshots of a growing map (the exploration planner) and do not know the region.
        """
        old = self.grid
        if (grid.data.shape != old.data.shape or grid.resolution != old.resolution
                or grid.origin.x != old.origin.x or grid.origin.y != old.origin.y):
            self.update(grid)
            return
        self.grid = grid
        if grid.data is old.data:
            return
        changed = (grid.data >= BLOCKED_FROM) != (old.data >= BLOCKED_FROM)
        if not self.allow_unknown:
            changed |= (grid.data < 0) != (old.data < 0)
        if not changed.any():
            return
        h, w = self.shape
        padded = np.zeros((self.ntr * TILE, self.ntc * TILE), bool)
        padded[:h, :w] = changed
        per_tile = padded.reshape(self.ntr, TILE, self.ntc, TILE).any(axis=(1, 3))
        touched: np.ndarray = np.ascontiguousarray(per_tile, dtype=np.uint8)
        reach = -(-self._pad // TILE)   # tiles the inflation of a changed cell can reach into
        kernel = np.ones((2 * reach + 1, 2 * reach + 1), np.uint8)
        tiles = cv2.dilate(touched, kernel).astype(bool)
        slots = self.cost_slot.reshape(self.ntr, self.ntc)
        hit = tiles & (slots >= 0)
        self._free_slots.extend(slots[hit].tolist())
        slots[hit] = -1
        if self._blocks is not None:   # A*'s coarse guide, where the map changed
            rows, cols = np.flatnonzero(changed.any(axis=1)), np.flatnonzero(changed.any(axis=0))
            self._refresh_blocks(int(rows[0]), int(rows[-1]) + 1, int(cols[0]), int(cols[-1]) + 1)

    def _invalidate(self, r0: int, r1: int, c0: int, c1: int) -> None:
        tr0, tr1 = max(r0, 0) >> TILE_BITS, (min(r1, self.shape[0]) - 1) >> TILE_BITS
        tc0, tc1 = max(c0, 0) >> TILE_BITS, (min(c1, self.shape[1]) - 1) >> TILE_BITS
        if tr1 < tr0 or tc1 < tc0:
            return
        block = self.cost_slot.reshape(self.ntr, self.ntc)[tr0:tr1 + 1, tc0:tc1 + 1]
        for slot in block[block >= 0].tolist():
            self._free_slots.append(slot)
        block[...] = -1

    def with_points(self, points: np.ndarray, radius: float = 0.08) -> Costmap:
        """A costmap of the same map with extra lethal discs at ``points`` (N, 2), for one replan.

        It starts from a copy of this costmap's tiles, all but those near the points (so a replan
        costs what a plan costs); lethal points already added here (:meth:`add_lethal`) stay lethal.
        """
        new = np.asarray(points, float).reshape(-1, 2)
        extra = np.concatenate([self.extra_lethal, new])
        other = Costmap(self.grid, self.radius, self.inflation_radius, self.cost_scaling, self.allow_unknown,
                        self.accelerate, extra, max(radius, self.extra_radius))
        other.cost_slot = self.cost_slot.copy()
        other.cost_pool = self.cost_pool.copy()
        other._free_slots = list(self._free_slots)
        other._blocks = None if self._blocks is None else self._blocks.copy()
        if other.extra_radius != self.extra_radius:
            other._invalidate_points(self.extra_lethal)
        other._invalidate_points(new)
        return other

    def add_lethal(self, points: np.ndarray) -> None:
        """Make discs of ``extra_radius`` at ``points`` (N, 2) lethal from now on (e.g. bumper hits)."""
        pts = np.asarray(points, float).reshape(-1, 2)
        if not len(pts):
            return
        self.extra_lethal = np.concatenate([self.extra_lethal, pts])
        self._invalidate_points(pts)

    def set_lethal(self, points: np.ndarray) -> None:
        """Replace the extra lethal points (those dropped stop costing at once)."""
        old = self.extra_lethal
        self.extra_lethal = np.asarray(points, float).reshape(-1, 2)
        self._invalidate_points(old)
        if self._blocks is not None and len(old):
            self._blocks = None  # recomputed from the map when next needed
        self._invalidate_points(self.extra_lethal)

    def _invalidate_points(self, pts: np.ndarray) -> None:
        res = self.grid.resolution
        reach = int(math.ceil(self.extra_radius / res)) + 1
        for x, y in pts.tolist():
            row, col = self.grid.world_to_cell(x, y)
            self._invalidate(row - reach - self._pad, row + reach + self._pad + 1,
                             col - reach - self._pad, col + reach + self._pad + 1)
            if self._blocks is not None:
                self._blocks[max(row, 0) >> BLOCK_BITS: (max(row, 0) >> BLOCK_BITS) + 1,
                             max(col, 0) >> BLOCK_BITS: (max(col, 0) >> BLOCK_BITS) + 1] = True

    def ensure_tile(self, tile: int) -> None:
        """Compute the costs of tile ``tile`` (row-major tile index) if not yet known."""
        if self.cost_slot[tile] >= 0:
            return
        if not self._free_slots:
            n = self.cost_pool.shape[0]
            self.cost_pool = np.concatenate([self.cost_pool, np.zeros((n, TILE, TILE), np.uint8)])
            self._free_slots = list(range(2 * n - 1, n - 1, -1))
        slot = self._free_slots.pop()
        self.cost_pool[slot] = self._tile_costs(tile)
        self.cost_slot[tile] = slot
        self.tiles_computed += 1

    def _tile_costs(self, tile: int) -> np.ndarray:
        tr, tc = divmod(tile, self.ntc)
        h, w = self.shape
        res, pad = self.grid.resolution, self._pad
        r0, c0 = tr * TILE, tc * TILE
        r1, c1 = min(r0 + TILE, h), min(c0 + TILE, w)
        wr0, wc0, wr1, wc1 = max(r0 - pad, 0), max(c0 - pad, 0), min(r1 + pad, h), min(c1 + pad, w)
        window = self.grid.data[wr0:wr1, wc0:wc1]
        lethal = window >= BLOCKED_FROM
        if len(self.extra_lethal):
            lethal = lethal.copy()
            self._stamp_points(lethal, wr0, wc0)
        out = np.zeros((TILE, TILE), np.uint8)
        inner = (slice(r0 - wr0, r1 - wr0), slice(c0 - wc0, c1 - wc0))
        if lethal.any():
            dist = cv2.distanceTransform((~lethal).view(np.uint8), cv2.DIST_L2, 5)[inner] * res
            cost = np.zeros(dist.shape, np.uint8)
            band = (dist <= self.inflation_radius) & (dist >= self.radius)
            cost[band] = (252.0 * np.exp(-self.cost_scaling * (dist[band] - self.radius))).astype(np.uint8)
            cost[dist < self.radius] = INSCRIBED
            cost[lethal[inner]] = LETHAL
        else:
            cost = np.zeros((r1 - r0, c1 - c0), np.uint8)
        if not self.allow_unknown:
            cost[(window[inner] < 0) & (cost < LETHAL)] = NO_INFORMATION
        out[: r1 - r0, : c1 - c0] = cost
        return out

    def _stamp_points(self, lethal: np.ndarray, wr0: int, wc0: int) -> None:
        res = self.grid.resolution
        r_cells = max(1, int(round(self.extra_radius / res)))
        rows = np.floor((self.extra_lethal[:, 1] - self.grid.origin.y) / res).astype(int) - wr0
        cols = np.floor((self.extra_lethal[:, 0] - self.grid.origin.x) / res).astype(int) - wc0
        hh, ww = lethal.shape
        near = (rows >= -r_cells) & (rows < hh + r_cells) & (cols >= -r_cells) & (cols < ww + r_cells)
        if not near.any():
            return
        view = lethal.view(np.uint8)
        for row, col in zip(rows[near].tolist(), cols[near].tolist(), strict=True):
            cv2.circle(view, (col, row), r_cells, 1, -1)

    def cell_cost(self, row: int, col: int) -> int:
        """Cost of a cell; LETHAL outside the map."""
        h, w = self.shape
        if not (0 <= row < h and 0 <= col < w):
            return LETHAL
        tile = (row >> TILE_BITS) * self.ntc + (col >> TILE_BITS)
        self.ensure_tile(tile)
        return int(self.cost_pool[self.cost_slot[tile], row & TILE_MASK, col & TILE_MASK])

    def cost_at(self, x: float, y: float) -> int:
        """Cost at a map point; LETHAL outside the map."""
        return self.cell_cost(*self.grid.world_to_cell(x, y))

    def contains(self, x: float, y: float) -> bool:
        """Whether a map point lies on the grid."""
        row, col = self.grid.world_to_cell(x, y)
        return 0 <= row < self.shape[0] and 0 <= col < self.shape[1]

    def blocked_along(self, points: np.ndarray) -> bool:
        """Whether any of the map ``points`` (N, 2) lies on a cell the robot cannot enter (or off the map)."""
        return bool((self.costs_along(points) > MAX_FREE).any())

    def costs_along(self, points: np.ndarray) -> np.ndarray:
        """The cost (0..254, LETHAL off the map) of the cell under each map point (N, 2), as an int array."""
        pts = np.asarray(points, float).reshape(-1, 2)
        if not len(pts):
            return np.zeros(0, np.int64)
        res, origin = self.grid.resolution, self.grid.origin
        rows = np.floor((pts[:, 1] - origin.y) / res).astype(np.int64)
        cols = np.floor((pts[:, 0] - origin.x) / res).astype(np.int64)
        h, w = self.shape
        outside = (rows < 0) | (rows >= h) | (cols < 0) | (cols >= w)
        costs = np.full(len(pts), LETHAL, np.int64)
        inside = ~outside
        if inside.any():
            r, c = rows[inside], cols[inside]
            tiles = (r >> TILE_BITS) * self.ntc + (c >> TILE_BITS)
            for tile in np.unique(tiles).tolist():
                self.ensure_tile(tile)
            costs[inside] = self.cost_pool[self.cost_slot[tiles], r & TILE_MASK, c & TILE_MASK]
        return costs

    def dense(self) -> np.ndarray:
        """The whole cost array (every tile computed): for pictures and tests, not for planning."""
        for tile in range(self.ntr * self.ntc):
            self.ensure_tile(tile)
        h, w = self.shape
        tiles = self.cost_pool[self.cost_slot].reshape(self.ntr, self.ntc, TILE, TILE)
        return tiles.transpose(0, 2, 1, 3).reshape(self.ntr * TILE, self.ntc * TILE)[:h, :w].copy()

    # -- searching ---------------------------------------------------------------------------------

    def _run(self, start_cell: tuple[int, int], goal_cells: np.ndarray, heuristic: bool,
             weight: float, guide: bool = True) -> tuple[_SearchState, int]:
        h, w = self.shape
        sr, sc = start_cell
        s = _SearchState(self.ntr * self.ntc)
        start = sr * w + sc
        tile = (sr >> TILE_BITS) * self.ntc + (sc >> TILE_BITS)
        s.g_slot[tile] = 0
        s.state[S_SLOTS] = 1
        s.g_pool[0] = np.inf
        s.par_pool[0] = -1
        off = (sr & TILE_MASK) * TILE + (sc & TILE_MASK)
        s.g_pool[0, off], s.l_pool[0, off], s.par_pool[0, off] = 0.0, 0.0, START
        s.heap_k[0], s.heap_v[0], s.state[S_HEAP] = 0.0, start, 1
        s.state[S_LEFT] = len(goal_cells)
        escape = int(math.ceil((self.radius + 0.1) / self.grid.resolution))
        escape2 = escape * escape if self.cell_cost(sr, sc) >= INSCRIBED else -1
        fn = search_jit if self.accelerate else search_loops
        coarse, cfar = _NO_COARSE, 0.0
        if heuristic:
            blocks = self._coarse()
            coarse = np.full(blocks.shape, np.inf, np.float32)
            n = blocks.size
            g_row, g_col = divmod(int(goal_cells[0]), w)
            gb = (g_row >> BLOCK_BITS) * blocks.shape[1] + (g_col >> BLOCK_BITS)
            sb = (sr >> BLOCK_BITS) * blocks.shape[1] + (sc >> BLOCK_BITS)
            cfn = coarse_jit if self.accelerate else coarse_loops
            heap_k, heap_v = np.empty(4 * n + 16, np.float32), np.empty(4 * n + 16, np.int64)
            cfar = float(cfn(blocks, gb, sb, coarse, heap_k, heap_v))
            if not guide or not math.isfinite(cfar):  # no way round at block scale (a narrow door): octile
                coarse.fill(np.inf)
                cfar = 0.0
        while True:
            code = fn(self.cost_slot, self.cost_pool, s.g_slot, s.g_pool, s.l_pool, s.par_pool, s.heap_k,
                      s.heap_v, s.state, h, w, self.ntc, sr, sc, escape2, goal_cells, weight, heuristic,
                      self.heuristic_weight, coarse, cfar)
            if code == NEED_COST:
                self.ensure_tile(int(s.state[S_TILE]))
            elif code == NEED_STATE:
                s.grow_state()
            elif code == NEED_HEAP:
                s.grow_heap()
            else:
                return s, code

    def plan(self, start: Pose2D | tuple[float, float], goal: Pose2D | tuple[float, float],
             cost_weight: float = 3.0) -> Path | None:
        """A* from ``start`` to ``goal`` (map points); None when no path exists or either is off the map.

        The start may lie in the inscribed zone (the robot leaves it); the goal must be enterable.
        """
        sx, sy = _xy(start)
        gx, gy = _xy(goal)
        sr, sc = self.grid.world_to_cell(sx, sy)
        gr, gc = self.grid.world_to_cell(gx, gy)
        h, w = self.shape
        if not (0 <= sr < h and 0 <= sc < w and 0 <= gr < h and 0 <= gc < w):
            return None
        if self.cell_cost(sr, sc) >= LETHAL or self.cell_cost(gr, gc) > MAX_FREE:
            return None
        path = self._search(sr, sc, gr, gc, cost_weight, True)
        if path is not None and path.length > _DETOUR_RATIO * math.hypot(gx - sx, gy - sy) + _DETOUR_SLACK:
            # the coarse guide counts a block holding any obstacle cell as closed, so a doorway
            # narrower than two blocks (0.8 m at 5 cm) can be closed at its scale while the way
            # round is open: its estimate then overstates the way through the door and the search
            # took the way round (13 m for 3 m beside a 0.5 m gap). A detour is checked unguided.
            plain = self._search(sr, sc, gr, gc, cost_weight, False)
            if plain is not None and plain.cost < path.cost:
                path = plain
        if path is None:
            return None
        pts = path.points
        pts[0] = (sx, sy)
        pts[-1] = (gx, gy)
        length = float(np.hypot(*np.diff(pts, axis=0).T).sum()) if len(pts) > 1 else 0.0
        return Path(pts, length, path.cost, path.expanded)

    def _search(self, sr: int, sc: int, gr: int, gc: int, cost_weight: float, guide: bool) -> Path | None:
        """One A* from cell (sr, sc) to cell (gr, gc): the path through cell centres, or None."""
        w = self.shape[1]
        goal_cell = gr * w + gc
        s, code = self._run((sr, sc), np.array([goal_cell], np.int64), True, cost_weight, guide)
        if code != FOUND:
            return None
        trace = trace_jit if self.accelerate else trace_loops
        cells = trace(s.g_slot, s.par_pool, w, self.ntc, sr * w + sc, goal_cell)[::-1]
        rows, cols = cells // w, cells % w
        res, origin = self.grid.resolution, self.grid.origin
        pts = np.stack([origin.x + (cols + 0.5) * res, origin.y + (rows + 0.5) * res], axis=1)
        length = float(np.hypot(*np.diff(pts, axis=0).T).sum()) if len(pts) > 1 else 0.0
        slot, off = s.lookup(gr, gc, self.ntc)
        return Path(pts, length, float(s.g_pool[slot, off]), int(s.state[S_EXPANDED]))

    def path_lengths(self, start: Pose2D | tuple[float, float],
                     goals: Sequence[Pose2D | tuple[float, float]],
                     cost_weight: float = 3.0) -> list[float | None]:
        """Length in metres of the best path from ``start`` to each goal (None: unreachable); one search."""
        sx, sy = _xy(start)
        sr, sc = self.grid.world_to_cell(sx, sy)
        h, w = self.shape
        out: list[float | None] = [None] * len(goals)
        if not (0 <= sr < h and 0 <= sc < w) or self.cell_cost(sr, sc) >= LETHAL:
            return out
        cells: dict[int, list[int]] = {}
        for i, goal in enumerate(goals):
            gr, gc = self.grid.world_to_cell(*_xy(goal))
            if 0 <= gr < h and 0 <= gc < w and self.cell_cost(gr, gc) <= MAX_FREE:
                cells.setdefault(gr * w + gc, []).append(i)
        if not cells:
            return out
        goal_cells = np.array(sorted(cells), np.int64)
        s, _ = self._run((sr, sc), goal_cells, False, cost_weight)
        res = self.grid.resolution
        for cell, idx in cells.items():
            slot, off = s.lookup(cell // w, cell % w, self.ntc)
            if slot >= 0 and s.par_pool[slot, off] >= CLOSED:
                cx, cy = self.grid.cell_to_world(cell // w, cell % w)
                for i in idx:
                    # cell steps in metres, plus the goal point's offset from its cell centre
                    gx, gy = _xy(goals[i])
                    out[i] = float(s.l_pool[slot, off]) * res + math.hypot(gx - cx, gy - cy)
        return out


class _SearchState:
    """The per-search arrays, in tiles allocated as the search reaches them."""

    def __init__(self, n_tiles: int, slots: int | None = None, heap: int = 1 << 14) -> None:
        # room for every tile up front: np.empty only reserves it (pages are touched as the search
        # reaches tiles), where growing by copies cost ~10 ms a time on a 30 x 50 m map
        slots = n_tiles + 4 if slots is None else slots
        self.g_slot = np.full(n_tiles, -1, np.int32)
        self.g_pool = np.empty((slots, TILE * TILE), np.float32)
        self.l_pool = np.empty((slots, TILE * TILE), np.float32)
        self.par_pool = np.empty((slots, TILE * TILE), np.int8)
        self.heap_k = np.empty(heap, np.float32)
        self.heap_v = np.empty(heap, np.int64)
        self.state = np.zeros(8, np.int64)

    def grow_state(self) -> None:
        n = self.g_pool.shape[0]
        self.g_pool = np.concatenate([self.g_pool, np.empty_like(self.g_pool)])
        self.l_pool = np.concatenate([self.l_pool, np.empty_like(self.l_pool)])
        self.par_pool = np.concatenate([self.par_pool, np.empty_like(self.par_pool)])
        assert self.g_pool.shape[0] == 2 * n

    def grow_heap(self) -> None:
        self.heap_k = np.concatenate([self.heap_k, np.empty_like(self.heap_k)])
        self.heap_v = np.concatenate([self.heap_v, np.empty_like(self.heap_v)])

    def lookup(self, row: int, col: int, ntc: int) -> tuple[int, int]:
        return (int(self.g_slot[(row >> TILE_BITS) * ntc + (col >> TILE_BITS)]),
                (row & TILE_MASK) * TILE + (col & TILE_MASK))


def _xy(p: Pose2D | tuple[float, float]) -> tuple[float, float]:
    if isinstance(p, Pose2D):
        return p.x, p.y
    return float(p[0]), float(p[1])


def plan(grid: OccupancyGrid | Costmap, start: Pose2D | tuple[float, float],
         goal: Pose2D | tuple[float, float],
         footprint_radius: float = 0.17, allow_unknown: bool = True, inflation_radius: float = 0.45,
         cost_scaling: float = 3.0) -> Path | None:
    """Plan once on ``grid`` (or on a kept :class:`Costmap`, whose settings then apply); None when no path."""
    costmap = grid if isinstance(grid, Costmap) else Costmap(
        grid, footprint_radius, inflation_radius, cost_scaling, allow_unknown)
    return costmap.plan(start, goal)


def path_lengths(grid: OccupancyGrid | Costmap, start: Pose2D | tuple[float, float],
                 goals: Sequence[Pose2D | tuple[float, float]], footprint_radius: float = 0.17,
                 allow_unknown: bool = True, inflation_radius: float = 0.45,
                 cost_scaling: float = 3.0) -> list[float | None]:
    """Path length in metres from ``start`` to every goal (None where unreachable), in one Dijkstra search."""
    costmap = grid if isinstance(grid, Costmap) else Costmap(
        grid, footprint_radius, inflation_radius, cost_scaling, allow_unknown)
    return costmap.path_lengths(start, goals)
