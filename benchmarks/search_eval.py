"""Object search: ours (trees/find_object.yaml) against the vision-language object-search report's method.

    python benchmarks/search_eval.py                   # both splits: dev 50 + 10 absent, test 20 + 5
    python benchmarks/search_eval.py --split dev       # tuning: the dev split only
    python benchmarks/search_eval.py --split test      # reporting: the held-out split, once a change is done
    python benchmarks/search_eval.py --quick           # dev 6 + 2, test 6 + 2 (a loaded 2-core machine)
    python benchmarks/search_eval.py --workers 2       # two missions at once

Splits. ``dev`` (what the search is tuned on): apartments from
:mod:`missiontree.backends.sim.generator` (4 rooms, no people), seeds from ``--first-seed`` (100).
``test`` (nobody tunes on it; report it once at the end of a change): the worlds of
:func:`missiontree.evaluation.splits.split_worlds` ("test") -- a second generator family (long
corridors with many 0.8-0.9 m doors, L and T corridors, open plan, rooms off rooms, clutter near
doors, warehouse floors) and real SLAM maps with objects placed by a placement generator. The test
sample is taken in whole rounds of the split's cycle, each round's real maps first
(``--test-order maps-first``, :func:`held_out_seeds`): a sample smaller than the cycle still holds
TurtleBot 4's warehouse and depot maps, the maze, Nav2's sandbox and (when installed) MRPT's grids;
the absent cases follow in the same order. The test figures are printed with 95 % Wilson intervals,
beside dev's, with the dev - test gap.

Worlds are edited for the search (``search_cases.py``; the generators are untouched), the
same way on both splits: a target (class and colour, e.g. "red backpack") is chosen per world among
the small objects (those the generator describes, or any object under 0.6 m across and 1 m high);
when no small object is of a target class, one is made into one. Decoys of both kinds are made sure
of -- an object of the same class in another colour and one of the same colour in another class
(missing ones are made by recolouring or relabelling another small object); any second object
matching the target is recoloured, so exactly one is right. In the ``absent`` cases the target itself
is recoloured into one more decoy: nothing matches. A world without a small object is skipped (counted).

Methods, each through the batch runner (:func:`missiontree.evaluation.run_batch`, a probe reading the
true final pose in the worker) with its mission's own ``run:`` section (map mode included), the worlds
in chunks run by one method then the other, alternating which goes first:

- ``ours``: ``trees/find_object.yaml`` on an unknown map (the robot starts knowing nothing): semantic
  map from every frame, known candidates first, exploration weighted by room priors, standoff
  approach from depth, VLM check on the detection.
- ``report``: ``trees/examples/report_search.yaml`` on the known map (the report localises with AMCL
  on a map SLAM built beforehand, so its scan points cover the whole place from the start): scan
  points with 360-degree scans, colour trigger, box-area approach steps, whole-frame VLM check,
  rounds without memory. The known map is a head start for the reference, not for ours. By default
  the reference runs on dev only (``--reference dev``): on the test split's large floors its
  rounds without memory take most of the time limit, and it is not what the issue's targets are on;
  ``--reference both`` runs it on both.

Scoring reads the simulator's ground truth after the run (never the leaves): a run *finds* the
target when it ends SUCCESS with the robot within ``REACH`` m of the target's footprint and facing
it (bearing error under ``FACING_DEG``). A *false found* is a SUCCESS anywhere else (or any SUCCESS
in an absent case); ``false_found_wrong_object`` counts those where the target was not even in view
(farther than ``VIEW_RANGE`` or outside the camera's half field of view): another object was taken
for it. The time comparison is also given paired: ours / report on the cases both found.
An absent case is *correct* when the run ends FAILURE by the tree's own verdict (not the time
limit) with a reason ("not found: ..."). Time to find is robot-clock seconds of the successful runs.
The time limit is ``--max-duration`` (600 s on dev; on test the mission's own 900 s, as its floors
are up to 30 x 50 m). Last line: JSON, ``{"dev": {...}, "test": {...}, "gap": {...}}``.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import shutil
import statistics
import sys
import tempfile
import threading
import time
from collections import Counter
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))  # search_cases, search_why beside it
from search_cases import (  # noqa: E402  (the cases, importable from here as before)
    CLASS_SHAPES,
    PALETTE,
    TARGETS,
    Case,
    edit_world,
    held_out_cases,
    held_out_seeds,
    make_case,
    small_objects,
)

__all__ = ["CLASS_SHAPES", "PALETTE", "TARGETS", "Case", "edit_world", "held_out_cases", "held_out_seeds",
           "make_case", "small_objects"]

REPO = Path(__file__).resolve().parents[1]
MISSIONS = {
    "ours": REPO / "trees" / "find_object.yaml",
    "report": REPO / "trees" / "examples" / "report_search.yaml",
}
REACH = 1.0
FACING_DEG = 30.0
#: A "found" with the target farther than this or outside the half field of view is of another object.
VIEW_RANGE, HALF_FOV_DEG = 3.0, 35.0
#: Robot seconds between the true poses the probe keeps for the report's why.
TRACE_S = 0.5


SPLITS = ("dev", "test")


@dataclass
class Trial:
    """One method on one case, scored against the truth."""

    method: str
    case: int
    seed: int
    target: str
    absent: bool
    split: str = "dev"
    status: str = ""
    stopped_by: str = ""
    reason: str = ""
    sim_s: float = math.nan
    wall_s: float = math.nan
    path_m: float = 0.0
    distance_m: float = math.nan
    bearing_deg: float = math.nan
    found: bool = False
    false_found: bool = False
    wrong_object: bool = False
    absent_correct: bool = False
    why: dict[str, Any] | None = None
    phases: dict[str, float] | None = None


class SearchProbe:
    """Reads, inside the batch worker, what scoring needs: the true final pose and the search's verdict.

    Also the true pose every :data:`TRACE_S` robot seconds and the tick log's phases and candidates,
    for the report's why (:mod:`search_why`). The true pose is the simulator's ground truth (scoring
    and diagnosis only; the leaves never see it).
    """

    def __init__(self) -> None:
        self.trace: list[list[float]] = []

    def on_tick(self, session: Any) -> None:
        """The true pose, once every TRACE_S robot seconds."""
        now = float(session.robot.now())
        if self.trace and now - self.trace[-1][0] < TRACE_S:
            return
        pose = session.robot.truth.robot_pose()
        self.trace.append([round(now, 2), round(pose.x, 3), round(pose.y, 3), round(pose.yaw, 3)])

    def finish(self, session: Any, result: Any) -> dict[str, Any]:
        """The true final pose, the search's last found / not-found message, the trace, phases, candidates."""
        from search_why import phases, search_events

        pose = session.robot.truth.robot_pose()
        log = (session.run_dir / "ticks.jsonl").read_text(encoding="utf-8")
        return {"final_pose": [pose.x, pose.y, pose.yaw], "search_reason": _reason(log),
                "trace": self.trace, "phases": phases(log), "search_events": search_events(log)}


def score(trial: Trial, case: Case, world: Any, record: Any) -> Trial:
    """Fill ``trial`` from a batch record and score it against the world's truth."""
    trial.status = record.status
    trial.stopped_by = str(record.stopped_by)
    trial.reason = str(record.figures.get("search_reason") or record.reason)
    trial.sim_s = float(record.robot_time_s)
    trial.wall_s = float(record.wall_time_s)
    trial.path_m = float(record.path_length_m)
    final = record.figures.get("final_pose")
    obj = next(o for o in world.objects if o.id == case.target_id)
    if final is not None:
        from missiontree.types import Pose2D

        pose = Pose2D(*final)
        trial.distance_m = _footprint_distance(obj.footprint(), (pose.x, pose.y))
        trial.bearing_deg = abs(math.degrees(pose.bearing_to(obj.pose.x, obj.pose.y)))
    claimed = trial.status == "SUCCESS"
    on_target = not case.absent and trial.distance_m <= REACH and trial.bearing_deg <= FACING_DEG
    trial.found = claimed and on_target
    trial.false_found = claimed and not on_target
    trial.wrong_object = claimed and (
        case.absent or not trial.distance_m <= VIEW_RANGE or not trial.bearing_deg <= HALF_FOV_DEG
    )
    trial.absent_correct = (
        case.absent and not claimed and trial.stopped_by == "status" and "not found" in trial.reason
    )
    trial.phases = record.figures.get("phases")
    trace = record.figures.get("trace")
    if trace is not None and not case.absent:
        from search_why import diagnose

        events = record.figures.get("search_events") or []
        trial.why = diagnose(trace, world, obj, events, trial.found)
    return trial


def run_chunk(
    method: str,
    cases: list[tuple[Case, Path]],
    engine: Any,
    out: Path,
    max_duration: float,
    report: Any,
) -> list[Any]:
    """Run one method's mission on ``cases`` with the batch runner; ``report`` gets each record."""
    from missiontree.evaluation import BatchPlan, RunSpec, run_batch

    specs = [
        RunSpec(
            world=str(path), seed=case.seed, run_seed=case.seed, params=_params(method, case, max_duration)
        )
        for case, path in cases
    ]
    plan = BatchPlan(mission=MISSIONS[method], runs=specs, request={"max_duration": max_duration})
    return run_batch(
        plan,
        engine,
        out / f"batch_{method}",
        resume=True,  # one batch directory per method, filled chunk by chunk
        probe=SearchProbe,
        on_record=lambda record, _skipped: report(method, record),
    )


def _params(method: str, case: Case, max_duration: float) -> tuple[tuple[str, str], ...]:
    """The mission's parameters: the target, and for ours the search's time budget (the limit less 60 s)."""
    if method != "ours":
        return (("target", case.target),)
    return (("target", case.target), ("time_budget", f"{max(60.0, max_duration - 60.0):g}"))


def _footprint_distance(corners: np.ndarray, xy: tuple[float, float]) -> float:
    """Distance from ``xy`` to a convex outline (0 inside)."""
    p = np.asarray(xy, dtype=float)
    best = math.inf
    inside = True
    n = len(corners)
    for i in range(n):
        a, b = corners[i], corners[(i + 1) % n]
        ab, ap = b - a, p - a
        t = float(np.clip(np.dot(ap, ab) / max(float(np.dot(ab, ab)), 1e-12), 0.0, 1.0))
        best = min(best, float(np.linalg.norm(a + t * ab - p)))
        if ab[0] * ap[1] - ab[1] * ap[0] < 0:
            inside = False
    return 0.0 if inside else best


def _reason(log: str) -> str:
    """The last failure reason or found message of the search leaves in the tick log."""
    reason = ""
    for line in log.splitlines():
        if '"object_found"' in line or '"search_explored"' in line or "not found" in line:
            try:
                event = json.loads(line)
            except json.JSONDecodeError:
                continue
            if event.get("event") == "object_found":
                reason = f"found {event.get('id')} ({event.get('reason', '')})"
            for change in event.get("changed", []) if event.get("event") == "tick" else []:
                if "not found" in str(change.get("feedback", "")):
                    reason = str(change["feedback"])[:160]
    return reason


def summarise(trials: list[Trial], method: str) -> dict[str, Any]:
    """Rates (with 95 % Wilson intervals) and medians of one method's trials."""
    from missiontree.evaluation.report import wilson

    mine = [t for t in trials if t.method == method]
    present = [t for t in mine if not t.absent]
    absent = [t for t in mine if t.absent]
    found = [t for t in present if t.found]
    times = sorted(t.sim_s for t in found)
    claimed = [t for t in present if t.status == "SUCCESS"]
    n_ok = sum(t.absent_correct for t in absent)

    def med(values: list[float]) -> float | None:
        return round(statistics.median(values), 3) if values else None

    def ci(k: int, n: int) -> list[float] | None:
        return [round(v, 4) for v in wilson(k, n)] if n else None

    return {
        "runs": len(mine),
        "present": len(present),
        "absent": len(absent),
        "success_rate": round(len(found) / len(present), 4) if present else None,
        "success_ci95": ci(len(found), len(present)),
        "false_found": sum(t.false_found for t in mine),
        "false_found_wrong_object": sum(t.wrong_object for t in mine),
        "absent_correct_rate": round(n_ok / len(absent), 4) if absent else None,
        "absent_correct_ci95": ci(n_ok, len(absent)),
        "time_to_find_s_median": med(times),
        "time_to_find_s_p90": round(float(np.percentile(times, 90)), 3) if times else None,
        "path_length_m_median": med([t.path_m for t in found]),
        "final_distance_error_m_median": med([t.distance_m for t in claimed]),
        "final_bearing_error_deg_median": med([t.bearing_deg for t in claimed]),
        "timeouts": sum(t.stopped_by != "status" for t in mine),
        "misses_by_cause": dict(Counter(t.why["cause"] for t in present if t.why and not t.found)),
        "wall_s_median": med([t.wall_s for t in mine]),
    }


def paired_ratios(trials: list[Trial]) -> dict[str, Any]:
    """Ours / report time to find on the cases both found: min, median, max and how many cases."""
    found = {(t.method, t.case): t.sim_s for t in trials if t.found}
    ratios = sorted(
        found[("ours", c)] / found[("report", c)]
        for m, c in found
        if m == "ours" and ("report", c) in found and found[("report", c)] > 0
    )
    if not ratios:
        return {"cases": 0}
    return {
        "cases": len(ratios),
        "min": round(ratios[0], 3),
        "median": round(statistics.median(ratios), 3),
        "max": round(ratios[-1], 3),
    }


#: Figures whose dev - test gap is reported (rates; the issue's targets are on test).
GAP_KEYS = ("success_rate", "absent_correct_rate")


def gaps(dev: dict[str, Any], test: dict[str, Any]) -> dict[str, Any]:
    """Dev - test of ours' rates (positive: test is worse), and test / dev of the median time."""
    out: dict[str, Any] = {}
    d, t = dev.get("ours", {}), test.get("ours", {})
    for key in GAP_KEYS:
        if d.get(key) is not None and t.get(key) is not None:
            out[key] = round(d[key] - t[key], 4)
    if d.get("time_to_find_s_median") and t.get("time_to_find_s_median"):
        out["time_to_find_ratio_test_vs_dev"] = round(
            t["time_to_find_s_median"] / d["time_to_find_s_median"], 3
        )
    return out


def markdown_table(results: dict[str, Any]) -> str:
    """A short markdown table of ours (and the reference where run) per split."""

    def rate(s: dict[str, Any], key: str) -> str:
        value, ci = s.get(key), s.get(key.replace("_rate", "_ci95"))
        if value is None:
            return "-"
        return f"{value:.3f} [{ci[0]:.2f}, {ci[1]:.2f}]" if ci else f"{value:.3f}"

    lines = [
        "| split | method | runs | success [95 % CI] | false found | absent reported [95 % CI] "
        "| time to find (median s) | timeouts |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for split in SPLITS:
        for method in MISSIONS:
            s = results.get(split, {}).get(method)
            if not s or not s.get("runs"):
                continue
            lines.append(
                f"| {split} | {method} | {s['present']} + {s['absent']} absent | "
                f"{rate(s, 'success_rate')} | {s['false_found']} | {rate(s, 'absent_correct_rate')} | "
                f"{s['time_to_find_s_median']} | {s['timeouts']} |"
            )
    gap = results.get("gap") or {}
    if gap:
        lines.append("")
        lines.append("dev - test gap (ours): " + ", ".join(f"{k} {v}" for k, v in gap.items()))
    return "\n".join(lines)


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--split", choices=["dev", "test", "both"], default="both")
    parser.add_argument("--quick", action="store_true", help="6 worlds with the target + 2 without, a split")
    parser.add_argument("--worlds", type=int, default=None, help="dev worlds with the target (default 50)")
    parser.add_argument("--absent", type=int, default=None, help="dev worlds without it (default 10)")
    parser.add_argument("--test-worlds", type=int, default=None, help="test worlds with the target (20)")
    parser.add_argument("--test-absent", type=int, default=None, help="test worlds without it (default 5)")
    parser.add_argument("--max-duration", type=float, default=None, help="robot s a mission (dev 600)")
    parser.add_argument("--test-max-duration", type=float, default=900.0, help="robot s a test mission")
    parser.add_argument("--workers", type=int, default=1, help="missions run at once")
    parser.add_argument("--first-seed", type=int, default=100, help="dev: the first generator seed")
    parser.add_argument("--dev-rooms", type=int, default=4, help="dev: rooms an apartment (large floors)")
    parser.add_argument("--dev-size", default="", help="dev: apartment size WxH in m (default: the seed's)")
    parser.add_argument("--test-first-seed", type=int, default=0, help="test: the splits API's first seed")
    parser.add_argument(
        "--test-order",
        choices=["maps-first", "cycle"],
        default="maps-first",
        help="test: each round of the cycle's real maps first (a small sample holds them), or in order",
    )
    parser.add_argument(
        "--reference",
        choices=["dev", "test", "both", "none"],
        default="dev",
        help="splits the report's method runs on (dev: the test floors take it most of the limit)",
    )
    parser.add_argument("--keep", default="", help="keep the worlds and runs (tick logs) in this directory")
    return parser


def _cases(split: str, args: argparse.Namespace, folder: Path) -> tuple[list[tuple[Case, Path]], list[str]]:
    """One split's cases (written into ``folder``) and the worlds skipped."""
    n_present, n_absent = _counts(args)[split]
    if split == "dev":
        size = _size(args.dev_size)
        n = n_present + n_absent
        return [
            make_case(i, args.first_seed + i, i >= n_present, folder, args.dev_rooms, size) for i in range(n)
        ], []
    return held_out_cases(n_present, n_absent, args.test_first_seed, folder, args.test_order)


def _counts(args: argparse.Namespace) -> dict[str, tuple[int, int]]:
    """(worlds with the target, worlds without) per split, from the options."""
    return {
        "dev": (
            args.worlds if args.worlds is not None else (6 if args.quick else 50),
            args.absent if args.absent is not None else (2 if args.quick else 10),
        ),
        "test": (
            args.test_worlds if args.test_worlds is not None else (6 if args.quick else 20),
            args.test_absent if args.test_absent is not None else (2 if args.quick else 5),
        ),
    }


def _split_results(
    split: str, cases: list[tuple[Case, Path]], skipped: list[str], methods: list[str], mine: list[Trial],
    limit: float,
) -> dict[str, Any]:
    """One split's figures per method (printed as a line each), and the paired time ratio."""
    out: dict[str, Any] = {
        "worlds": sum(not c.absent for c, _ in cases),
        "absent_cases": sum(c.absent for c, _ in cases),
        "skipped": len(skipped),
        "max_duration_s": limit,
        "families": sorted({c.world.split(":")[0] for c, _ in cases}),
    }
    for method in methods:
        out[method] = s = summarise(mine, method)
        print(
            f"{split} {method}: success {s['success_rate']} {s['success_ci95']}, false found "
            f"{s['false_found']}, absent correct {s['absent_correct_rate']} "
            f"{s['absent_correct_ci95']}, time to find median {s['time_to_find_s_median']} s "
            f"(p90 {s['time_to_find_s_p90']}), path {s['path_length_m_median']} m, final "
            f"distance {s['final_distance_error_m_median']} m, bearing "
            f"{s['final_bearing_error_deg_median']} deg",
            flush=True,
        )
    if "report" in methods:
        ours, ref = s_get(out, "ours"), s_get(out, "report")
        out["time_ratio_ours_vs_report"] = round(ours / ref, 3) if ours and ref else None
        out["time_ratio_paired"] = paired_ratios(mine)
        print(f"{split}: time to find, ours / report on the cases both found: {out['time_ratio_paired']}")
    return out


def main(argv: list[str] | None = None) -> int:
    from missiontree.backends.sim import load_world

    args = _parser().parse_args(argv)
    splits = list(SPLITS) if args.split == "both" else [args.split]
    limits = {"dev": args.max_duration or 600.0, "test": args.test_max_duration}
    results: dict[str, Any] = {}
    started = time.perf_counter()
    with tempfile.TemporaryDirectory() if not args.keep else _kept(args.keep) as tmp:
        for split in splits:
            folder = Path(tmp) / split
            folder.mkdir()
            cases, skipped = _cases(split, args, folder)
            for line in skipped:
                print(f"{split}: skipped {line}", flush=True)
            methods = ["ours"] + (["report"] if args.reference in (split, "both") else [])
            mine = run_split(split, cases, methods, args.workers, folder, limits[split], load_world)
            results[split] = _split_results(split, cases, skipped, methods, mine, limits[split])
    results["wall_s"] = round(time.perf_counter() - started, 1)
    if "dev" in results and "test" in results:
        results["gap"] = gaps(results["dev"], results["test"])
    print()
    print(markdown_table(results))
    print(json.dumps(results))
    return 0


def s_get(split: dict[str, Any], method: str) -> float | None:
    """A method's median time to find in one split's results."""
    value = split.get(method, {}).get("time_to_find_s_median")
    return float(value) if value else None


@contextlib.contextmanager
def _kept(folder: str) -> Iterator[str]:
    """A directory kept after the benchmark (for the runs' tick logs), made empty first."""
    path = Path(folder)
    if path.exists():
        shutil.rmtree(path)
    path.mkdir(parents=True)
    yield str(path)


def _size(text: str) -> tuple[float, float] | None:
    """'30x20' -> (30.0, 20.0); '' -> None (the generator draws the size)."""
    if not text:
        return None
    w, h = text.lower().split("x")
    return float(w), float(h)


def run_split(
    split: str,
    cases: list[tuple[Case, Path]],
    methods: list[str],
    workers: int,
    folder: Path,
    max_duration: float,
    load_world: Any,
) -> list[Trial]:
    """Run ``methods`` on one split's cases in chunks (alternating which goes first); the trials."""
    from missiontree.evaluation import PoolEngine, SerialEngine

    trials: list[Trial] = []
    by_path = {str(path): case for case, path in cases}
    worlds = {case.index: load_world(path) for case, path in cases}
    lock = threading.Lock()

    def report(method: str, record: Any) -> None:  # printed as they come
        case = by_path[str(record.world)]
        t = score(
            Trial(method, case.index, case.seed, case.target, case.absent, split),
            case,
            worlds[case.index],
            record,
        )
        with lock:
            trials.append(t)
            print(
                f"{split:4s} {t.method:6s} case {t.case:3d} {case.world[:22]:22s} "
                f"{'absent ' if t.absent else ''}{t.target:16s} "
                f"{t.status:8s} {t.stopped_by:8s} {t.sim_s:6.1f} s  d={t.distance_m:5.2f} m  "
                f"bearing={t.bearing_deg:5.1f}  found={t.found!s:5s} false={t.false_found!s:5s}  "
                f"{t.reason[:90]}",
                flush=True,
            )
            if t.why is not None or t.phases:
                print(f"{split:4s} {t.method:6s} case {t.case:3d} why: {json.dumps(t.why)} "
                      f"phases: {json.dumps(t.phases)}", flush=True)

    size = 2 * max(1, workers)
    engines = {m: PoolEngine(workers) if workers > 1 else SerialEngine() for m in methods}
    try:
        for engine in engines.values():
            engine.__enter__()
        for k, at in enumerate(range(0, len(cases), size)):
            chunk = cases[at : at + size]
            for m in methods if k % 2 == 0 else list(reversed(methods)):
                run_chunk(m, chunk, engines[m], folder, max_duration, report)
    finally:
        for engine in engines.values():
            engine.__exit__(None, None, None)
    return trials


if __name__ == "__main__":
    sys.exit(main())
