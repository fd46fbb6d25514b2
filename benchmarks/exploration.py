"""Exploring unknown worlds: coverage of the reachable area and false "explored", on a dev and a test split.

Every run is the real mission through the session (loader, builder, runner, the Explore leaf) on the
simulator in unknown-map mode, run by the batch runner (missiontree.evaluation) on a process pool:
the robot starts knowing nothing, its map is the log-odds grid its own lidar builds, and its
navigation plans on that map with unknown cells traversable.

Splits (:mod:`missiontree.evaluation.splits`; ``--split dev|test|both``, default both):

- ``dev`` -- the apartment generator's worlds (``generated:<seed>``, 9-13 x 7-10 m, five rooms),
  without walkers (who pace through doorways and would time the navigator's waits, not the
  exploration). Tune on these only.
- ``test`` -- worlds of another kind: the floorplan family (long corridors with many 0.8-0.9 m
  doors, L- and T-shaped corridors, open plan, suites of rooms off rooms, clutter beside doors,
  warehouse floors up to 30 x 50 m) and the real SLAM maps (TurtleBot 4's maze, depot and
  warehouse, Nav2's tb3_sandbox) with rooms segmented from them. The real maps are held-out real
  geometry: they are in ``test`` only. Run it once at the end of a change, to report.

Configurations of the same leaf on the same worlds: ``ours`` (``strategy: gain``: frontiers scored
by the unknown area they would reveal against the path to them) always; with ``--compare`` also
``nearest_frontier`` (explore_lite's nearest-frontier rule, its size term off) and ``scan_points``
(the vision-language object-search report's scan points with its 360° scan at each).

Scoring reads the simulator's truth, which the leaf never sees:

- *reachable free area*: the truth raster's free cells the robot's body can reach from the start
  (cells with the robot's radius of clearance connected to the start, widened by that radius);
- *coverage*: the share of those cells the learned map reads free, sampled every SAMPLE_S seconds
  of robot time (time to 90 % and 99 %); a run *covers* when its final coverage is >= 0.95;
  *observed coverage* (printed beside it, not the target's figure) also counts a cell the map
  reads occupied right beside a true wall: observed, but mapped a cell off (a cell-accuracy error);
- *rooms*: every room of the world (the truth knows them; on real maps, the segmented ones) with
  at least 1 m^2 of reachable area is *seen* when ``ROOM_SEEN`` of its reachable cells read free;
- *false "explored"*: the leaf ended SUCCESS saying "explored" while the coverage was < 0.95 or a
  reachable room was not seen. A *partial* end (the leaf's own FAILURE "partial: ..." naming the
  frontiers it could not reach) is honest, not false; it still counts against coverage;
- *cell accuracy* on observed cells (boundary-tolerant, with the strict figure beside it) and the
  path length, as before.

Each split prints per-run lines, then the figures: the share of runs covering >= 0.95 and the
false-"explored" rate with 95 % Wilson intervals (missiontree.evaluation.report.wilson), coverage
medians, and the dev - test gap of each; a markdown table of both splits; the per-scan map update
cost (numba kernel and numpy fallback on recorded scans). Targets on ``test``: >= 0.95 coverage in
>= 95 % of runs, no false "explored", gap <= 0.05. The LAST line is one JSON object:
``{"dev": {...}, "test": {...}, "gap": {...}, "targets": {...}, ...}``.

    python benchmarks/exploration.py                    # 20 dev + 11 test worlds (one of each test kind)
    python benchmarks/exploration.py --split dev --quick      # 3 dev worlds
    python benchmarks/exploration.py --split test --test-worlds 22
    python benchmarks/exploration.py --split dev --compare    # ours against the other two rules
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import json
import math
import sys
import tempfile
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import yaml
from scipy import ndimage

ALL_STRATEGIES: dict[str, dict[str, Any]] = {
    "ours": {"strategy": "gain"},
    "nearest_frontier": {"strategy": "nearest", "min_frontier_size": 0.75},  # explore_lite's default size
    "scan_points": {"strategy": "scan_points", "look_around": True},
}
STRATEGIES = ALL_STRATEGIES        # the configurations of this run (main() narrows it without --compare)
SAMPLE_S = 2.0                      # coverage sampling period (robot clock)
COVERED = 0.95                      # a run covers when its final coverage reaches this
ROOM_SEEN = 0.8                     # a room is seen when this share of its reachable cells reads free
MIN_ROOM_M2 = 1.0                   # rooms with less reachable area are not judged
ROBOT_RADIUS = 0.17                 # TurtleBot 4 (the reachable area is judged with it)
#: The camera is not used by exploration: a small, slow one keeps the runs cheap.
SIM_CONFIG = {"camera": {"rate": 0.5, "width": 64, "height": 48}}


# -- worlds -----------------------------------------------------------------------------------------


def split_world_files(tmp: Path, split: str, count: int, first_seed: int) -> list[tuple[str, str]]:
    """(name, world file) of ``count`` worlds of ``split`` from ``first_seed`` on, without people."""
    from missiontree.evaluation.splits import split_worlds, write_split_world

    folder = tmp / split
    return [(w.name, str(write_split_world(w, folder)))
            for w in split_worlds(split, count, first_seed=first_seed, people=False)]


def most_open_point(data: np.ndarray, res: float, ox: float, oy: float) -> tuple[float, float]:
    """The free cell farthest from anything not free (ties: lowest row, then column)."""
    clearance = ndimage.distance_transform_edt((data >= 0) & (data < 50))
    r, c = np.unravel_index(int(np.argmax(clearance)), clearance.shape)
    return round(float(ox + (c + 0.5) * res), 4), round(float(oy + (r + 0.5) * res), 4)


# -- scoring against the truth ----------------------------------------------------------------------


class Truth:
    """The world's raster and its reachable free cells, for scoring learned maps."""

    def __init__(self, world: Any, radius: float = ROBOT_RADIUS) -> None:
        g = world.grid
        self.grid = g
        free = (g.data >= 0) & (g.data < 50)
        clearance = ndimage.distance_transform_edt(g.data < 50) * g.resolution
        centre_ok = clearance >= radius
        labels, _ = ndimage.label(centre_ok)
        r, c = g.world_to_cell(world.start.x, world.start.y)
        if not (0 <= r < labels.shape[0] and 0 <= c < labels.shape[1]) or labels[r, c] == 0:
            rr, cc = np.nonzero(centre_ok)
            k = int(np.argmin((rr - r) ** 2 + (cc - c) ** 2))
            r, c = int(rr[k]), int(cc[k])
        reach = labels == labels[r, c]
        k = int(math.ceil(radius / g.resolution))
        yy, xx = np.mgrid[-k:k + 1, -k:k + 1]
        self.reachable = ndimage.binary_dilation(reach, structure=(xx * xx + yy * yy) <= k * k) & free
        rows, cols = np.nonzero(self.reachable)
        self.x = g.origin.x + (cols + 0.5) * g.resolution
        self.y = g.origin.y + (rows + 0.5) * g.resolution
        self.area_m2 = float(len(rows)) * g.resolution ** 2
        occupied = g.data >= 50
        self.near_occupied = ndimage.binary_dilation(occupied, structure=np.ones((3, 3), bool))
        self.near_free = ndimage.binary_dilation(~occupied, structure=np.ones((3, 3), bool))
        #: per room with at least MIN_ROOM_M2 reachable: its name and the indices of its reachable cells
        self.rooms: list[tuple[str, np.ndarray]] = []
        for room in getattr(world, "rooms", []):
            canvas = np.zeros(g.data.shape, np.uint8)
            poly = np.round((np.asarray(room.polygon, float) - [g.origin.x, g.origin.y]) / g.resolution - 0.5)
            cv2.fillPoly(canvas, [poly.astype(np.int32)], 1)
            inside = np.flatnonzero(canvas[rows, cols])
            if len(inside) * g.resolution ** 2 >= MIN_ROOM_M2:
                self.rooms.append((str(room.name), inside))

    def seen_free(self, learned: Any) -> np.ndarray:
        """Per reachable free cell: whether the learned map reads it free."""
        lr = np.floor((self.y - learned.origin.y) / learned.resolution).astype(np.int64)
        lc = np.floor((self.x - learned.origin.x) / learned.resolution).astype(np.int64)
        h, w = learned.data.shape
        ok = (lr >= 0) & (lr < h) & (lc >= 0) & (lc < w)
        out = np.zeros(len(self.x), bool)
        values = learned.data[lr[ok], lc[ok]]
        out[ok] = (values >= 0) & (values < 25)
        return out

    def coverage(self, learned: Any) -> float:
        """Share of the reachable free cells the learned map reads free."""
        return float(np.count_nonzero(self.seen_free(learned))) / max(1, len(self.x))

    def coverage_observed(self, learned: Any) -> float:
        """Share of the reachable free cells the learned map reads free, or occupied beside a true wall.

        A free cell next to a wall that the learned map reads occupied was observed: the scan's hit
        marked the cell it fell in, a cell off the wall's true edge. That is a mapping error (cell
        accuracy counts it), not unexplored area; on small maps with much wall it is 2-5 % of the
        reachable cells.
        """
        seen = self.seen_free(learned)
        lr = np.floor((self.y - learned.origin.y) / learned.resolution).astype(np.int64)
        lc = np.floor((self.x - learned.origin.x) / learned.resolution).astype(np.int64)
        h, w = learned.data.shape
        ok = (lr >= 0) & (lr < h) & (lc >= 0) & (lc < w)
        occupied = np.zeros(len(self.x), bool)
        occupied[ok] = learned.data[lr[ok], lc[ok]] >= 65
        g = self.grid
        tr = np.floor((self.y - g.origin.y) / g.resolution).astype(np.int64)
        tc = np.floor((self.x - g.origin.x) / g.resolution).astype(np.int64)
        beside = self.near_occupied[tr, tc]
        return float(np.count_nonzero(seen | (occupied & beside))) / max(1, len(self.x))

    def rooms_missed(self, learned: Any) -> list[tuple[str, float]]:
        """Reachable rooms (at least MIN_ROOM_M2) of which less than ROOM_SEEN reads free: (name, share)."""
        seen = self.seen_free(learned)
        shares = [(name, float(np.mean(seen[cells]))) for name, cells in self.rooms]
        return [(name, round(share, 3)) for name, share in shares if share < ROOM_SEEN]

    def accuracy(self, learned: Any) -> tuple[float, float, int]:
        """(boundary-tolerant accuracy, strict accuracy, cells scored) on the learned map's known cells."""
        g = self.grid
        h, w = learned.data.shape
        rows, cols = np.nonzero(learned.data >= 0)
        values = learned.data[rows, cols]
        known = (values < 25) | (values >= 65)
        rows, cols, values = rows[known], cols[known], values[known]
        x = learned.origin.x + (cols + 0.5) * learned.resolution
        y = learned.origin.y + (rows + 0.5) * learned.resolution
        tr = np.floor((y - g.origin.y) / g.resolution).astype(np.int64)
        tc = np.floor((x - g.origin.x) / g.resolution).astype(np.int64)
        inside = (tr >= 0) & (tr < g.data.shape[0]) & (tc >= 0) & (tc < g.data.shape[1])
        tr, tc, occ = tr[inside], tc[inside], values[inside] >= 65
        if len(tr) == 0:
            return math.nan, math.nan, 0
        truth_occ = g.data[tr, tc] >= 50
        strict = float(np.mean(occ == truth_occ))
        tolerant = float(np.mean(np.where(occ, self.near_occupied[tr, tc], self.near_free[tr, tc])))
        return tolerant, strict, int(len(tr))


# -- one run ----------------------------------------------------------------------------------------


@dataclass
class RunScore:
    """One strategy on one world."""

    world: str
    split: str
    strategy: str
    status: str
    reason: str
    sim_s: float
    wall_s: float
    coverage_final: float
    time_to_90_s: float | None
    time_to_99_s: float | None
    cell_accuracy: float
    cell_accuracy_strict: float
    cells_scored: int
    path_length_m: float
    reachable_m2: float
    goals: int
    unreachable: int
    rooms: int = 0
    rooms_missed: list[tuple[str, float]] = field(default_factory=list)
    coverage_observed: float = math.nan
    scans: list[tuple[float, list[float], float, float, float]] = field(default_factory=list)


def mission_text(params: dict[str, Any]) -> str:
    """A one-leaf Explore mission in unknown-map mode with the given parameters."""
    return yaml.safe_dump({
        "version": 1, "description": "exploration benchmark run",
        "run": {"backend": "sim", "map": "unknown", "tick_hz": 10},
        "root": {"Explore": {"name": "explore", **params}}}, sort_keys=False)


class ExploreProbe:
    """Scores one run inside its batch worker, between ticks, from the simulator's truth.

    Coverage is sampled every SAMPLE_S seconds of robot time; scans with their poses are kept (up to
    ``keep_scans``, on the worlds in ``keep_scans_worlds``) for the per-scan update cost. The leaf
    never sees any of it.
    """

    def __init__(self, keep_scans_worlds: frozenset[str] = frozenset(), keep_scans: int = 40) -> None:
        self.keep_worlds = keep_scans_worlds
        self.keep = keep_scans
        self.truth: Truth | None = None
        self.next = 0.0
        self.trace: list[tuple[float, float]] = []
        self.scans: list[tuple[float, list[float], float, float, float]] = []

    def on_tick(self, session: Any) -> None:
        """Sample coverage when due; keep a scan about every 0.5 s while wanted."""
        robot = session.robot
        if self.truth is None:
            self.truth = Truth(robot.world)
        now = robot.now()
        if now >= self.next:
            self.next = now + SAMPLE_S
            learned = robot.occupancy()
            if learned is not None:
                self.trace.append((now, self.truth.coverage(learned)))
        if session.request.world in self.keep_worlds and len(self.scans) < self.keep:
            scan = robot.scan()
            if scan is not None and (not self.scans or scan.stamp > self.scans[-1][0] + 0.45):
                pose = robot.pose_at(scan.stamp)
                if pose is not None:
                    ranges = scan.ranges.astype(float).tolist()
                    self.scans.append((scan.stamp, ranges, pose.x, pose.y, pose.yaw))

    def finish(self, session: Any, result: Any) -> dict[str, Any]:
        """The run's score: RunScore's fields but the world, the split, the strategy and the wall time."""
        robot = session.robot
        truth = self.truth or Truth(robot.world)
        learned = robot.occupancy()
        now = robot.now()
        self.trace.append((now, truth.coverage(learned)))
        tolerant, strict, cells = truth.accuracy(learned)
        traj = np.array([(x, y) for _, x, y in robot.trajectory])
        path = float(np.hypot(*np.diff(traj, axis=0).T).sum()) if len(traj) > 1 else 0.0
        log = (session.run_dir / "ticks.jsonl").read_text(encoding="utf-8")
        events = [json.loads(line) for line in log.splitlines() if line.strip()]
        reason = next((c.get("feedback", "") for e in reversed(events) if e.get("event") == "tick"
                       for c in e.get("changed", []) if c.get("node") == "explore" and c.get("status") in
                       ("SUCCESS", "FAILURE")), "")
        times = np.array(self.trace)

        def reached(share: float) -> float | None:
            hit = np.nonzero(times[:, 1] >= share)[0]
            return float(times[hit[0], 0]) if len(hit) else None

        return {
            "status": result.status.name if result.stopped_by == "status" else
            f"{result.status.name} ({result.stopped_by})", "reason": reason, "sim_s": now,
            "coverage_final": float(times[-1, 1]), "coverage_observed": truth.coverage_observed(learned),
            "time_to_90_s": reached(0.90),
            "time_to_99_s": reached(0.99), "cell_accuracy": tolerant, "cell_accuracy_strict": strict,
            "cells_scored": cells, "path_length_m": path, "reachable_m2": truth.area_m2,
            "rooms": len(truth.rooms), "rooms_missed": truth.rooms_missed(learned),
            "goals": sum(e.get("event") == "explore_goal" for e in events),
            "unreachable": sum(e.get("event") == "explore_blacklist" for e in events), "scans": self.scans}


def run_strategies(worlds: list[tuple[str, str]], split: str, strategies: list[str], max_duration: float,
                   engine: Any, tmp: Path, keep_scans: frozenset[str] = frozenset()) -> list[RunScore]:
    """Every strategy on every world of a split through the batch runner: one batch per strategy.

    A run that raised (status ERROR) or whose process died twice (INFRA) is reported and left out.
    Scans are kept (for the update cost) on the worlds in ``keep_scans``.
    """
    from missiontree.evaluation import BatchPlan, RunSpec, run_batch

    keep = functools.partial(ExploreProbe, keep_scans)
    names = {world: name for name, world in worlds}
    fields = {f.name for f in dataclasses.fields(RunScore)} - {"world", "split", "strategy", "wall_s"}
    runs: list[RunScore] = []
    for strategy in strategies:
        tree = tmp / f"explore_{strategy}.yaml"
        tree.write_text(mission_text(ALL_STRATEGIES[strategy]), encoding="utf-8")
        specs = [RunSpec(world=world, seed=1, run_seed=1) for _, world in worlds]
        request = {"unknown_map": True, "config": SIM_CONFIG, "max_duration": max_duration}
        plan = BatchPlan(mission=tree, runs=specs, request=request)
        probe = keep if strategy == "ours" else ExploreProbe
        for record in run_batch(plan, engine, tmp / f"batch_{split}_{strategy}", probe=probe, write_log=True):
            name = names[str(record.world)]
            if record.status in ("ERROR", "INFRA"):  # one broken run must not lose the others
                print(f"  {split:4s} {name:22s} {strategy:16s} {record.status} {record.reason}", flush=True)
                continue
            score = RunScore(world=name, split=split, strategy=strategy, wall_s=record.wall_time_s,
                             **{k: v for k, v in record.figures.items() if k in fields})
            score.scans = [tuple(s) for s in score.scans]  # type: ignore[misc]
            score.rooms_missed = [tuple(m) for m in score.rooms_missed]  # type: ignore[misc]
            runs.append(score)
    return runs


# -- per-scan update cost ---------------------------------------------------------------------------


def update_cost(scans: list[tuple[float, list[float], float, float, float]],
                repeats: int = 3) -> dict[str, Any]:
    """Milliseconds per scan integrated into a 20 x 20 m grid at 5 cm: numba kernel and numpy, alternating."""
    from missiontree.backends.sim import load_robot_profile
    from missiontree.mapping.grid import HAVE_NUMBA, LogOddsGrid
    from missiontree.types import LaserScan, Pose2D

    lidar = load_robot_profile("turtlebot4").lidar
    n = lidar.beams
    inc = 2.0 * math.pi / n
    items = [(LaserScan(stamp, math.radians(lidar.angle_min_deg), inc, lidar.range_min, lidar.range_max,
                        np.array(ranges, np.float32), math.radians(lidar.mount.yaw_deg)), Pose2D(x, y, yaw))
             for stamp, ranges, x, y, yaw in scans]
    if not items:
        return {"update_ms_median": None, "update_ms_median_numpy": None, "scans": 0}
    cx = float(np.mean([p.x for _, p in items]))
    cy = float(np.mean([p.y for _, p in items]))
    times: dict[bool, list[float]] = {True: [], False: []}
    modes = [True, False] if HAVE_NUMBA else [False]
    grids = {a: LogOddsGrid(0.05, 20.0, 20.0, Pose2D(round(cx) - 10.0, round(cy) - 10.0), accelerate=a)
             for a in modes}
    grids[modes[0]].integrate(*items[0])  # compile / warm up
    for _ in range(repeats):
        for scan, pose in items:
            for a in modes:
                t0 = time.perf_counter()
                grids[a].integrate(scan, pose)
                times[a].append((time.perf_counter() - t0) * 1000.0)
    numba_ms = float(np.median(times[True])) if times[True] else None
    numpy_ms = float(np.median(times[False]))
    return {"update_ms_median": numba_ms if numba_ms is not None else numpy_ms,
            "update_ms_median_numba": numba_ms, "update_ms_median_numpy": numpy_ms,
            "update_ms_max_numba": float(np.max(times[True])) if times[True] else None,
            "numpy_over_numba": numpy_ms / numba_ms if numba_ms else None,
            "grid_cells": int(grids[modes[0]].logodds.size), "scans": len(items), "numba": HAVE_NUMBA}


# -- summary ----------------------------------------------------------------------------------------


def median_time(values: list[float | None]) -> float | None:
    """Median with "not reached" (None) above every time; None when the median run did not reach it."""
    ordered = sorted(values, key=lambda v: math.inf if v is None else v)
    if not ordered:
        return None
    k = (len(ordered) - 1) / 2
    lo, hi = ordered[math.floor(k)], ordered[math.ceil(k)]
    if lo is None or hi is None:
        return None
    return (lo + hi) / 2


def spread(values: list[float]) -> dict[str, float | None]:
    """Min / median / max of the finite values."""
    v = [x for x in values if x is not None and math.isfinite(x)]
    if not v:
        return {"min": None, "median": None, "max": None}
    return {"min": round(min(v), 3), "median": round(float(np.median(v)), 3), "max": round(max(v), 3)}


def explored_claim(r: RunScore) -> bool:
    """Whether the leaf ended SUCCESS saying the place is explored."""
    return r.status == "SUCCESS" and r.reason.startswith("explored")


def false_explored(r: RunScore) -> bool:
    """SUCCESS 'explored' with coverage under COVERED or a reachable room not seen."""
    return explored_claim(r) and (r.coverage_final < COVERED or bool(r.rooms_missed))


def summarise(runs: list[RunScore]) -> dict[str, Any]:
    """Per-strategy figures over the worlds of one split (the Wilson intervals for ``ours``)."""
    from missiontree.evaluation.report import wilson

    out: dict[str, Any] = {}
    for name in STRATEGIES:
        mine = [r for r in runs if r.strategy == name]
        if not mine:
            continue
        n = len(mine)
        covered = sum(r.coverage_final >= COVERED for r in mine)
        false = sum(false_explored(r) for r in mine)
        t90 = median_time([r.time_to_90_s for r in mine])
        t99 = median_time([r.time_to_99_s for r in mine])
        out[name] = {
            "runs": n,
            "covered_share": round(covered / n, 4),
            "covered_share_ci95": [round(v, 4) for v in wilson(covered, n)],
            "false_explored": false,
            "false_explored_rate": round(false / n, 4),
            "false_explored_rate_ci95": [round(v, 4) for v in wilson(false, n)],
            "partial": sum(r.reason.startswith("partial") for r in mine),
            "explored_claims": sum(explored_claim(r) for r in mine),
            "stopped_by_limit": sum("limit" in r.status for r in mine),
            "rooms_missed": sum(len(r.rooms_missed) for r in mine),
            "rooms": sum(r.rooms for r in mine),
            "coverage_final": round(float(np.median([r.coverage_final for r in mine])), 4),
            "coverage_final_mean": round(float(np.mean([r.coverage_final for r in mine])), 4),
            "coverage_final_min": round(float(np.min([r.coverage_final for r in mine])), 4),
            "coverage_observed": round(float(np.nanmedian([r.coverage_observed for r in mine])), 4),
            "coverage_observed_min": round(float(np.nanmin([r.coverage_observed for r in mine])), 4),
            "covered_observed_share": round(sum(r.coverage_observed >= COVERED for r in mine) / n, 4),
            "time_to_90_s_median": None if t90 is None else round(t90, 1),
            "time_to_99_s_median": None if t99 is None else round(t99, 1),
            "cell_accuracy": round(float(np.nanmedian([r.cell_accuracy for r in mine])), 4),
            "cell_accuracy_strict": round(float(np.nanmedian([r.cell_accuracy_strict for r in mine])), 4),
            "path_length_m_median": round(float(np.median([r.path_length_m for r in mine])), 2),
            "duration_s_median": round(float(np.median([r.sim_s for r in mine])), 1),
            "duration_s_max": round(float(np.max([r.sim_s for r in mine])), 1),
            "wall_s_median": round(float(np.median([r.wall_s for r in mine])), 1),
            "succeeded": sum(r.status == "SUCCESS" for r in mine),
        }
    return out


def ratios(runs: list[RunScore], key: str, a: str = "ours", b: str = "nearest_frontier") -> list[float]:
    """Per world: ``key`` of strategy a over strategy b (worlds where both have a value)."""
    by = {(r.world, r.strategy): getattr(r, key) for r in runs}
    worlds = sorted({r.world for r in runs})
    out = []
    for w in worlds:
        va, vb = by.get((w, a)), by.get((w, b))
        if va is not None and vb:
            out.append(va / vb)
    return out


GAP_KEYS = ("covered_share", "false_explored_rate", "coverage_final", "coverage_final_mean")


def gap(dev: dict[str, Any], test: dict[str, Any]) -> dict[str, float | None]:
    """Dev - test of each figure in GAP_KEYS (None where a split has no runs)."""
    return {k: (round(dev[k] - test[k], 4) if k in dev and k in test else None) for k in GAP_KEYS}


def interval(figure: dict[str, Any], key: str) -> str:
    low, high = figure[f"{key}_ci95"]
    return f"{figure[key]:.3f} [{low:.3f}, {high:.3f}]"


def markdown(by_split: dict[str, dict[str, Any]], gaps: dict[str, float | None]) -> str:
    """A short table of ``ours`` on each split, with the gap."""
    lines = ["| split | runs | coverage >= 0.95 (95 % CI) | false \"explored\" (95 % CI) | partial | "
             "median coverage | rooms missed |",
             "|---|---|---|---|---|---|---|"]
    for split, s in by_split.items():
        o = s.get("ours")
        if not o:
            continue
        lines.append(f"| {split} | {o['runs']} | {interval(o, 'covered_share')} | "
                     f"{o['false_explored']} ({interval(o, 'false_explored_rate')}) | {o['partial']} | "
                     f"{o['coverage_final']:.3f} | {o['rooms_missed']} of {o['rooms']} |")
    if gaps.get("covered_share") is not None:
        lines.append(f"| dev - test | | {gaps['covered_share']:+.3f} | {gaps['false_explored_rate']:+.3f} "
                     f"| | {gaps['coverage_final']:+.3f} | |")
    return "\n".join(lines)


def main() -> int:
    global STRATEGIES
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--split", choices=("dev", "test", "both"), default="both",
                        help="which split(s) to run")
    parser.add_argument("--quick", action="store_true", help="3 dev worlds, 4 test worlds (a smoke run)")
    parser.add_argument("--worlds", type=int, default=20, help="dev worlds (default 20)")
    parser.add_argument("--first-seed", type=int, default=100, help="seed of the first dev world")
    parser.add_argument("--test-worlds", type=int, default=11,
                        help="test worlds (default 11: one of each kind the test split cycles through)")
    parser.add_argument("--test-first-seed", type=int, default=0, help="seed of the first test world")
    parser.add_argument("--max-duration", type=float, default=900.0,
                        help="robot-clock limit per run (s; default 900, the shipped explore mission's)")
    parser.add_argument("--jobs", type=int, default=2, help="runs in parallel (processes)")
    parser.add_argument("--compare", action="store_true", help="also run nearest_frontier and scan_points")
    args = parser.parse_args()
    from missiontree.evaluation import PoolEngine

    STRATEGIES = ALL_STRATEGIES if args.compare else {"ours": ALL_STRATEGIES["ours"]}
    splits = ["dev", "test"] if args.split == "both" else [args.split]
    counts = {"dev": (3 if args.quick else args.worlds, args.first_seed),
              "test": (4 if args.quick else args.test_worlds, args.test_first_seed)}
    started = time.perf_counter()
    runs: list[RunScore] = []
    names: dict[str, list[str]] = {}
    with tempfile.TemporaryDirectory() as tmp, PoolEngine(max(1, args.jobs)) as engine:
        for split in splits:
            count, first = counts[split]
            worlds = split_world_files(Path(tmp), split, count, first)
            names[split] = [name for name, _ in worlds]
            print(f"exploration {split}: {len(worlds)} worlds x {len(STRATEGIES)} configurations, max "
                  f"{args.max_duration:g} s each, {args.jobs} processes (the batch runner)", file=sys.stderr)
            keep = frozenset(world for _, world in worlds[:3]) if split == splits[0] else frozenset()
            got = run_strategies(worlds, split, list(STRATEGIES), args.max_duration, engine, Path(tmp), keep)
            order = {name: i for i, name in enumerate(names[split])}
            got.sort(key=lambda r: (order[r.world], list(STRATEGIES).index(r.strategy)))
            for r in got:
                t90 = "-" if r.time_to_90_s is None else f"{r.time_to_90_s:.0f}"
                missed = ",".join(f"{m[0]}:{m[1]:.2f}" for m in r.rooms_missed) or "-"
                print(f"  {split:4s} {r.world:22s} {r.strategy:16s} {r.status:18s} "
                      f"cov {r.coverage_final:.3f} (observed {r.coverage_observed:.3f}) t90 {t90:>4s} "
                      f"acc {r.cell_accuracy:.4f} "
                      f"path {r.path_length_m:6.1f} m {r.sim_s:5.0f} s sim {r.wall_s:6.1f} s wall "
                      f"goals {r.goals} given up {r.unreachable} "
                      f"rooms missed {missed}  {r.reason[:90]}", flush=True)
            runs += got
    cost = update_cost([s for r in runs for s in r.scans])
    by_split = {split: summarise([r for r in runs if r.split == split]) for split in splits}
    gaps = gap(by_split["dev"].get("ours", {}), by_split["test"].get("ours", {})) if len(splits) == 2 else {}
    print()
    for split, summary in by_split.items():
        for name, s in summary.items():
            print(f"{split:4s} {name:16s} runs {s['runs']}: coverage >= {COVERED} in "
                  f"{interval(s, 'covered_share')} of runs; false 'explored' {s['false_explored']} (rate "
                  f"{interval(s, 'false_explored_rate')}); partial {s['partial']}; median coverage "
                  f"{s['coverage_final']:.3f} (min {s['coverage_final_min']:.3f}); rooms missed "
                  f"{s['rooms_missed']} of {s['rooms']}; t90 {s['time_to_90_s_median']} s; accuracy "
                  f"{s['cell_accuracy']:.4f}; sim {s['duration_s_median']} s median, "
                  f"{s['duration_s_max']} s max")
    if gaps:
        print(f"dev - test gap (ours): {gaps}")
    if args.compare:
        for split in splits:
            mine = [r for r in runs if r.split == split]
            print(f"{split}: ours / nearest_frontier, time to 90 %: {spread(ratios(mine, 'time_to_90_s'))}; "
                  f"path length: {spread(ratios(mine, 'path_length_m'))}")
    print(f"per-scan update (20 x 20 m at 5 cm, {cost['scans']} recorded scans): numba "
          f"{cost.get('update_ms_median_numba')} ms, numpy {cost.get('update_ms_median_numpy')} ms")
    print()
    print(markdown(by_split, gaps))
    test = by_split.get("test", {}).get("ours", {})
    result: dict[str, Any] = {split: {**summary.get("ours", {}), "worlds": names[split],
                                      **({"strategies": summary} if args.compare else {})}
                              for split, summary in by_split.items()}
    result["gap"] = gaps
    result["targets"] = {
        "test_covered_share_ge_0.95": bool(test.get("covered_share", 0) >= 0.95) if test else None,
        "test_no_false_explored": bool(test.get("false_explored", 1) == 0) if test else None,
        "gap_le_0.05": bool(all(v is not None and abs(v) <= 0.05 for v in (
            gaps.get("covered_share"), gaps.get("false_explored_rate")))) if gaps else None,
    }
    result["update_ms_median"] = cost["update_ms_median"]
    result["update_ms_median_numpy"] = cost.get("update_ms_median_numpy")
    result["max_duration_s"] = args.max_duration
    result["wall_s"] = round(time.perf_counter() - started, 1)
    result["runs"] = [{k: v for k, v in asdict(r).items() if k != "scans"} for r in runs]
    print(json.dumps(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
