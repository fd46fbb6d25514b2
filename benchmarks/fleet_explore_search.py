"""Fleet exploration and search, measured (``benchmarks/fleet_eval.py`` runs them beside the patrol).

**Exploration.** ``trees/fleet_explore.yaml``'s leaf (``FleetExplore``) from no map on each world of
a split, with 1, 2 (and 3) robots. Coverage is the share of the world's reachable free cells (free
cells connected to the start through space the robot's body fits, from the world's map: scoring only,
never seen by the robots) that the fleet's merged map reads free, sampled every ``SAMPLE_S`` s of
robot time. ``explore_time_ratio_2v1`` is, per world, the time two robots took to 90 % coverage over
the time one robot took (median, min and max over the worlds where both reached 90 %).

**Search.** ``trees/fleet_find_object.yaml`` (the single robot's search with the fleet's leaves;
with one robot they are the single robot's) on the search benchmark's cases
(:mod:`search_cases`: a target per world, decoys; the test split's worlds in the cycle's order), with
1 and 2 robots. A run *found* the target when it ended SUCCESS and the confirmed candidate lies within
``FOUND_M`` m of the target's true position; its time is the first ``fleet_found``. An *absent* case
(the target recoloured away) is right when the mission ends FAILURE "not found".
``search_time_ratio_2v1`` is, per case found by both, the two-robot time over the one-robot time.
"""

from __future__ import annotations

import json
import math
import statistics
import sys
import time
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import yaml

from missiontree.backends.sim.world import World, load_world
from missiontree.evaluation.report import wilson
from missiontree.evaluation.splits import split_worlds, write_split_world
from missiontree.session import MissionRequest, run_mission
from missiontree.testing import clean_state

#: Coverage sampling period (robot s).
SAMPLE_S = 2.0
#: The body radius reachability is judged with (m): the TurtleBot 4's 0.17 and a margin.
BODY_M = 0.2
#: A confirmed candidate this close (m) to the target's true position is the target.
FOUND_M = 1.0
ROOT = Path(__file__).resolve().parent.parent


def reachable_cells(world: World) -> tuple[np.ndarray, np.ndarray]:
    """The (x, y) of the world's free cells the robot can reach from its start (scoring only)."""
    g = world.grid
    free = (g.data >= 0) & (g.data < 50)
    clearance = cv2.distanceTransform(free.astype(np.uint8), cv2.DIST_L2, 5) * g.resolution
    fits = (clearance >= BODY_M).astype(np.uint8)
    _, labels = cv2.connectedComponents(fits, connectivity=8)
    r, c = g.world_to_cell(world.start.x, world.start.y)
    label = labels[r, c] if 0 <= r < fits.shape[0] and 0 <= c < fits.shape[1] else 0
    if label == 0:
        rows, cols = np.nonzero(fits)
        k = int(np.argmin((rows - r) ** 2 + (cols - c) ** 2))
        label = labels[rows[k], cols[k]]
    k = int(math.ceil(BODY_M / g.resolution))
    disc = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * k + 1, 2 * k + 1))
    reach = cv2.dilate((labels == label).astype(np.uint8), disc).astype(bool) & free
    rows, cols = np.nonzero(reach)
    return g.origin.x + (cols + 0.5) * g.resolution, g.origin.y + (rows + 0.5) * g.resolution


def coverage(cells: tuple[np.ndarray, np.ndarray], grid: Any) -> float:
    """Share of ``cells`` that ``grid`` reads free."""
    x, y = cells
    rows = np.floor((y - grid.origin.y) / grid.resolution).astype(np.int64)
    cols = np.floor((x - grid.origin.x) / grid.resolution).astype(np.int64)
    h, w = grid.data.shape
    ok = (rows >= 0) & (rows < h) & (cols >= 0) & (cols < w)
    values = grid.data[rows[ok], cols[ok]]
    return float(np.count_nonzero((values >= 0) & (values < 25))) / max(1, len(x))


class CoverageProbe:
    """Samples the fleet's merged map's coverage between ticks (the session's ``on_tick``)."""

    def __init__(self, world: World) -> None:
        self.cells = reachable_cells(world)
        self.next = 0.0
        self.trace: list[tuple[float, float]] = []

    def __call__(self, session: Any) -> None:
        """Sample when due."""
        now = session.robot.now()
        if now < self.next:
            return
        self.next = now + SAMPLE_S
        grid = _fleet_grid(session)
        if grid is not None:
            self.trace.append((now, coverage(self.cells, grid)))

    def time_to(self, share: float) -> float | None:
        """The first sample at or above ``share`` (None: never)."""
        return next((t for t, c in self.trace if c >= share), None)


def _fleet_grid(session: Any) -> Any:
    """The merged map of every robot (one robot: its own map), as the fleet's leaves see it."""
    from missiontree.behaviours.fleet_map import merge_grids

    if session.fleet is None:
        return session.robot.occupancy()
    grids = [g for g in (r.occupancy() for r in session.fleet.clock.fleet.robots) if g is not None]
    return merge_grids(grids) if grids else None


def _reason(summary: dict[str, Any]) -> str:
    fleet = summary.get("fleet") or {}
    ends = [f"{name}: {end.get('status')} {str(end.get('reason') or '')[:160]}"
            for name, end in (fleet.get("robots") or {}).items()]
    return "; ".join(ends) or str(summary.get("reason") or "")[:300]


def explore_run(world_path: Path, robots: int, seed: int, max_duration: float, out: Path) -> dict[str, Any]:
    """One exploration: status, time to 90 % and 99 % coverage, final coverage, CPU."""
    world = load_world(str(world_path))
    probe = CoverageProbe(world)
    clean_state()
    started = time.process_time()
    result = run_mission(MissionRequest(
        mission=ROOT / "trees" / "fleet_explore.yaml", world=str(world_path), robots=robots, seed=seed,
        max_duration=max_duration, out=out, handle_signals=False, on_tick=probe,
        params={"time_budget": int(max_duration - 30)}))
    cpu = time.process_time() - started
    clean_state()
    final = probe.trace[-1][1] if probe.trace else 0.0
    return {"robots": robots, "status": result.status.name, "stopped_by": result.stopped_by,
            "sim_s": round(result.duration, 1), "t90_s": probe.time_to(0.90), "t99_s": probe.time_to(0.99),
            "coverage_final": round(final, 4), "cpu_s": round(cpu, 1),
            "reason": _reason(result.summary)}


def explore_rows(split: str, count: int, first_seed: int, counts: tuple[int, ...], max_duration: float,
                 work: Path) -> list[dict[str, Any]]:
    """Every world of the split explored with each robot count."""
    rows = []
    for sw in split_worlds(split, count, first_seed=first_seed, people=False):
        path = write_split_world(sw, work / "worlds")
        row: dict[str, Any] = {"world": sw.name, "runs": {}}
        for n in counts:
            run = explore_run(path, n, first_seed, max_duration, work / sw.name.replace(":", "_") / f"x{n}")
            row["runs"][n] = run
            print(f"  explore {split} {sw.name} robots={n}: {run['status']} t90 {run['t90_s']} s, "
                  f"final {run['coverage_final']:.3f}, sim {run['sim_s']} s, cpu {run['cpu_s']} s",
                  file=sys.stderr, flush=True)
        rows.append(row)
    return rows


def search_run(case: Any, world_path: Path, robots: int, max_duration: float, out: Path) -> dict[str, Any]:
    """One search: status, the first confirmed find (time, finder, distance to the truth), CPU."""
    world = load_world(str(world_path))
    clean_state()
    started = time.process_time()
    result = run_mission(MissionRequest(
        mission=ROOT / "trees" / "fleet_find_object.yaml", world=str(world_path), robots=robots,
        seed=case.seed, max_duration=max_duration, out=out, handle_signals=False,
        params={"target": case.target, "time_budget": int(max(60, max_duration - 60))}))
    cpu = time.process_time() - started
    clean_state()
    lines = (out / "ticks.jsonl").read_text(encoding="utf-8").splitlines()
    finds = [json.loads(line) for line in lines if '"fleet_found"' in line]
    first = next((f for f in finds if f.get("event") == "fleet_found"), None)
    truth = next((o for o in world.objects if o.id == case.target_id), None)
    distance = None
    if first is not None and truth is not None and first.get("x") is not None:
        distance = math.hypot(float(first["x"]) - truth.pose.x, float(first["y"]) - truth.pose.y)
    status = result.status.name
    found = (not case.absent and status == "SUCCESS" and distance is not None and distance <= FOUND_M)
    return {"robots": robots, "status": status, "stopped_by": result.stopped_by,
            "sim_s": round(result.duration, 1), "found": found,
            "false_found": status == "SUCCESS" and not found,
            "absent_right": case.absent and status == "FAILURE" and result.stopped_by == "status",
            "t_found_s": float(first["t"]) if first is not None and found else None,
            "finder": first.get("finder") if first is not None else None,
            "distance_m": None if distance is None else round(distance, 2), "cpu_s": round(cpu, 1),
            "reason": _reason(result.summary)}


def search_rows(split: str, present: int, absent: int, first_seed: int, counts: tuple[int, ...],
                max_duration: float, work: Path) -> tuple[list[dict[str, Any]], list[str]]:
    """Every search case of the split with each robot count; the worlds the cases skipped."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from search_cases import held_out_cases, make_case

    folder = work / "cases"
    folder.mkdir(parents=True, exist_ok=True)
    if split == "dev":
        cases = [make_case(i, first_seed + i, i >= present, folder) for i in range(present + absent)]
        skipped: list[str] = []
    else:
        cases, skipped = held_out_cases(present, absent, first_seed, folder, "cycle")
    rows = []
    for case, path in cases:
        row: dict[str, Any] = {"world": case.world, "target": case.target, "absent": case.absent, "runs": {}}
        for n in counts:
            run = search_run(case, path, n, max_duration, work / f"case{case.index}" / f"s{n}")
            row["runs"][n] = run
            what = f"{'absent ' if case.absent else ''}{case.target}"
            print(f"  search {split} {case.world} {what} robots={n}: "
                  f"{run['status']} found={run['found']} t {run['t_found_s']} by {run['finder']}, "
                  f"sim {run['sim_s']} s, cpu {run['cpu_s']} s", file=sys.stderr, flush=True)
        rows.append(row)
    return rows, skipped


def _spread(values: list[float]) -> dict[str, Any] | None:
    if not values:
        return None
    return {"median": round(statistics.median(values), 3), "min": round(min(values), 3),
            "max": round(max(values), 3), "n": len(values)}


def explore_summary(rows: list[dict[str, Any]], counts: tuple[int, ...]) -> dict[str, Any]:
    """Per robot count: time to 90 % (min/median/max), runs reaching it, SUCCESS 'explored'; ratios to one."""
    out: dict[str, Any] = {"worlds": len(rows), "t90_s": {}, "reached_90": {}, "explored": {},
                           "ratio_to_1": {}}
    for n in counts:
        runs = [r["runs"][n] for r in rows]
        t90 = [r["t90_s"] for r in runs if r["t90_s"] is not None]
        out["t90_s"][n] = _spread(t90)
        out["reached_90"][n] = f"{len(t90)}/{len(runs)}"
        out["explored"][n] = f"{sum(r['status'] == 'SUCCESS' for r in runs)}/{len(runs)}"
        ratios = [r["runs"][n]["t90_s"] / r["runs"][1]["t90_s"] for r in rows
                  if r["runs"][n]["t90_s"] is not None and r["runs"][1]["t90_s"]]
        out["ratio_to_1"][n] = _spread(ratios)
    out["cpu_s"] = round(sum(run["cpu_s"] for r in rows for run in r["runs"].values()), 1)
    return out


def search_summary(rows: list[dict[str, Any]], counts: tuple[int, ...]) -> dict[str, Any]:
    """Per robot count: found rate (Wilson), false finds, absent right, time to find; ratios to one robot."""
    out: dict[str, Any] = {"cases": len(rows), "found": {}, "false_found": {}, "absent_right": {},
                           "t_found_s": {}, "ratio_to_1": {}}
    present = [r for r in rows if not r["absent"]]
    absent = [r for r in rows if r["absent"]]
    for n in counts:
        ok = sum(r["runs"][n]["found"] for r in present)
        low, high = wilson(ok, len(present)) if present else (0.0, 0.0)
        out["found"][n] = {"ok": ok, "of": len(present), "wilson95": [round(low, 3), round(high, 3)]}
        out["false_found"][n] = sum(r["runs"][n]["false_found"] for r in rows)
        out["absent_right"][n] = f"{sum(r['runs'][n]['absent_right'] for r in absent)}/{len(absent)}"
        out["t_found_s"][n] = _spread([r["runs"][n]["t_found_s"] for r in present if r["runs"][n]["found"]])
        ratios = [r["runs"][n]["t_found_s"] / r["runs"][1]["t_found_s"] for r in present
                  if r["runs"][n]["found"] and r["runs"][1]["found"] and r["runs"][1]["t_found_s"]]
        out["ratio_to_1"][n] = _spread(ratios)
    out["cpu_s"] = round(sum(run["cpu_s"] for r in rows for run in r["runs"].values()), 1)
    return out


def write_rows(path: Path, rows: list[dict[str, Any]]) -> None:
    """Keep the per-run rows (JSON) for the report."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(yaml.safe_dump(rows, sort_keys=False), encoding="utf-8")
