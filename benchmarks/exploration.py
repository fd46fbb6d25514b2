"""Exploring unknown worlds: ours against nearest-frontier (explore_lite's rule) and the report's scan points.

Every run is the real mission through the session (loader, builder, runner, the Explore leaf) on the
simulator in unknown-map mode, run by the batch runner (missiontree.evaluation) on a process pool:
the robot starts knowing nothing, its map is the log-odds grid its own lidar builds, and its
navigation plans on that map with unknown cells traversable. Three configurations of the same leaf
run on the same worlds and seeds (one batch per configuration on the same pool; every score is on
the robot clock, so the order the runs happen to finish in changes none of them):

- ``ours`` -- ``strategy: gain``: frontiers scored by the unknown area they would reveal (ray cast
  over the map, walls blocking) against the length of the path to them;
- ``nearest_frontier`` -- ``strategy: nearest``: the nearest frontier by path length, the rule of
  Yamauchi's frontier exploration as explore_lite runs it (its size term off);
- ``scan_points`` -- ``strategy: scan_points, look_around: true``: the vision-language object-search
  report's scan points (centroids of the largest eroded free regions, largest first) with its 360°
  scan at each.

Worlds: generated apartments (``generated:<seed>``, 9-13 x 7-10 m, five rooms; without the walkers, who
pace through doorways and would measure how long the navigator waits for them, not the strategy)
plus the shipped map_server maps (config/worlds/maps: real SLAM maps from TurtleBot 4 and Nav2, and a
drawn office), each made into a world file with the start at the free cell farthest from any obstacle.

Scoring reads the simulator's truth, which the leaf never sees:

- *reachable free area*: the truth raster's free cells the robot's body can reach from the start
  (cells with the robot's radius of clearance connected to the start, widened by that radius);
- *coverage* at a moment: the share of those cells the learned map reads free; sampled every
  SAMPLE_S seconds of robot time, giving the time to 90 % and 99 % (a run that never gets there
  counts as not reached: medians are taken over all runs with "not reached" above every time);
- *cell accuracy* on observed cells: of the cells the learned map reads free or occupied (inside
  the truth raster), the share whose class agrees with the truth raster within one cell at a
  boundary (the raster draws walls 0.1 m thick around the zero-thickness segments the lidar hits, so
  the cell in front of a wall line is "occupied" in the raster though the beam passes it); the
  strict cell-for-cell figure is printed beside it;
- *path length*: the true trajectory's length.

The per-scan update cost is measured apart, on scans and poses recorded from the runs, integrated
into a 20 x 20 m grid at 5 cm by the numba kernel and by the numpy fallback, alternating.

Ratios (ours against nearest-frontier, per world) are printed with min/median/max. Last line: one
JSON object with, per strategy, ``coverage_final``, ``time_to_90_s_median``, ``cell_accuracy``,
``path_length_m_median`` (and more), plus ``update_ms_median``.

    python benchmarks/exploration.py            # 20 generated worlds + the shipped maps (~10 min)
    python benchmarks/exploration.py --quick    # 3 generated worlds + one map
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import json
import math
import shutil
import sys
import tempfile
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from scipy import ndimage

STRATEGIES: dict[str, dict[str, Any]] = {
    "ours": {"strategy": "gain"},
    "nearest_frontier": {"strategy": "nearest", "min_frontier_size": 0.75},  # explore_lite's default size
    "scan_points": {"strategy": "scan_points", "look_around": True},
}
SAMPLE_S = 2.0                      # coverage sampling period (robot clock)
ROBOT_RADIUS = 0.17                 # TurtleBot 4 (the reachable area is judged with it)
#: The camera is not used by exploration: a small, slow one keeps the runs cheap.
SIM_CONFIG = {"camera": {"rate": 0.5, "width": 64, "height": 48}}
REPO = Path(__file__).resolve().parents[1]
MAP_DIRS = [REPO / "config" / "worlds" / "maps"]


# -- worlds -----------------------------------------------------------------------------------------


def generated_world_files(tmp: Path, seeds: range) -> list[tuple[str, str]]:
    """Generated apartments without people (walkers in doorways would time the navigator's waits)."""
    from missiontree.backends.sim.generator import write_world_file

    return [(f"generated:{s}", str(write_world_file(s, tmp / f"generated_{s}.yaml", people=0)))
            for s in seeds]


def map_world_files(tmp: Path, limit: int | None = None) -> list[tuple[str, str]]:
    """A world file for every shipped map_server map, the start where the map is most open."""
    from missiontree.mapping.mapfile import read_map

    out: list[tuple[str, str]] = []
    for folder in MAP_DIRS:
        for meta in sorted(folder.glob("*.yaml")) if folder.is_dir() else []:
            try:
                grid = read_map(meta)
            except ValueError as exc:
                print(f"  note: {meta} skipped: {exc}", file=sys.stderr)
                continue
            x, y = most_open_point(grid.data, grid.resolution, grid.origin.x, grid.origin.y)
            # the world loader reads maps beside the world file: copy the map (yaml and image) there
            doc = yaml.safe_load(meta.read_text(encoding="utf-8"))
            folder_out = tmp / f"map_{meta.stem}"
            folder_out.mkdir(exist_ok=True)
            shutil.copy(meta.parent / str(doc["image"]), folder_out / Path(str(doc["image"])).name)
            doc["image"] = Path(str(doc["image"])).name
            (folder_out / meta.name).write_text(yaml.safe_dump(doc, sort_keys=False))
            world = folder_out / f"map_{meta.stem}.yaml"
            world.write_text(yaml.safe_dump({
                "name": f"map_{meta.stem}",
                "robot": {"profile": "turtlebot4", "start": {"x": x, "y": y, "yaw": 0.0}},
                "map": {"yaml": meta.name}}, sort_keys=False))
            out.append((f"map:{meta.stem}", str(world)))
    return out[:limit] if limit is not None else out


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

    def coverage(self, learned: Any) -> float:
        """Share of the reachable free cells the learned map reads free."""
        lr = np.floor((self.y - learned.origin.y) / learned.resolution).astype(np.int64)
        lc = np.floor((self.x - learned.origin.x) / learned.resolution).astype(np.int64)
        h, w = learned.data.shape
        ok = (lr >= 0) & (lr < h) & (lc >= 0) & (lc < w)
        values = learned.data[lr[ok], lc[ok]]
        return float(np.count_nonzero((values >= 0) & (values < 25))) / max(1, len(self.x))

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
        """The run's score: RunScore's fields but the world, the strategy and the wall time."""
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
            "coverage_final": float(times[-1, 1]), "time_to_90_s": reached(0.90),
            "time_to_99_s": reached(0.99), "cell_accuracy": tolerant, "cell_accuracy_strict": strict,
            "cells_scored": cells, "path_length_m": path, "reachable_m2": truth.area_m2,
            "goals": sum(e.get("event") == "explore_goal" for e in events),
            "unreachable": sum(e.get("event") == "explore_blacklist" for e in events), "scans": self.scans}


def run_strategies(worlds: list[tuple[str, str]], max_duration: float, jobs: int,
                   tmp: Path) -> list[RunScore]:
    """Every strategy on every world through the batch runner: one batch per strategy, one process pool.

    A run that raised (status ERROR) or whose process died twice (INFRA) is reported and left out.
    """
    from missiontree.evaluation import BatchPlan, PoolEngine, RunSpec, run_batch

    keep = functools.partial(ExploreProbe, frozenset(world for _, world in worlds[:3]))
    names = {world: name for name, world in worlds}
    fields = {f.name for f in dataclasses.fields(RunScore)} - {"world", "strategy", "wall_s"}
    runs: list[RunScore] = []
    with PoolEngine(jobs) as engine:
        for strategy in STRATEGIES:
            tree = tmp / f"explore_{strategy}.yaml"
            tree.write_text(mission_text(STRATEGIES[strategy]), encoding="utf-8")
            specs = [RunSpec(world=world, seed=1, run_seed=1) for _, world in worlds]
            request = {"unknown_map": True, "config": SIM_CONFIG, "max_duration": max_duration}
            plan = BatchPlan(mission=tree, runs=specs, request=request)
            probe = keep if strategy == "ours" else ExploreProbe
            for record in run_batch(plan, engine, tmp / f"batch_{strategy}", probe=probe, write_log=True):
                name = names[str(record.world)]
                if record.status in ("ERROR", "INFRA"):  # one broken run must not lose the others
                    print(f"  {name:22s} {strategy:16s} {record.status} {record.reason}", flush=True)
                    continue
                score = RunScore(world=name, strategy=strategy, wall_s=record.wall_time_s,
                                 **{k: v for k, v in record.figures.items() if k in fields})
                score.scans = [tuple(s) for s in score.scans]  # type: ignore[misc]
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


def summarise(runs: list[RunScore]) -> dict[str, Any]:
    """Per-strategy figures over all worlds."""
    out: dict[str, Any] = {}
    for name in STRATEGIES:
        mine = [r for r in runs if r.strategy == name]
        if not mine:
            continue
        t90 = median_time([r.time_to_90_s for r in mine])
        t99 = median_time([r.time_to_99_s for r in mine])
        out[name] = {
            "coverage_final": round(float(np.median([r.coverage_final for r in mine])), 4),
            "coverage_final_mean": round(float(np.mean([r.coverage_final for r in mine])), 4),
            "coverage_final_min": round(float(np.min([r.coverage_final for r in mine])), 4),
            "time_to_90_s_median": None if t90 is None else round(t90, 1),
            "time_to_99_s_median": None if t99 is None else round(t99, 1),
            "reached_90": sum(r.time_to_90_s is not None for r in mine),
            "reached_99": sum(r.time_to_99_s is not None for r in mine),
            "cell_accuracy": round(float(np.nanmedian([r.cell_accuracy for r in mine])), 4),
            "cell_accuracy_min": round(float(np.nanmin([r.cell_accuracy for r in mine])), 4),
            "cell_accuracy_strict": round(float(np.nanmedian([r.cell_accuracy_strict for r in mine])), 4),
            "path_length_m_median": round(float(np.median([r.path_length_m for r in mine])), 2),
            "duration_s_median": round(float(np.median([r.sim_s for r in mine])), 1),
            "succeeded": sum(r.status == "SUCCESS" for r in mine),
            "runs": len(mine),
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


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="3 generated worlds and one map (a smoke run)")
    parser.add_argument("--worlds", type=int, default=20, help="generated worlds (default 20)")
    parser.add_argument("--first-seed", type=int, default=100, help="seed of the first generated world")
    parser.add_argument("--max-duration", type=float, default=300.0, help="robot-clock limit per run (s)")
    parser.add_argument("--jobs", type=int, default=2, help="runs in parallel (processes)")
    parser.add_argument("--no-maps", action="store_true", help="generated worlds only")
    args = parser.parse_args()
    n_worlds = 3 if args.quick else args.worlds
    started = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        worlds = [] if args.no_maps else map_world_files(Path(tmp), limit=1 if args.quick else None)
        worlds += generated_world_files(Path(tmp), range(args.first_seed, args.first_seed + n_worlds))
        print(f"exploration: {len(worlds)} worlds x {len(STRATEGIES)} strategies, max "
              f"{args.max_duration:g} s each, {args.jobs} processes (the batch runner)", file=sys.stderr)
        runs = run_strategies(worlds, args.max_duration, max(1, args.jobs), Path(tmp))
        order = list(STRATEGIES)
        by_world = {name: i for i, (name, _) in enumerate(worlds)}
        # the order the runs were listed in before the batch runner: strategies rotated world by world
        runs.sort(key=lambda r: (by_world[r.world],
                                 (order.index(r.strategy) - by_world[r.world]) % len(order)))
        for r in runs:
            t90 = "-" if r.time_to_90_s is None else f"{r.time_to_90_s:.0f}"
            t99 = "-" if r.time_to_99_s is None else f"{r.time_to_99_s:.0f}"
            print(f"  {r.world:22s} {r.strategy:16s} {r.status:18s} cov {r.coverage_final:.3f} "
                  f"t90 {t90:>4s} t99 {t99:>4s} acc {r.cell_accuracy:.4f} "
                  f"({r.cell_accuracy_strict:.4f} strict) "
                  f"path {r.path_length_m:5.1f} m  {r.sim_s:5.0f} s sim {r.wall_s:5.1f} s wall  "
                  f"goals {r.goals} unreachable {r.unreachable}  {r.reason[:70]}", flush=True)
    cost = update_cost([s for r in runs for s in r.scans])
    summary = summarise(runs)
    print("\nper strategy (medians over worlds; times on the robot clock):")
    for name, s in summary.items():
        print(f"  {name:16s} coverage {s['coverage_final']:.3f} (min {s['coverage_final_min']:.3f})  "
              f"t90 {s['time_to_90_s_median']} s  t99 {s['time_to_99_s_median']} s  "
              f"accuracy {s['cell_accuracy']:.4f} (strict {s['cell_accuracy_strict']:.4f})  "
              f"path {s['path_length_m_median']} m  succeeded {s['succeeded']}/{s['runs']}")
    r90 = ratios(runs, "time_to_90_s")
    rpath = ratios(runs, "path_length_m")
    print(f"ours / nearest_frontier, time to 90 %: {spread(r90)} over {len(r90)} worlds where both got there")
    print(f"ours / nearest_frontier, path length:  {spread(rpath)}")
    print(f"per-scan update (20 x 20 m at 5 cm, {cost['scans']} recorded scans): numba "
          f"{cost.get('update_ms_median_numba')} ms, numpy {cost.get('update_ms_median_numpy')} ms")
    ours = summary.get("ours", {})
    t90_ratio = spread(r90)["median"]
    result = {
        **summary,
        "update_ms_median": cost["update_ms_median"],
        "update_ms_median_numba": cost.get("update_ms_median_numba"),
        "update_ms_median_numpy": cost.get("update_ms_median_numpy"),
        "update_numpy_over_numba": cost.get("numpy_over_numba"),
        "t90_ratio_ours_vs_nearest": spread(r90),
        "path_ratio_ours_vs_nearest": spread(rpath),
        "targets": {
            "coverage_ge_0.97": bool(ours.get("coverage_final", 0) >= 0.97),
            "cell_accuracy_ge_0.98": bool(ours.get("cell_accuracy", 0) >= 0.98),
            "t90_ratio_le_0.8": bool(t90_ratio is not None and t90_ratio <= 0.8),
            "update_le_1ms": bool(cost["update_ms_median"] is not None and cost["update_ms_median"] <= 1.0),
        },
        "worlds": sorted({r.world for r in runs}),
        "max_duration_s": args.max_duration,
        "wall_s": round(time.perf_counter() - started, 1),
        "runs": [{k: v for k, v in asdict(r).items() if k != "scans"} for r in runs],
    }
    print(json.dumps(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
