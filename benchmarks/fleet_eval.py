"""Fleet patrol, measured: idleness with 1, 2 and 3 robots, and reassignment after a robot is killed.

Each world of a split (``--split dev|test|both``; dev = generated apartments, test = the held-out
floorplans and real maps of :func:`missiontree.evaluation.splits.split_worlds`, people left out)
gets a patrol route read from its map, never from its ground truth: the free cells with at least
``CLEARANCE`` m to any obstacle and connected to the robot's start through cells with ``PASSAGE``
m (doors), grouped by k-means into ``--waypoints`` groups, each group's cell farthest from
obstacles a spot (spots closer than ``MIN_SPACING`` to an earlier one dropped), toured nearest first
from the start. The real mission runs (``FleetPatrol`` with ``laps: 0`` on the simulator,
loader, builder, runner, leaves) for ``--duration`` s of simulated time with 1, 2 and 3 robots.

**Idleness** (the standard multi-robot patrol measure): a waypoint's idleness at time t is the time
since it was last visited (``waypoint_reached`` in the tick log). It is measured from the moment
every waypoint has been visited once (before that the fleet is still spreading out) to the end of
the run. ``idleness_avg_s`` is its average over waypoints and time; ``idleness_worst_s`` its
largest value (the longest any waypoint waited, the open wait at the end included). A run in which
some waypoint was never visited has no idleness (``null``, counted in ``unvisited_runs``).

**Reassignment**: a one-lap patrol (``laps: 1``) with 3 robots, robot2 killed mid-lap (its goals
abort as a vanished server's, ``--kill-robot``): at half the time the 3-robot idleness run took to
visit every waypoint once (``KILL_AT`` s when it never did), so the kill falls inside the lap on
small maps too. It is OK when the run ends SUCCESS, robot2 is recorded lost, and every waypoint
the fleet could reach was visited (skipped ones are listed); ``reassign_all_visited`` counts the
runs in which every waypoint was visited (none skipped: a dead robot can block a passage).

**Exploration and search** (:mod:`fleet_explore_search`, ``--parts``): time to 90 % coverage of
``trees/fleet_explore.yaml`` with 1-3 robots on ``--explore-worlds`` worlds a split, and time to a
confirmed find of ``trees/fleet_find_object.yaml`` with 1 and 2 robots on ``--search-cases`` cases
with the target (plus ``--absent-cases`` without); the 2-to-1 ratios per world, min/median/max.

Printed: per split and robot count, the idleness (mean over worlds, min-max), the worst-idleness
ratio of N robots to one (per world, then min/median/max), the reassignment rate with its 95 %
Wilson interval, the exploration and search figures, the dev-test gap (test minus dev) and markdown
tables. Last line: one JSON object with ``dev``, ``test``, ``gap``, ``idleness_avg_s`` and
``idleness_worst_s`` (per robot count, test split when run, else dev), ``worst_ratio_3v1``,
``reassign_ok``, ``explore_time_ratio_2v1`` and ``search_time_ratio_2v1`` (medians of the per-world
ratios; null with the reason when that part was not run or no world gave a ratio).
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import yaml

from missiontree.backends.sim.world import World, load_world
from missiontree.evaluation.report import wilson
from missiontree.evaluation.splits import split_worlds, write_split_world
from missiontree.mapping.occupancy import BLOCKED_FROM
from missiontree.session import MissionRequest, run_mission
from missiontree.testing import clean_state

#: Least distance from a waypoint to any obstacle (m).
CLEARANCE = 0.5
#: Least clearance of the free space a route's spots must be connected to the start through (m):
#: the robot's radius (0.18) and a margin, so doors count as passages.
PASSAGE = 0.25
#: Least distance between two waypoints (m).
MIN_SPACING = 1.0
#: When robot2 is killed in the reassignment run (s) when the 3-robot run never visited every waypoint.
KILL_AT = 30.0
COUNTS = (1, 2, 3)

MISSION = """\
version: 1
run: {{backend: sim, tick_hz: 5, seed: {seed}}}
root:
  FleetPatrol:
    name: patrol
    waypoints_file: {route}
    laps: {laps}
    xy_tolerance: 0.3
    waypoint_timeout: 120
"""


def route_spots(world: World, count: int, seed: int) -> list[tuple[float, float]]:
    """``count`` patrol spots from the world's map (see the module docstring), toured nearest first."""
    grid = world.grid
    open_cells = (grid.data < BLOCKED_FROM).astype(np.uint8)
    clearance = cv2.distanceTransform(open_cells, cv2.DIST_L2, 5) * grid.resolution
    free = (clearance >= PASSAGE).astype(np.uint8)  # connected through doors the robot fits through
    _, labels = cv2.connectedComponents(free, connectivity=8)
    row0, col0 = grid.world_to_cell(world.start.x, world.start.y)
    label = labels[row0, col0] if 0 <= row0 < free.shape[0] and 0 <= col0 < free.shape[1] else 0
    if label == 0:  # the start hugs a wall: its nearest qualifying component
        rows, cols = np.nonzero(free)
        nearest = int(np.argmin(np.hypot(rows - row0, cols - col0)))
        label = labels[rows[nearest], cols[nearest]]
    rows, cols = np.nonzero((labels == label) & (clearance >= CLEARANCE))
    if len(rows) < count:  # a cramped map: any cell of the start's free space
        rows, cols = np.nonzero(labels == label)
    xy = np.stack([grid.origin.x + (cols + 0.5) * grid.resolution,
                   grid.origin.y + (rows + 0.5) * grid.resolution], axis=1).astype(np.float32)
    k = min(count, len(xy))
    cv2.setRNGSeed(seed)
    criteria = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 50, 0.01)
    _, groups, _ = cv2.kmeans(xy, k, None, criteria, 3, cv2.KMEANS_PP_CENTERS)  # type: ignore[call-overload]
    spots: list[tuple[float, float]] = []
    for g in range(k):
        members = np.nonzero(groups.ravel() == g)[0]
        best = members[int(np.argmax(clearance[rows[members], cols[members]]))]
        spot = (float(xy[best, 0]), float(xy[best, 1]))
        if all(np.hypot(spot[0] - x, spot[1] - y) >= MIN_SPACING for x, y in spots):
            spots.append(spot)  # two groups' best cells side by side are one waypoint
    return _tour(spots, (world.start.x, world.start.y))


def _tour(spots: list[tuple[float, float]], start: tuple[float, float]) -> list[tuple[float, float]]:
    left, order, here = list(spots), [], start
    while left:
        nxt = min(left, key=lambda p: (p[0] - here[0]) ** 2 + (p[1] - here[1]) ** 2)
        left.remove(nxt)
        order.append(nxt)
        here = nxt
    return order


def idleness(visits: dict[str, list[float]], names: list[str], end: float) -> dict[str, float] | None:
    """Average and worst idleness from when every waypoint was first visited to ``end``.

    None when some waypoint was never visited (or the window is empty).
    """
    if any(not visits.get(n) for n in names):
        return None
    t0 = max(min(visits[n]) for n in names)
    if end <= t0:
        return None
    area, worst = 0.0, 0.0
    for n in names:
        times = sorted(visits[n])
        last = max(t for t in times if t <= t0)
        for t in [t for t in times if t > t0] + [end]:
            a, b = max(last, t0), t
            # idleness grows from (a - last) to (b - last) over [a, b]
            area += (b - a) * ((a - last) + (b - last)) / 2.0
            worst = max(worst, b - last)
            last = t
    return {"avg": area / ((end - t0) * len(names)), "worst": worst, "window_s": end - t0}


def _events(run_dir: Path) -> list[dict[str, Any]]:
    lines = (run_dir / "ticks.jsonl").read_text(encoding="utf-8").splitlines()
    return [json.loads(line) for line in lines if '"event":"tick"' not in line]


def one_run(world: Path, route: Path, robots: int, seed: int, duration: float, laps: int,
            out: Path, kill: str | None = None) -> dict[str, Any]:
    """Run the fleet patrol once; its visits, status and fleet section."""
    mission = out / "mission.yaml"
    out.mkdir(parents=True, exist_ok=True)
    mission.write_text(MISSION.format(seed=seed, route=route, laps=laps), encoding="utf-8")
    clean_state()
    started = time.process_time()
    result = run_mission(MissionRequest(mission=mission, world=str(world), robots=robots,
                                        max_duration=duration, out=out / "run", handle_signals=False,
                                        kill_robots=[kill] if kill else []))
    cpu = time.process_time() - started
    clean_state()
    visits: dict[str, list[float]] = {}
    for e in _events(out / "run"):
        if e["event"] == "waypoint_reached":
            visits.setdefault(str(e["waypoint"]), []).append(float(e["t"]))
    return {"status": result.status.name, "stopped_by": result.stopped_by, "visits": visits, "cpu_s": cpu,
            "duration": result.duration, "fleet": result.summary.get("fleet")}


def world_rows(split: str, count: int, first_seed: int, waypoints: int, duration: float,
               work: Path) -> list[dict[str, Any]]:
    """Every world of the split: idleness per robot count and the reassignment run."""
    rows = []
    for sw in split_worlds(split, count, first_seed=first_seed, people=False):
        path = write_split_world(sw, work / "worlds")
        world = load_world(str(path))
        seed = first_seed  # one run seed for every world: the worlds differ
        spots = route_spots(world, waypoints, seed)
        names = [f"W{i + 1}" for i in range(len(spots))]
        route = work / f"{sw.name.replace(':', '_')}_route.yaml"
        route.write_text(yaml.safe_dump({"waypoints": [{"name": n, "x": x, "y": y, "yaw": 0.0}
                                                       for n, (x, y) in zip(names, spots, strict=True)]}))
        row: dict[str, Any] = {"world": sw.name, "waypoints": len(spots), "idleness": {}, "cpu_s": 0.0}
        first_all: float | None = None
        for robots in COUNTS:
            run = one_run(path, route, robots, seed, duration, 0,
                          work / sw.name.replace(":", "_") / f"r{robots}")
            row["idleness"][robots] = idleness(run["visits"], names, run["duration"])
            row["cpu_s"] += run["cpu_s"]
            print(f"  {split} {sw.name} robots={robots}: {_fmt(row['idleness'][robots])} "
                  f"({sum(len(v) for v in run['visits'].values())} visits, cpu {run['cpu_s']:.0f} s)",
                  file=sys.stderr)
            if robots == 3:
                visits = run["visits"]
                first_all = max(min(visits[n]) for n in names) if all(visits.get(n) for n in names) else None
        kill_at = round(first_all / 2.0, 1) if first_all else KILL_AT
        folder = work / sw.name.replace(":", "_") / "kill"
        row["reassign"] = reassign(path, route, names, seed, folder, kill_at)
        rows.append(row)
    return rows


def reassign(world: Path, route: Path, names: list[str], seed: int, out: Path,
             kill_at: float) -> dict[str, Any]:
    """One lap with 3 robots, robot2 killed at ``kill_at``: does the fleet still visit everything?"""
    run = one_run(world, route, 3, seed, 900.0, 1, out, kill=f"robot2@{kill_at:g}")
    fleet = run["fleet"] or {}
    dispatch: dict[str, Any] = next(iter((fleet.get("dispatchers") or {}).values()), {})
    skipped = dispatch.get("skipped") or {}
    missing = [n for n in names if n not in run["visits"] and n not in skipped]
    ok = run["status"] == "SUCCESS" and fleet.get("lost") == ["robot2"] and not missing
    all_visited = ok and all(n in run["visits"] for n in names)
    return {"ok": ok, "all_visited": all_visited, "kill_at": kill_at, "status": run["status"],
            "lost": fleet.get("lost"),
            "missing": missing, "skipped": sorted(skipped),
            "rebalances": len(dispatch.get("rebalances") or [])}


def _fmt(found: dict[str, float] | None) -> str:
    return "never visited every waypoint" if found is None else \
        f"avg {found['avg']:.1f} s, worst {found['worst']:.1f} s"


def aggregate(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """Mean idleness per robot count, worst ratios to one robot, reassignment rate."""
    out: dict[str, Any] = {"worlds": len(rows), "idleness_avg_s": {}, "idleness_worst_s": {},
                           "unvisited_runs": {}, "worst_ratio_to_1": {}}
    for n in COUNTS:
        found = [r["idleness"][n] for r in rows if r["idleness"][n] is not None]
        out["unvisited_runs"][n] = len(rows) - len(found)
        out["idleness_avg_s"][n] = round(statistics.mean(f["avg"] for f in found), 2) if found else None
        out["idleness_worst_s"][n] = round(statistics.mean(f["worst"] for f in found), 2) if found else None
        ratios = [r["idleness"][n]["worst"] / r["idleness"][1]["worst"] for r in rows
                  if r["idleness"][n] is not None and r["idleness"][1] is not None]
        out["worst_ratio_to_1"][n] = ({"min": round(min(ratios), 3), "max": round(max(ratios), 3),
                                       "median": round(statistics.median(ratios), 3), "n": len(ratios)}
                                      if ratios else None)
    ok = sum(1 for r in rows if r["reassign"]["ok"])
    low, high = wilson(ok, len(rows)) if rows else (0.0, 0.0)
    out["reassign_ok"] = {"ok": ok, "of": len(rows), "rate": round(ok / len(rows), 3) if rows else None,
                          "wilson95": [round(low, 3), round(high, 3)]}
    every = sum(1 for r in rows if r["reassign"]["all_visited"])
    low, high = wilson(every, len(rows)) if rows else (0.0, 0.0)
    out["reassign_all_visited"] = {"ok": every, "of": len(rows), "wilson95": [round(low, 3), round(high, 3)]}
    out["reassign_failures"] = [{"world": r["world"], **r["reassign"]} for r in rows
                                if not r["reassign"]["all_visited"]]
    return out


def gap(dev: dict[str, Any], test: dict[str, Any]) -> dict[str, Any]:
    """Test minus dev of each figure both have."""
    found: dict[str, Any] = {}
    for key in ("idleness_avg_s", "idleness_worst_s"):
        found[key] = {n: (round(test[key][n] - dev[key][n], 2) if test[key][n] is not None and
                          dev[key][n] is not None else None) for n in COUNTS}
    rates = (dev["reassign_ok"]["rate"], test["reassign_ok"]["rate"])
    found["reassign_ok"] = None if None in rates else round(rates[1] - rates[0], 3)
    return found


def table(results: dict[str, dict[str, Any]]) -> str:
    """The markdown table of both splits."""
    lines = ["| split | worlds | robots | idleness avg (s) | idleness worst (s) | worst / 1 robot (median) "
             "| reassign OK | all visited after the loss |", "|---|---|---|---|---|---|---|---|"]
    for split, agg in results.items():
        for n in COUNTS:
            ratio = agg["worst_ratio_to_1"][n]
            r = agg["reassign_ok"]
            lines.append(f"| {split} | {agg['worlds']} | {n} | {agg['idleness_avg_s'][n]} | "
                         f"{agg['idleness_worst_s'][n]} | {ratio['median'] if ratio else None} | "
                         f"{r['ok']}/{r['of']} [{r['wilson95'][0]}, {r['wilson95'][1]}] | "
                         f"{agg['reassign_all_visited']['ok']}/{r['of']} |")
    return "\n".join(lines)


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--split", choices=("dev", "test", "both"), default="both")
    parser.add_argument("--parts", default="patrol,explore,search",
                        help="comma-separated: patrol, explore, search")
    parser.add_argument("--worlds", type=int, default=3, help="patrol worlds per split")
    parser.add_argument("--first-seed", type=int, default=0)
    parser.add_argument("--waypoints", type=int, default=8)
    parser.add_argument("--duration", type=float, default=480.0, help="simulated seconds per idleness run")
    parser.add_argument("--explore-worlds", type=int, default=3, help="exploration worlds per split")
    parser.add_argument("--explore-robots", default="1,2,3", help="robot counts explored with")
    parser.add_argument("--explore-duration", type=float, default=600.0, help="robot s per exploration")
    parser.add_argument("--search-cases", type=int, default=3, help="search cases with the target a split")
    parser.add_argument("--absent-cases", type=int, default=1, help="search cases without the target")
    parser.add_argument("--search-robots", default="1,2", help="robot counts searched with")
    parser.add_argument("--search-duration", type=float, default=600.0, help="robot s per search")
    parser.add_argument("--out", type=Path, default=None, help="work folder (default: a temporary one)")
    return parser


def _run_split(split: str, args: argparse.Namespace, parts: set[str], work: Path) -> dict[str, Any]:
    """One split's patrol, exploration and search figures (the parts asked for)."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from fleet_explore_search import explore_rows, explore_summary, search_rows, search_summary, write_rows

    found: dict[str, Any] = {}
    if "patrol" in parts:
        rows = world_rows(split, args.worlds, args.first_seed, args.waypoints, args.duration, work / "patrol")
        found = aggregate(rows)
        found["cpu_s"] = round(sum(r["cpu_s"] for r in rows), 1)
    if "explore" in parts:
        counts = tuple(int(n) for n in args.explore_robots.split(","))
        xrows = explore_rows(split, args.explore_worlds, args.first_seed, counts, args.explore_duration,
                             work / "explore")
        write_rows(work / "explore_rows.yaml", xrows)
        found["explore"] = {**explore_summary(xrows, counts), "rows": xrows}
    if "search" in parts:
        counts = tuple(int(n) for n in args.search_robots.split(","))
        srows, skipped = search_rows(split, args.search_cases, args.absent_cases, args.first_seed, counts,
                                     args.search_duration, work / "search")
        write_rows(work / "search_rows.yaml", srows)
        found["search"] = {**search_summary(srows, counts), "skipped": skipped, "rows": srows}
    return found


def _ratio(split: dict[str, Any] | None, part: str) -> float | None:
    spread = (((split or {}).get(part) or {}).get("ratio_to_1") or {}).get(2)
    return spread["median"] if spread else None


def _why_null(results: dict[str, Any], part: str, split: str) -> str | None:
    if split not in results:
        return None
    if part not in results[split]:
        return f"the {part} part was not run (--parts)"
    if _ratio(results[split], part) is None:
        return f"no {split} world gave both a 1- and a 2-robot time ({part})"
    return None


def table_parts(results: dict[str, dict[str, Any]]) -> str:
    """The markdown table of exploration and search per split and robot count."""
    lines = ["| split | part | robots | n | done | time (s), median (min-max) | 2 v 1, median (min-max) |",
             "|---|---|---|---|---|---|---|"]
    for split, found in results.items():
        for part, done_key, time_key in (("explore", "reached_90", "t90_s"),
                                         ("search", "found", "t_found_s")):
            if part not in found:
                continue
            agg = found[part]
            for n, spread in agg[time_key].items():
                done = agg[done_key][n]
                done_text = (f"{done['ok']}/{done['of']} [{done['wilson95'][0]}, {done['wilson95'][1]}]"
                             if isinstance(done, dict) else done)
                ratio = agg["ratio_to_1"][n]
                size = agg.get("worlds", agg.get("cases"))
                lines.append(f"| {split} | {part} | {n} | {size} | {done_text} | "
                             f"{_fmt_spread(spread)} | {_fmt_spread(ratio)} |")
    return "\n".join(lines)


def _fmt_spread(spread: dict[str, Any] | None) -> str:
    return "-" if spread is None else f"{spread['median']} ({spread['min']}-{spread['max']}, n={spread['n']})"


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark; print per-world lines, the tables and the JSON line."""
    args = _parser().parse_args(argv)
    parts = set(args.parts.split(","))
    splits = ("dev", "test") if args.split == "both" else (args.split,)
    results: dict[str, dict[str, Any]] = {}
    with tempfile.TemporaryDirectory(prefix="fleet_eval_") as tmp:
        work = args.out or Path(tmp)
        for split in splits:
            results[split] = _run_split(split, args, parts, work / split)
    if "patrol" in parts:
        print(table(results))
    print(table_parts(results))
    headline_split = "test" if "test" in results else "dev"
    headline = results.get(headline_split) or {}
    ratio = (headline.get("worst_ratio_to_1") or {}).get(3)
    final = {
        "dev": results.get("dev"), "test": results.get("test"),
        "gap": _gaps(results) if len(results) == 2 else None,
        "idleness_avg_s": headline.get("idleness_avg_s"),
        "idleness_worst_s": headline.get("idleness_worst_s"),
        "worst_ratio_3v1": ratio["median"] if ratio else None,
        "reassign_ok": (headline.get("reassign_ok") or {}).get("rate"),
        "reassign_all_visited": headline.get("reassign_all_visited"),
        "explore_time_ratio_2v1": _ratio(headline, "explore"),
        "search_time_ratio_2v1": _ratio(headline, "search"),
        "not_measured": {k: v for k, v in (
            ("explore_time_ratio_2v1", _why_null(results, "explore", headline_split)),
            ("search_time_ratio_2v1", _why_null(results, "search", headline_split))) if v},
        "settings": {k: (str(v) if isinstance(v, Path) else v) for k, v in vars(args).items()},
    }
    print(json.dumps(final, sort_keys=True, default=str))
    return 0


def _gaps(results: dict[str, dict[str, Any]]) -> dict[str, Any]:
    """Test minus dev: the patrol's figures (when run) and the 2-to-1 ratios."""
    dev, test = results["dev"], results["test"]
    found = gap(dev, test) if "idleness_avg_s" in dev and "idleness_avg_s" in test else {}
    for part in ("explore", "search"):
        a, b = _ratio(dev, part), _ratio(test, part)
        found[f"{part}_time_ratio_2v1"] = None if a is None or b is None else round(b - a, 3)
    return found


if __name__ == "__main__":
    raise SystemExit(main())
