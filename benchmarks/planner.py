"""The planner on a warehouse-sized map: the tiled, lazily inflated planner against the old whole-grid method.

A 30 x 50 m map at 3 cm cells (1,000 x 1,667 cells, the size of a real warehouse map): outer walls,
two banks of racks with aisles, a cross aisle and scattered pallets, generated from a seed. Pairs of
free points at least 20 m apart are planned between, alternating:

- new: ``missiontree.mapping.planner.Costmap`` kept between plans (as a navigator keeps it): cost
  tiles computed when a search first reaches them, search state in tiles, A* guided by a coarse
  distance; also ``new_cold``: a fresh costmap per plan (its lazy inflation included), and
  ``new_replan``: the same with a few lidar points made lethal (a person in the way).
- old: the previous whole-grid method (the whole costmap inflated with one distance transform,
  A* with whole-grid g/parent/closed arrays and a heap of 8 entries per cell), and ``old_replan``,
  which re-inflated the whole grid for the lidar points before planning.

The new planner is weighted A* (its heuristic times ``Costmap.heuristic_weight``); the old kernel
is run twice, as it was (optimal A*, weight 1) and with the same weight (``old_w``), so the ratio
that compares the implementations (``old_w / new``) is printed apart from the one that also holds
the weight (``old / new``), with the path-length cost of the weight beside it.

Each plan is timed in CPU time (``time.thread_time``: this thread's; every kernel is single-threaded)
beside wall time, with nothing else on (tracemalloc off); its peak allocation is measured in a
second call of its own: the larger of tracemalloc's peak (numpy arrays) and the rise of the
process's resident high-water mark (which also sees numba's own allocations). The methods'
order turns with every pair (no method always runs first, on a cold cache). Prints per-method
min/median/max, ratios old/new on CPU time, then one JSON line.

    .venv/bin/python benchmarks/planner.py [--pairs 12] [--seed 1]
"""

from __future__ import annotations

import argparse
import gc
import json
import math
import statistics
import time
import tracemalloc
from collections.abc import Callable
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from missiontree.mapping.planner import HAVE_NUMBA, Costmap
from missiontree.types import OccupancyGrid, Pose2D

RES = 0.03
WIDTH_M, HEIGHT_M = 50.0, 30.0
RADIUS, INFLATION, SCALING = 0.17, 0.45, 3.0


def warehouse(seed: int) -> OccupancyGrid:
    """A 50 x 30 m warehouse at 3 cm: walls, rack banks with aisles, a cross aisle, pallets."""
    rng = np.random.default_rng(seed)
    h, w = int(round(HEIGHT_M / RES)), int(round(WIDTH_M / RES))
    data = np.zeros((h, w), np.int8)
    wall = max(1, int(round(0.1 / RES)))
    data[:wall], data[-wall:], data[:, :wall], data[:, -wall:] = 100, 100, 100, 100

    def block(x0: float, y0: float, x1: float, y1: float) -> None:
        data[int(y0 / RES): int(y1 / RES), int(x0 / RES): int(x1 / RES)] = 100

    x = 4.0
    while x < WIDTH_M - 4.0:
        block(x, 3.0, x + 1.0, 12.5)       # lower bank
        block(x, 16.5, x + 1.0, 27.0)      # upper bank
        x += 1.0 + rng.uniform(2.2, 3.2)    # aisle width
    for _ in range(40):                      # pallets in the open areas
        px, py = rng.uniform(1.0, WIDTH_M - 2.0), rng.uniform(0.5, HEIGHT_M - 1.5)
        block(px, py, px + rng.uniform(0.5, 1.2), py + rng.uniform(0.5, 1.2))
    return OccupancyGrid(0.0, RES, Pose2D(0.0, 0.0), data)


# -- the old whole-grid method (as navigation.py had it), the reference -------------------------------

def old_inflate(grid: OccupancyGrid, lethal: np.ndarray) -> np.ndarray:
    """The whole-grid inflation of the old Costmap."""
    dist = cv2.distanceTransform((~lethal).astype(np.uint8), cv2.DIST_L2, 5) * grid.resolution
    cost = np.zeros(lethal.shape, np.uint8)
    band = (dist <= INFLATION) & (dist >= RADIUS)
    cost[band] = (252.0 * np.exp(-SCALING * (dist[band] - RADIUS))).astype(np.uint8)
    cost[dist < RADIUS] = 253
    cost[lethal] = 254
    return cost


def _old_astar(cost, start, goal, weight, hweight):  # noqa: ANN001, ANN202 - the old kernel + heuristic weight
    h, w = cost.shape
    n = h * w
    g = np.full(n, np.inf)
    parent = np.full(n, -1, np.int64)
    closed = np.zeros(n, np.bool_)
    heap_key = np.empty(8 * n + 8)
    heap_val = np.empty(8 * n + 8, np.int64)
    size = 0
    gr, gc_ = goal // w, goal % w
    g[start] = 0.0
    heap_key[0], heap_val[0], size = 0.0, start, 1
    drs = (-1, -1, -1, 0, 0, 1, 1, 1)
    dcs = (-1, 0, 1, -1, 1, -1, 0, 1)
    while size > 0:
        cur = heap_val[0]
        size -= 1
        heap_key[0], heap_val[0] = heap_key[size], heap_val[size]
        i = 0
        while True:
            left = 2 * i + 1
            if left >= size:
                break
            child = left
            if left + 1 < size and heap_key[left + 1] < heap_key[left]:
                child = left + 1
            if heap_key[child] < heap_key[i]:
                heap_key[i], heap_key[child] = heap_key[child], heap_key[i]
                heap_val[i], heap_val[child] = heap_val[child], heap_val[i]
                i = child
            else:
                break
        if closed[cur]:
            continue
        closed[cur] = True
        if cur == goal:
            break
        r, c = cur // w, cur % w
        for k in range(8):
            nr, nc = r + drs[k], c + dcs[k]
            if nr < 0 or nr >= h or nc < 0 or nc >= w:
                continue
            nxt = nr * w + nc
            if closed[nxt] or cost[nr, nc] >= 253:
                continue
            step = 1.4142135623730951 if drs[k] != 0 and dcs[k] != 0 else 1.0
            ng = g[cur] + step * (1.0 + weight * cost[nr, nc] / 252.0)
            if ng < g[nxt]:
                g[nxt] = ng
                parent[nxt] = cur
                f = ng + hweight * math.sqrt((nr - gr) ** 2 + (nc - gc_) ** 2)
                j = size
                heap_key[j], heap_val[j] = f, nxt
                size += 1
                while j > 0:
                    up = (j - 1) // 2
                    if heap_key[up] > heap_key[j]:
                        heap_key[up], heap_key[j] = heap_key[j], heap_key[up]
                        heap_val[up], heap_val[j] = heap_val[j], heap_val[up]
                        j = up
                    else:
                        break
    if parent[goal] < 0 and goal != start:
        return np.zeros(0, np.int64)
    path = [goal]
    cur = goal
    while cur != start:
        cur = parent[cur]
        path.append(cur)
    return np.array(path, dtype=np.int64)


if HAVE_NUMBA:
    import numba

    _old_astar = numba.njit(cache=True)(_old_astar)


Point = tuple[float, float]


def old_plan(grid: OccupancyGrid, cost: np.ndarray, a: Point, b: Point, hweight: float = 1.0) -> float | None:
    """Old A* on a whole-grid cost array (heuristic times ``hweight``); the path length in metres."""
    w = cost.shape[1]
    sr, sc = grid.world_to_cell(*a)
    gr, gc_ = grid.world_to_cell(*b)
    cells = _old_astar(cost, sr * w + sc, gr * w + gc_, 3.0, float(hweight))
    if len(cells) == 0:
        return None
    rows, cols = cells // w, cells % w
    return float(np.hypot(np.diff(rows), np.diff(cols)).sum()) * grid.resolution


# -- measuring ----------------------------------------------------------------------------------------

def _rss_kb(field: str) -> int:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith(field):
            return int(line.split()[1])
    return 0


def timed(fn: Callable[[], Any]) -> tuple[Any, float, float]:
    """(result, CPU milliseconds of this thread, wall milliseconds) of one call, nothing else measured."""
    gc.collect()
    cpu0, wall0 = time.thread_time(), time.perf_counter()
    out = fn()
    return out, (time.thread_time() - cpu0) * 1000.0, (time.perf_counter() - wall0) * 1000.0


def measure(fn: Callable[[], Any]) -> tuple[Any, float, float]:
    """(result, wall milliseconds, peak allocation MB) of one call (timing under tracemalloc: memory only)."""
    gc.collect()
    hwm_ok = True
    try:
        Path("/proc/self/clear_refs").write_text("5")  # reset the resident high-water mark
    except OSError:
        hwm_ok = False
    rss0 = _rss_kb("VmRSS:")
    tracemalloc.start()
    t0 = time.perf_counter()
    out = fn()
    ms = (time.perf_counter() - t0) * 1000.0
    traced = tracemalloc.get_traced_memory()[1] / 2**20
    tracemalloc.stop()
    rise = (_rss_kb("VmHWM:") - rss0) / 1024.0 if hwm_ok else 0.0
    return out, ms, max(traced, rise)


def pairs(grid: OccupancyGrid, costmap: Costmap, n: int, seed: int) -> list[tuple[Point, Point]]:
    """``n`` pairs of free points at least 20 m apart."""
    rng = np.random.default_rng(seed + 1000)
    out = []
    while len(out) < n:
        a = (rng.uniform(0.5, WIDTH_M - 0.5), rng.uniform(0.5, HEIGHT_M - 0.5))
        b = (rng.uniform(0.5, WIDTH_M - 0.5), rng.uniform(0.5, HEIGHT_M - 0.5))
        if math.dist(a, b) >= 20.0 and costmap.cost_at(*a) == 0 and costmap.cost_at(*b) == 0:
            out.append((a, b))
    return out


def spread(values: list[float]) -> str:
    return f"min {min(values):8.2f}  median {statistics.median(values):8.2f}  max {max(values):8.2f}"


def spread_json(values: list[float]) -> dict[str, float]:
    return {"min": round(min(values), 2), "median": round(statistics.median(values), 2),
            "max": round(max(values), 2)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pairs", type=int, default=12,
                        help="start/goal pairs (each planned by every method)")
    parser.add_argument("--seed", type=int, default=1, help="map and pair seed")
    args = parser.parse_args()
    grid = warehouse(args.seed)
    print(f"map {grid.data.shape[1]} x {grid.data.shape[0]} cells ({WIDTH_M:.0f} x {HEIGHT_M:.0f} m at "
          f"{RES * 100:.0f} cm); numba {'on' if HAVE_NUMBA else 'off (numpy/Python loops)'}")
    kept = Costmap(grid, RADIUS, INFLATION, SCALING)
    work = pairs(grid, kept, args.pairs, args.seed)
    # warm up: compile or load the kernels, and let the old method's whole costmap be built once
    kept.plan(*work[0])
    old_cost, old_inflate_ms, _ = measure(lambda: old_inflate(grid, grid.data >= 50))
    weight = kept.heuristic_weight
    old_plan(grid, old_cost, *work[0])
    old_plan(grid, old_cost, *work[0], hweight=weight)
    rng = np.random.default_rng(args.seed)
    names = ("new", "new_cold", "new_replan", "old", "old_w", "old_replan")
    times: dict[str, list[float]] = {k: [] for k in names}
    walls: dict[str, list[float]] = {k: [] for k in names}
    mem: dict[str, list[float]] = {k: [] for k in names}
    lengths: list[tuple[float, float, float]] = []
    for index, (a, b) in enumerate(work):
        # a person 1.5 m along the straight line, as a lidar would see them (a few points)
        ux, uy = (b[0] - a[0]) / math.dist(a, b), (b[1] - a[1]) / math.dist(a, b)
        person = np.array([(a[0] + 1.5 * ux + 0.1 * math.cos(t), a[1] + 1.5 * uy + 0.1 * math.sin(t))
                           for t in rng.uniform(0, 2 * math.pi, 12)])
        people = grid.data >= 50
        def old_replan(a=a, b=b, people=people, person=person) -> float | None:  # noqa: ANN001
            return old_plan(grid, old_inflate(grid, _with_points(grid, people, person)), a, b)

        runs: list[tuple[str, Callable[[], Any]]] = [
            ("new", lambda a=a, b=b: kept.plan(a, b)),
            ("old", lambda a=a, b=b: old_plan(grid, old_cost, a, b)),
            ("old_w", lambda a=a, b=b: old_plan(grid, old_cost, a, b, hweight=weight)),
            ("new_cold", lambda a=a, b=b: Costmap(grid, RADIUS, INFLATION, SCALING).plan(a, b)),
            ("old_replan", old_replan),
            ("new_replan", lambda a=a, b=b, person=person: kept.with_points(person).plan(a, b)),
        ]
        turn = index % len(runs)
        found: dict[str, Any] = {}
        for name, fn in runs[turn:] + runs[:turn]:  # the order turns with every pair
            out, cpu_ms, wall_ms = timed(fn)
            times[name].append(cpu_ms)
            walls[name].append(wall_ms)
            mem[name].append(measure(fn)[2])
            found[name] = out
        new_len = found["new"].length if found["new"] is not None else math.nan
        old_len = found["old"] if found["old"] is not None else math.nan
        old_w_len = found["old_w"] if found["old_w"] is not None else math.nan
        lengths.append((new_len, old_len, old_w_len))
        print(f"  {math.dist(a, b):5.1f} m apart: new {times['new'][-1]:7.2f} ms CPU "
              f"({found['new'].expanded} cells, {mem['new'][-1]:.1f} MB, path {new_len:.2f} m) | "
              f"old {times['old'][-1]:7.2f} ms ({mem['old'][-1]:.0f} MB, path {old_len:.2f} m) | "
              f"old w={weight} {times['old_w'][-1]:7.2f} ms (path {old_w_len:.2f} m) | "
              f"cold {times['new_cold'][-1]:.1f} ms | "
              f"replan new {times['new_replan'][-1]:.1f} ms, old {times['old_replan'][-1]:.1f} ms")
    print()
    for name in times:
        print(f"{name:11s} CPU ms  {spread(times[name])}    wall ms  {spread(walls[name])}    "
              f"MB  {spread(mem[name])}")
    speed = [o / n for o, n in zip(times["old"], times["new"], strict=True)]
    same_weight = [o / n for o, n in zip(times["old_w"], times["new"], strict=True)]
    weight_gain = [o / w for o, w in zip(times["old"], times["old_w"], strict=True)]
    replan = [o / n for o, n in zip(times["old_replan"], times["new_replan"], strict=True)]
    memory = [o / max(n, 1e-3) for o, n in zip(mem["old"], mem["new"], strict=True)]
    excess = [n / o - 1.0 for n, o, _ in lengths if o > 0]
    weight_excess = [w / o - 1.0 for _, o, w in lengths if o > 0]
    print(f"old_w/new plan CPU time (same weight {weight}: the implementations) {spread(same_weight)}")
    print(f"old/old_w plan CPU time (the weight alone, old kernel)         {spread(weight_gain)}")
    print(f"old/new plan CPU time (implementation and weight together)    {spread(speed)}")
    print(f"old/new replan CPU time {spread(replan)}")
    print(f"old/new peak alloc  {spread(memory)}")
    print(f"path length new/old - 1: {spread(excess)}; old_w/old - 1: {spread(weight_excess)}")
    print(json.dumps({
        "ratio_old_w_over_new_plan_cpu": spread_json(same_weight),
        "ratio_old_over_old_w_plan_cpu": spread_json(weight_gain),
        "heuristic_weight": weight,
        "old_w_plan_ms_median_30x50_3cm": round(statistics.median(times["old_w"]), 3),
        "plan_ms_median_30x50_3cm": round(statistics.median(times["new"]), 3),
        "peak_alloc_mb_30x50_3cm": round(max(mem["new"]), 2),
        "plan_ms_cold_median_30x50_3cm": round(statistics.median(times["new_cold"]), 3),
        "peak_alloc_mb_cold_30x50_3cm": round(max(mem["new_cold"]), 2),
        "replan_ms_median_30x50_3cm": round(statistics.median(times["new_replan"]), 3),
        "old_plan_ms_median_30x50_3cm": round(statistics.median(times["old"]), 3),
        "old_peak_alloc_mb_30x50_3cm": round(max(mem["old"]), 2),
        "old_replan_ms_median_30x50_3cm": round(statistics.median(times["old_replan"]), 3),
        "old_inflate_ms_30x50_3cm": round(old_inflate_ms, 3),
        "ratio_old_over_new_plan_cpu": spread_json(speed),
        "ratio_old_over_new_replan_cpu": spread_json(replan),
        "time": "CPU ms (this thread) unless named wall",
        "path_length_excess_median": round(statistics.median(excess), 4) if excess else None,
        "pairs": len(work),
        "numba": HAVE_NUMBA,
    }))


def _with_points(grid: OccupancyGrid, lethal: np.ndarray, points: np.ndarray) -> np.ndarray:
    """The old Costmap.with_points: a whole copy of the lethal mask with discs stamped in."""
    out = lethal.copy()
    r_cells = max(1, int(round(0.08 / grid.resolution)))
    for x, y in points:
        row, col = grid.world_to_cell(float(x), float(y))
        cv2.circle(out.view(np.uint8), (col, row), r_cells, 1, -1)
    return out


if __name__ == "__main__":
    main()
