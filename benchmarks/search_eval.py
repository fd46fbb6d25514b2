"""Object search: ours (trees/find_object.yaml) against the vision-language object-search report's method.

    python benchmarks/search_eval.py               # 50 worlds with the target + 10 without
    python benchmarks/search_eval.py --quick       # 6 + 2 (tractable on a loaded 2-core machine)
    python benchmarks/search_eval.py --workers 2   # two missions at once (one of each method)

Worlds. Apartments from :mod:`missiontree.backends.sim.generator` (4 rooms, no people), edited here
for the search (benchmark-side world editing, the generator is untouched): a target (class and
colour, e.g. "red backpack") is chosen per world among the small objects; decoys of both kinds are
made sure of — an object of the same class in another colour and one of the same colour in another
class (the generated furnishings already hold some; missing ones are made by recolouring another
small object); any second object matching the target is recoloured, so exactly one is right. In the
``absent`` cases the target itself is recoloured into one more decoy: nothing matches.

Methods, each through the batch runner (:func:`missiontree.evaluation.run_batch`, a probe reading the
true final pose in the worker) with its mission's own ``run:`` section (map mode included), the worlds
in chunks run by one method then the other, alternating which goes first:

- ``ours``: ``trees/find_object.yaml`` on an unknown map (the robot starts knowing nothing): semantic
  map from every frame, known candidates first, exploration weighted by room priors, standoff
  approach from depth, VLM check on the detection.
- ``report``: ``trees/examples/report_search.yaml`` on the known map (the report localises with AMCL
  on a map SLAM built beforehand, so its scan points cover the whole place from the start): scan
  points with 360-degree scans, colour trigger, box-area approach steps, whole-frame VLM check,
  rounds without memory. The known map is a head start for the reference, not for ours.

Scoring reads the simulator's ground truth after the run (never the leaves): a run *finds* the
target when it ends SUCCESS with the robot within ``REACH`` m of the target's footprint and facing
it (bearing error under ``FACING_DEG``). A *false found* is a SUCCESS anywhere else (or any SUCCESS
in an absent case); ``false_found_wrong_object`` counts those where the target was not even in view
(farther than ``VIEW_RANGE`` or outside the camera's half field of view): another object was taken
for it. The time comparison is also given paired: ours / report on the cases both found.
An absent case is *correct* when the run ends FAILURE by the tree's own verdict
(not the time limit). Time to find is robot-clock seconds of the successful runs. Last line: JSON.
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import sys
import tempfile
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

REPO = Path(__file__).resolve().parents[1]
MISSIONS = {
    "ours": REPO / "trees" / "find_object.yaml",
    "report": REPO / "trees" / "examples" / "report_search.yaml",
}
#: Targets drawn from the generator's small objects: (class, colour).
TARGETS = [
    ("backpack", "red"),
    ("backpack", "blue"),
    ("bottle", "green"),
    ("backpack", "green"),
    ("umbrella", "red"),
    ("bottle", "blue"),
]
#: Colours a decoy may be painted in.
PALETTE = ["red", "blue", "green", "grey", "white", "pink", "black", "yellow"]
REACH = 1.0
FACING_DEG = 30.0
#: A "found" with the target farther than this or outside the half field of view is of another object.
VIEW_RANGE, HALF_FOV_DEG = 3.0, 35.0


@dataclass
class Case:
    """One world and what is searched in it."""

    index: int
    seed: int
    label: str
    colour: str
    absent: bool
    target_id: str = ""

    @property
    def target(self) -> str:
        """The phrase searched for ("red backpack")."""
        return f"{self.colour} {self.label}"


@dataclass
class Trial:
    """One method on one case, scored against the truth."""

    method: str
    case: int
    seed: int
    target: str
    absent: bool
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


def make_case(index: int, seed: int, absent: bool, folder: Path) -> tuple[Case, Path]:
    """Generate, edit and write the world of one case; return the case and the world file."""
    from missiontree.backends.sim.generator import generate_world

    data = generate_world(seed, rooms=4, people=0)
    objects = data["objects"]
    small = [o for o in objects if "description" in o]
    rng = np.random.default_rng(seed + 7919)
    options = [t for t in TARGETS if any(o["label"] == t[0] for o in small)]
    label, colour = options[int(rng.integers(len(options)))]
    same_class = [o for o in small if o["label"] == label]
    target = next((o for o in same_class if o["color"] == colour), same_class[0])
    target["color"] = colour
    for o in same_class:  # exactly one right object
        if o is not target and o["color"] == colour:
            o["color"] = next(c for c in PALETTE if c != colour)
    others = [o for o in small if o["label"] != label]
    if len(same_class) < 2 and others:  # a same-class decoy: another small object becomes one
        decoy = others.pop(int(rng.integers(len(others))))
        decoy.update(
            label=label,
            color=next(c for c in PALETTE if c != colour),
            size=list(target["size"]),
            shape=target.get("shape", "box"),
        )
    if not any(o["color"] == colour for o in others) and others:  # a same-colour decoy of another class
        others[int(rng.integers(len(others)))]["color"] = colour
    if absent:
        target["color"] = next(
            c
            for c in PALETTE
            if c != colour and not any(o["color"] == c and o["label"] == label for o in same_class)
        )
    for o in small:
        o["description"] = f"a {o['color']} {o['label']}"
    case = Case(index, seed, label, colour, absent, target_id=target["id"])
    path = folder / f"world_{index:03d}.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return case, path


class SearchProbe:
    """Reads, inside the batch worker, what scoring needs: the true final pose and the search's verdict.

    The true pose is the simulator's ground truth (scoring only; the leaves never see it).
    """

    def on_tick(self, session: Any) -> None:
        """Nothing per tick."""

    def finish(self, session: Any, result: Any) -> dict[str, Any]:
        """The robot's true final pose and the search's last found / not-found message."""
        pose = session.robot.truth.robot_pose()
        log = (session.run_dir / "ticks.jsonl").read_text(encoding="utf-8")
        return {"final_pose": [pose.x, pose.y, pose.yaw], "search_reason": _reason(log)}


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
    trial.absent_correct = case.absent and not claimed and trial.stopped_by == "status"
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
        RunSpec(world=str(path), seed=case.seed, run_seed=case.seed, params=(("target", case.target),))
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
    """Rates and medians of one method's trials."""
    mine = [t for t in trials if t.method == method]
    present = [t for t in mine if not t.absent]
    absent = [t for t in mine if t.absent]
    found = [t for t in present if t.found]
    times = sorted(t.sim_s for t in found)
    claimed = [t for t in present if t.status == "SUCCESS"]

    def med(values: list[float]) -> float | None:
        return round(statistics.median(values), 3) if values else None

    return {
        "runs": len(mine),
        "success_rate": round(len(found) / len(present), 4) if present else None,
        "false_found": sum(t.false_found for t in mine),
        "false_found_wrong_object": sum(t.wrong_object for t in mine),
        "absent_correct_rate": round(sum(t.absent_correct for t in absent) / len(absent), 4)
        if absent
        else None,
        "time_to_find_s_median": med(times),
        "time_to_find_s_p90": round(float(np.percentile(times, 90)), 3) if times else None,
        "path_length_m_median": med([t.path_m for t in found]),
        "final_distance_error_m_median": med([t.distance_m for t in claimed]),
        "final_bearing_error_deg_median": med([t.bearing_deg for t in claimed]),
        "timeouts": sum(t.stopped_by != "status" for t in mine),
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


def main(argv: list[str] | None = None) -> int:
    from missiontree.backends.sim import load_world
    from missiontree.evaluation import PoolEngine, SerialEngine

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="6 worlds with the target + 2 without")
    parser.add_argument("--worlds", type=int, default=None, help="worlds with the target (default 50)")
    parser.add_argument("--absent", type=int, default=None, help="worlds without it (default 10)")
    parser.add_argument("--max-duration", type=float, default=None, help="robot seconds per mission")
    parser.add_argument("--workers", type=int, default=1, help="missions run at once")
    parser.add_argument("--first-seed", type=int, default=100)
    args = parser.parse_args(argv)
    n_present = args.worlds if args.worlds is not None else (6 if args.quick else 50)
    n_absent = args.absent if args.absent is not None else (2 if args.quick else 10)
    max_duration = args.max_duration or 600.0
    trials: list[Trial] = []
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        n = n_present + n_absent
        cases = [make_case(i, args.first_seed + i, i >= n_present, folder) for i in range(n)]
        by_path = {str(path): case for case, path in cases}
        worlds = {case.index: load_world(path) for case, path in cases}
        lock = threading.Lock()

        def report(method: str, record: Any) -> None:  # printed as they come
            case = by_path[str(record.world)]
            t = score(Trial(method, case.index, case.seed, case.target, case.absent), case,
                      worlds[case.index], record)
            with lock:
                trials.append(t)
                print(
                    f"{t.method:6s} case {t.case:3d} {'absent ' if t.absent else ''}{t.target:16s} "
                    f"{t.status:8s} {t.stopped_by:8s} {t.sim_s:6.1f} s  d={t.distance_m:5.2f} m  "
                    f"bearing={t.bearing_deg:5.1f}  found={t.found!s:5s} false={t.false_found!s:5s}  "
                    f"{t.reason[:90]}",
                    flush=True,
                )

        started = time.perf_counter()
        # the worlds in chunks, each run by one method then the other (which goes first alternates),
        # every chunk on the batch runner with all the workers
        size = 2 * max(1, args.workers)
        engines = {m: PoolEngine(args.workers) if args.workers > 1 else SerialEngine() for m in MISSIONS}
        with engines["ours"], engines["report"]:
            for k, at in enumerate(range(0, n, size)):
                chunk = cases[at : at + size]
                for m in ("ours", "report") if k % 2 == 0 else ("report", "ours"):
                    run_chunk(m, chunk, engines[m], folder, max_duration, report)
        wall = time.perf_counter() - started
    out: dict[str, Any] = {
        "worlds": n_present,
        "absent_cases": n_absent,
        "max_duration_s": max_duration,
        "wall_s": round(wall, 1),
    }
    for method in ("ours", "report"):
        out[method] = summarise(trials, method)
        s = out[method]
        print(
            f"{method}: success {s['success_rate']}, false found {s['false_found']}, absent correct "
            f"{s['absent_correct_rate']}, time to find median {s['time_to_find_s_median']} s "
            f"(p90 {s['time_to_find_s_p90']}), path {s['path_length_m_median']} m, final distance "
            f"{s['final_distance_error_m_median']} m, bearing {s['final_bearing_error_deg_median']} deg"
        )
    ours, report = out["ours"]["time_to_find_s_median"], out["report"]["time_to_find_s_median"]
    out["time_ratio_ours_vs_report"] = round(ours / report, 3) if ours and report else None
    out["time_ratio_paired"] = paired_ratios(trials)
    print(f"time to find, ours / report on the cases both found: {out['time_ratio_paired']}")
    absent_ok = out["ours"]["absent_correct_rate"]
    out["absent_correct_rate"] = absent_ok
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
