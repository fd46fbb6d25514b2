"""The order to visit exploration goals in: a short tour that reaches the most value soonest.

Ranking goals one step ahead (the best gain against the path to it) leaves a pocket beside the
robot for a larger frontier farther on, and comes back for it only after the rest of the floor.
Here the goals on offer are put in the order that minimises the *latency* of what they reveal:
the sum over goals of value x the path driven before it is reached (the minimum-latency tour; for
a search with a prior on where the target lies, the expected path driven before the target comes
into view). A pocket near the robot is then taken before leaving it, because putting it off costs
its value times the whole trip away and back, while a far frontier pays only for the detour.

Path lengths from the robot are the planner's; between goals they are measured on a coarse graph
of the known free space (blocks of ``block_m``; a block holding an occupied cell is closed, so
walls are not cut through), bounded below by the straight line and above by the way round through
the robot. The tour is found by a greedy start and local moves (move one goal elsewhere in the
order, swap two), on at most ``max_stops`` goals; the others follow in their own order.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra

from missiontree.mapping.grid import free_mask, occupied_mask
from missiontree.types import OccupancyGrid

#: Blocks this far (in blocks) round a goal's own block are searched for an open one.
_SNAP_BLOCKS = 3


def tour_latency(order: Sequence[int], values: np.ndarray, start: np.ndarray, between: np.ndarray) -> float:
    """Sum over the goals in ``order`` of value x path length driven before reaching it."""
    total, t, prev = 0.0, 0.0, -1
    for i in order:
        t += start[i] if prev < 0 else between[prev, i]
        total += values[i] * t
        prev = i
    return total


def latency_order(values: np.ndarray, start: np.ndarray, between: np.ndarray) -> list[int]:
    """The order of the goals (indices) with the least :func:`tour_latency`, found by local search.

    Starts from the greedy order (next: the most value per metre from where the last goal left the
    robot), then moves one goal to another place and swaps two while that lowers the latency.
    """
    n = len(values)
    left = list(range(n))
    order: list[int] = []
    while left:
        prev = order[-1] if order else -1
        legs = [max(start[i] if prev < 0 else between[prev, i], 1e-3) for i in left]
        j = max(range(len(left)), key=lambda k: (values[left[k]] / legs[k], -legs[k]))
        order.append(left.pop(j))
    best = tour_latency(order, values, start, between)
    improved = True
    while improved:
        improved = False
        for trial in _moves(order):
            latency = tour_latency(trial, values, start, between)
            if latency < best - 1e-9:
                order, best, improved = trial, latency, True
                break
    return order


def _moves(order: list[int]) -> list[list[int]]:
    """Orders one move away: a goal taken out and put elsewhere, or two goals swapped."""
    n = len(order)
    out = []
    for i in range(n):
        rest = order[:i] + order[i + 1:]
        out += [rest[:j] + [order[i]] + rest[j:] for j in range(n) if j != i]
    for i in range(n):
        for j in range(i + 1, n):
            trial = list(order)
            trial[i], trial[j] = trial[j], trial[i]
            out.append(trial)
    return out


class CoarseGraph:
    """The known free space as a graph of blocks: path lengths between places, walls not cut through.

    A block is open when it holds a known free cell and no occupied cell; open blocks are joined to
    their 8 neighbours (a diagonal only when both blocks beside it are open too).
    """

    def __init__(self, grid: OccupancyGrid, block_m: float = 0.25) -> None:
        self.grid = grid
        self.k = max(1, int(round(block_m / grid.resolution)))
        self.block_m = self.k * grid.resolution
        h, w = grid.data.shape
        hb, wb = -(-h // self.k), -(-w // self.k)
        self.open = _blocks(free_mask(grid), self.k, hb, wb) & ~_blocks(occupied_mask(grid), self.k, hb, wb)
        self.index = -np.ones((hb, wb), np.int64)
        rr, cc = np.nonzero(self.open)
        self.index[rr, cc] = np.arange(len(rr))
        self.graph = self._edges(hb, wb, len(rr))

    def _edges(self, hb: int, wb: int, n: int) -> coo_matrix:
        """The sparse adjacency of the open blocks (edge weights in m)."""
        op = np.pad(self.open, 1)
        idx = np.pad(self.index, 1, constant_values=-1)
        here = op[1:-1, 1:-1]
        rows, cols, weights = [], [], []
        for dr, dc in ((0, 1), (1, 0), (1, 1), (1, -1)):
            there = op[1 + dr: hb + 1 + dr, 1 + dc: wb + 1 + dc]
            both = here & there
            if dr and dc:  # no corner cutting: both blocks beside the diagonal are open too
                both &= op[1 + dr: hb + 1 + dr, 1: wb + 1] & op[1: hb + 1, 1 + dc: wb + 1 + dc]
            r, c = np.nonzero(both)
            rows.append(idx[r + 1, c + 1])
            cols.append(idx[r + 1 + dr, c + 1 + dc])
            weights.append(np.full(len(r), self.block_m * (math.sqrt(2.0) if dr and dc else 1.0)))
        return coo_matrix((np.concatenate(weights), (np.concatenate(rows), np.concatenate(cols))),
                          shape=(n, n))

    def node(self, xy: tuple[float, float]) -> int:
        """The open block at ``xy`` or the nearest within a few blocks (-1: none)."""
        r, c = self.grid.world_to_cell(*xy)
        br, bc = r // self.k, c // self.k
        hb, wb = self.index.shape
        best, best_d = -1, math.inf
        for dr in range(-_SNAP_BLOCKS, _SNAP_BLOCKS + 1):
            for dc in range(-_SNAP_BLOCKS, _SNAP_BLOCKS + 1):
                rr, cc = br + dr, bc + dc
                if 0 <= rr < hb and 0 <= cc < wb and self.index[rr, cc] >= 0 and dr * dr + dc * dc < best_d:
                    best, best_d = int(self.index[rr, cc]), dr * dr + dc * dc
        return best

    def lengths(self, places: Sequence[tuple[float, float]]) -> np.ndarray:
        """Path lengths (m) between every two of ``places`` on the graph (inf: no way on it)."""
        n = len(places)
        out = np.full((n, n), np.inf)
        nodes = [self.node(p) for p in places]
        known = [i for i, v in enumerate(nodes) if v >= 0]
        if known and self.graph.shape[0]:
            dist = dijkstra(self.graph, directed=False, indices=[nodes[i] for i in known])
            for a, i in enumerate(known):
                for j in known:
                    out[i, j] = dist[a, nodes[j]]
        np.fill_diagonal(out, 0.0)
        return out


def _blocks(mask: np.ndarray, k: int, hb: int, wb: int) -> np.ndarray:
    """Whether each k x k block of ``mask`` holds a True cell (the grid padded to whole blocks)."""
    h, w = mask.shape
    padded = np.zeros((hb * k, wb * k), bool)
    padded[:h, :w] = mask
    return np.asarray(padded.reshape(hb, k, wb, k).any(axis=(1, 3)), bool)


def between_lengths(grid: OccupancyGrid, places: Sequence[tuple[float, float]], start: np.ndarray,
                    block_m: float = 0.25) -> np.ndarray:
    """Path lengths between goals: the coarse graph's, within the straight line and the way via the robot.

    ``start`` holds each goal's path length from the robot (the planner's), so a goal's distance to
    another is at least the difference of theirs and at most their sum.
    """
    coarse = CoarseGraph(grid, block_m).lengths(places)
    xy = np.asarray(places, float).reshape(-1, 2)
    straight = np.sqrt(((xy[:, None, :] - xy[None, :, :]) ** 2).sum(axis=2))
    lower = np.maximum(straight, np.abs(start[:, None] - start[None, :]))
    upper = start[:, None] + start[None, :]
    return np.clip(np.minimum(coarse, upper), lower, None)
