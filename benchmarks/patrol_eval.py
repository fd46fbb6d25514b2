"""The patrol-robot thesis's scenarios, measured: the thesis's surveillance (0.5 s and 0.2 s) against ours.

Scenarios (the thesis §4.5): A = corridor, B = entrance hall, C/D = the combined route. People cross
the robot's path: walkers pace back and forth across every leg of the route at 1.0-1.6 m/s, so they
cross the camera's view at bearings across its 70° field of view. The VLM answers after a latency
drawn from 0.5-3 s (simulated clock). Configurations, all on the same worlds, seeds and routes:

- ``seed_05`` — the thesis as built: the latest frame to the VLM every 0.5 s (scenarios A-C), the
  distance read by its ±15° front cone from the *latest* scan once the answer arrives.
- ``seed_02`` — the same every 0.2 s (scenario D).
- ``ours`` — the detector on every frame, the VLM confirming at most every 0.5 s (≤ 2 calls/s),
  the distance from the depth inside the person's box, fused at the frame's instant.

Each run is the real mission (loader, builder, runner, leaves) on the simulator: a Parallel of
Patrol (one lap) and Surveillance, without servoing so that every configuration drives the same
path. The runs go through the batch runner (missiontree.evaluation) on a process pool of ``--jobs``
workers; a probe scores each run inside its worker. Scoring uses the simulator's ground truth
(never seen by the leaves):

- an *encounter* is a run of frames in which a person shows (gaps up to 1 s bridged), with at least
  two frames showing them with MIN_PIXELS or more while they stand at least OVERLAP from the robot
  (a walker passing through the robot's body, which real people cannot, is not a crossing anyone
  can be asked to see; such encounters are counted apart, ``through_robot``, in the JSON and the
  per-run lines, as overlapping alarms are); it is *detected* when an alarm's frame lies inside
  it and shows that person (encounters that begin in a run's last 3 s, the longest answer latency,
  are not scored: no configuration could answer them before the patrol ends);
- the distance error of an alarm is |reported − true| against the true distance, at the frame's
  time, from the robot to the person in that frame whose distance matches best (favourable to
  every method alike); an alarm without a distance (the thesis's ``inf``) counts as an error > 1 m.
  Simulated walkers ignore the robot and may walk through its body; alarms on frames where a person
  is closer than OVERLAP (bodies overlapping, impossible for real people) are not scored for
  distance and are counted apart (``overlapping``).

``--detector oracle`` runs every configuration on the simulation oracle (a perfect detector) instead
of the shipped trained detector, to separate what the detector costs from what the design costs.
The runs are listed alternating between configurations scenario by scenario (every score is on the
simulated clock, so the order the pool finishes them in changes none of them); ratios of ours
against the thesis's are printed with min/median/max over scenarios. Last line: one JSON object
with the figures.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import random
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from missiontree.backends.sim import load_world
from missiontree.behaviours.waypoints import load_waypoints
from missiontree.evaluation import BatchPlan, PoolEngine, RunSpec, run_batch
from missiontree.paths import find_config
from missiontree.plugins.manager import load_plugins
from missiontree.session.models import BrokenProvider, build_models

#: (scenario, world, route file, laps) — C and D share the combined route; D is seed_02's scenario.
SCENARIOS = [("A", "corridor", "scenario_a", 5), ("B", "entrance_hall", "scenario_b", 3),
             ("C/D", "combined", "scenario_c", 1)]

CONFIGS: dict[str, dict[str, Any]] = {
    "seed_05": {"mode": "poll", "period": 0.5, "method": "seed", "fuse_at": "answer", "max_in_flight": 99},
    "seed_02": {"mode": "poll", "period": 0.2, "method": "seed", "fuse_at": "answer", "max_in_flight": 99},
    "ours": {"mode": "detect", "period": 0.5, "method": "depth", "fuse_at": "frame", "max_in_flight": 6},
}

LATENCY = (0.5, 3.0)          # seconds, the thesis's cloud VLM
SPEEDS = (1.0, 1.6)           # m/s, people crossing
MIN_PIXELS = 400              # a person this visible in a frame can be asked to be seen
MERGE_GAP = 1.0               # seconds out of view that still belong to the same encounter
OVERLAP = 0.36                # m: robot body (0.17) + torso (0.19); simulated walkers pass through it
WALKER_SPACING = 3.0          # metres of route between crossing walkers
BEARING_BINS = [-35, -25, -15, -5, 5, 15, 25, 35]
SEEDS = (7, 13)               # each scenario runs with walkers and simulator seeded by each


@dataclass
class RunScore:
    """What one run of one configuration on one scenario measured."""

    scenario: str
    config: str
    seed: int = 0
    sim_seconds: float = 0.0
    wall_seconds: float = 0.0
    encounters: int = 0
    detected: int = 0
    calls: int = 0
    errors: list[float] = field(default_factory=list)
    bearings: list[float] = field(default_factory=list)
    no_distance: int = 0
    overlapping: int = 0
    through_robot: int = 0
    reached: int = 0
    skipped: int = 0

    @property
    def detection_rate(self) -> float:
        """Share of encounters with an alarm."""
        return self.detected / self.encounters if self.encounters else float("nan")

    @property
    def calls_per_s(self) -> float:
        """VLM calls per simulated second."""
        return self.calls / self.sim_seconds if self.sim_seconds else float("nan")


# -- worlds with crossing people ---------------------------------------------------------------------


def crossing_world(world_name: str, route_name: str, out_dir: Path, rng: random.Random) -> Path:
    """The scenario's world with its people replaced by walkers pacing across every leg of the route."""
    source = find_config("worlds", world_name)
    data = yaml.safe_load(source.read_text())
    data["people"] = []
    empty = out_dir / f"{world_name}_empty.yaml"
    empty.write_text(yaml.safe_dump(data, sort_keys=False))
    world = load_world(empty)
    route = load_waypoints(route_name)
    legs = {(a.pose.x, a.pose.y, b.pose.x, b.pose.y)
            for a, b in zip(route, route[1:] + route[:1], strict=True) if a.name != b.name}
    people = []
    for x1, y1, x2, y2 in sorted(legs):
        if (x2, y2, x1, y1) in legs and (x2, y2) < (x1, y1):
            continue  # out and back along the same leg: one set of walkers
        length = math.hypot(x2 - x1, y2 - y1)
        nx, ny = -(y2 - y1) / max(length, 1e-9), (x2 - x1) / max(length, 1e-9)
        for k in range(max(1, int(length // WALKER_SPACING))):
            f = (k + 0.5) / max(1, int(length // WALKER_SPACING))
            cx, cy = x1 + f * (x2 - x1), y1 + f * (y2 - y1)
            ends = [_free_end(world, cx, cy, s * nx, s * ny) for s in (1.0, -1.0)]
            if math.dist(ends[0], ends[1]) < 1.0:
                continue
            people.append({
                "id": f"walker{len(people) + 1}", "route": [list(ends[0]), list(ends[1])],
                "speed": round(rng.uniform(*SPEEDS), 2), "start_time": round(rng.uniform(0.0, 15.0), 1),
                "loop": True, "pause": round(rng.uniform(1.0, 6.0), 1),
                "shirt_rgb": [rng.randrange(30, 226) for _ in range(3)],   # people dress differently
                "trousers_rgb": [rng.randrange(20, 120) for _ in range(3)],
            })
    data["people"] = people
    path = out_dir / f"{world_name}_crossing.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def _free_end(world: Any, cx: float, cy: float, dx: float, dy: float) -> tuple[float, float]:
    """The farthest point up to 2.5 m from (cx, cy) along (dx, dy) with 0.35 m to any wall."""
    best = (round(cx, 2), round(cy, 2))
    for step in np.arange(0.1, 2.55, 0.1):
        x, y = cx + step * dx, cy + step * dy
        if world.clearance(x, y) < 0.35:
            break
        best = (round(float(x), 2), round(float(y), 2))
    return best


# -- one run -----------------------------------------------------------------------------------------


#: The benchmark mission: one lap of the route with surveillance, no servoing. The route, the laps
#: and the surveillance configuration are its ``params`` (set per run by the batch).
MISSION = """version: 1
description: patrol_eval run
params:
  route: scenario_a
  laps: 1
  mode: detect
  period: 0.5
  method: depth
  fuse_at: frame
  max_in_flight: 6
root:
  Parallel:
    name: patrol_and_watch
    policy: success_on_one
    children:
      - Patrol:
          name: patrol
          waypoints_file: ${route}
          laps: ${laps}
          yaw_tolerance: 6.28
          waypoint_timeout: 90
      - Surveillance:
          name: surveillance
          alarm_cooldown: 0
          mode: ${mode}
          period: ${period}
          method: ${method}
          fuse_at: ${fuse_at}
          max_in_flight: ${max_in_flight}
"""


def models_config(detector: str) -> dict[str, Any]:
    """A shipped models config (``offline``: the trained detector; ``oracle``) with the VLM latency pinned."""
    data = yaml.safe_load(find_config("models", detector).read_text(encoding="utf-8"))
    data["roles"]["vlm"].update(latency={"uniform": list(LATENCY)}, timeout=10.0)
    return data


def choose_models(oracle: bool) -> tuple[dict[str, Any], str]:
    """The models every run uses: the shipped trained detector, or the oracle when asked or unusable."""
    if oracle:
        return models_config("oracle"), "oracle (trained detector not used: --detector oracle)"
    models = build_models(models_config("offline"), providers=load_plugins(autoload=False).providers, seed=0)
    detector = models.get("detector")
    if not isinstance(detector, BrokenProvider):
        return models_config("offline"), "sim_detector (trained)"
    return models_config("oracle"), f"oracle (trained detector not used: {detector.reason})"


class PatrolProbe:
    """Scores one run inside its batch worker: the true pose at every camera frame, then the events.

    The leaves never see the truth; the probe reads it between ticks and, at the end, scores the
    run's tick log (its ``ticks.jsonl``) against it.
    """

    def __init__(self) -> None:
        self.poses: dict[float, Any] = {}

    def on_tick(self, session: Any) -> None:
        """The true pose of the latest frame (scoring only)."""
        frame = session.robot.rgbd()
        if frame is not None and frame.stamp not in self.poses:
            self.poses[frame.stamp] = session.robot.truth.robot_pose_at(frame.stamp)

    def finish(self, session: Any, result: Any) -> dict[str, Any]:
        """RunScore's figures (an infinite error, an alarm without a distance, as null)."""
        log = (session.run_dir / "ticks.jsonl").read_text(encoding="utf-8")
        events = [json.loads(line) for line in log.splitlines() if line.strip()]
        score = RunScore("", "", sim_seconds=session.robot.now())
        score_events(score, events, session.robot.truth, self.poses)
        figures = dataclasses.asdict(score)
        figures["errors"] = [None if math.isinf(e) else e for e in score.errors]
        for key in ("scenario", "config", "seed", "wall_seconds"):
            figures.pop(key)
        return figures


def run_all(runs: list[tuple[str, Path, str, int, str, int]], models: dict[str, Any], jobs: int,
            out: Path) -> list[RunScore]:
    """Every (scenario, world file, route, laps, configuration, seed) on the batch runner, scored."""
    mission = out / "patrol_eval.yaml"
    mission.write_text(MISSION, encoding="utf-8")
    specs = [RunSpec(world=str(world), seed=seed, run_seed=seed,
                     params=(("route", route), ("laps", str(laps)),
                             *((k, str(v)) for k, v in CONFIGS[name].items())))
             for _, world, route, laps, name, seed in runs]
    request = {"backend": "sim", "models": models, "tick_hz": 10, "max_duration": 900, "allow_outside": True}
    plan = BatchPlan(mission=mission, runs=specs, request=request)
    fields = {f.name for f in dataclasses.fields(RunScore)} - {"scenario", "config", "seed", "wall_seconds"}
    scores = []
    with PoolEngine(jobs) as engine:
        records = run_batch(plan, engine, out / "batch", probe=PatrolProbe)
    for (scenario, _, _, _, name, seed), record in zip(runs, records, strict=True):
        if record.status in ("ERROR", "INFRA"):
            raise SystemExit(f"{scenario}/{name} seed {seed}: the run did not complete ({record.status}: "
                             f"{record.reason})")
        if record.status != "SUCCESS":
            print(f"  note: {scenario}/{name} ended {record.status} ({record.stopped_by})", file=sys.stderr)
        figures = {k: v for k, v in record.figures.items() if k in fields}
        figures["errors"] = [math.inf if e is None else e for e in figures.get("errors", [])]
        scores.append(RunScore(scenario, name, seed, wall_seconds=record.wall_time_s, **figures))
    return scores


def score_events(score: RunScore, events: list[dict[str, Any]], truth: Any, poses: dict[float, Any]) -> None:
    """Fill ``score`` from the run's tick-log events and the simulator's ground truth."""
    alarms = [e for e in events if e["event"] == "alarm"]
    score.calls = sum(1 for e in events if e["event"] == "model_call" and e.get("role") == "vlm")
    score.reached = sum(1 for e in events if e["event"] == "waypoint_reached")
    score.skipped = sum(1 for e in events if e["event"] == "waypoint_skipped")
    end = truth.visibility[-1][0] if truth.visibility else 0.0

    def through_robot(name: str, stamp: float) -> bool:
        pose = poses.get(stamp)
        return pose is not None and any(pid == name and math.hypot(x - pose.x, y - pose.y) < OVERLAP
                                        for pid, x, y in truth.people_at(stamp))

    spans = [span for span in encounters(truth.visibility, through_robot) if span[1] < end - LATENCY[1]]
    score.through_robot = len([span for span in encounters(truth.visibility) if span[1] < end - LATENCY[1]]) \
        - len(spans)
    shown = [(a["stamp"], set(truth.visible_at(a["stamp"]))) for a in alarms]
    score.encounters = len(spans)
    score.detected = sum(1 for name, t0, t1 in spans
                         if any(t0 - 1e-6 <= stamp <= t1 + 1e-6 and name in seen for stamp, seen in shown))
    for alarm in alarms:
        stamp = alarm["stamp"]
        pose = poses.get(stamp)
        seen = truth.visible_at(stamp)
        people = {pid: (x, y) for pid, x, y in truth.people_at(stamp) if pid in seen}
        if pose is None or not people:
            continue
        truths = {pid: (math.hypot(x - pose.x, y - pose.y), pose.bearing_to(x, y))
                  for pid, (x, y) in people.items()}
        if min(d for d, _ in truths.values()) < OVERLAP:
            score.overlapping += 1  # a walker passing through the robot's body: no real person can
            continue
        reported = alarm.get("distance")
        if reported is None:
            score.no_distance += 1
            score.errors.append(math.inf)
            score.bearings.append(min(truths.values())[1])
            continue
        best = min(truths.values(), key=lambda tb: abs(tb[0] - reported))
        score.errors.append(abs(best[0] - reported))
        score.bearings.append(best[1])


def encounters(
    visibility: list[tuple[float, dict[str, Any]]],
    through_robot: Callable[[str, float], bool] | None = None,
) -> list[tuple[str, float, float]]:
    """(person, first frame, last frame) of every encounter.

    An encounter is a run of frames in which a person shows at all, gaps up to MERGE_GAP seconds
    bridged (a leg hidden for a frame is the same crossing); it counts when at least two of its
    frames show the person with MIN_PIXELS or more (someone a guard could be asked to notice) and,
    when ``through_robot(person, stamp)`` is given, not inside the robot's body at that frame.
    """
    spans: list[tuple[str, float, float]] = []
    current: dict[str, list[Any]] = {}  # name -> [first, last, frames with MIN_PIXELS]

    def close(name: str) -> None:
        first, last, big = current.pop(name)
        if big >= 2:
            spans.append((name, first, last))

    for stamp, seen in visibility:
        for name in [n for n, (_, last, _) in current.items() if stamp - last > MERGE_GAP]:
            close(name)
        for name, sighting in seen.items():
            if sighting.kind != "person":
                continue
            entry = current.setdefault(name, [stamp, stamp, 0])
            entry[1] = stamp
            entry[2] += sighting.pixels >= MIN_PIXELS and not (through_robot and through_robot(name, stamp))
    for name in list(current):
        close(name)
    return spans


# -- report ------------------------------------------------------------------------------------------


def stats(errors: list[float]) -> tuple[float, float, int]:
    """Median and p95 of the finite errors (inf when any error is infinite at that rank), and count > 1 m."""
    if not errors:
        return float("nan"), float("nan"), 0
    values = np.sort(np.array(errors))
    median = float(values[int(0.5 * (len(values) - 1))]) if len(values) else float("nan")
    p95 = float(values[int(math.ceil(0.95 * (len(values) - 1)))])
    return median, p95, int(np.sum(values > 1.0))


def fmt(value: float) -> str:
    return "inf" if math.isinf(value) else ("nan" if math.isnan(value) else f"{value:.3f}")


def json_number(value: float) -> float | None:
    return None if not math.isfinite(value) else round(value, 4)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--detector", choices=("shipped", "oracle"), default="shipped",
                        help="the shipped trained detector, or the simulation oracle (a perfect detector)")
    parser.add_argument("--jobs", type=int, default=os.cpu_count() or 1,
                        help="runs in parallel (batch runner's process pool; default: the cores)")
    parser.add_argument("--quick", action="store_true", help=f"seed {SEEDS[0]} only (a smoke run)")
    args = parser.parse_args()
    seeds = SEEDS[:1] if args.quick else SEEDS
    started = time.perf_counter()
    models, note = choose_models(args.detector == "oracle")
    with tempfile.TemporaryDirectory(prefix="patrol_eval_") as tmp_name:
        tmp = Path(tmp_name)
        runs = []
        for i, (seed, scenario, world, route, laps) in enumerate(
                (seed, *scenario) for seed in seeds for scenario in SCENARIOS):
            world_path = crossing_world(world, route, tmp, random.Random(f"{seed}:{scenario}"))
            order = list(CONFIGS) if i % 2 == 0 else list(reversed(CONFIGS))  # alternate the order
            runs.extend((scenario, world_path, route, laps, name, seed) for name in order)
        scores = run_all(runs, models, max(1, args.jobs), tmp)
        for score in scores:
            seed, scenario, name = score.seed, score.scenario, score.config
            median, p95, over = stats(score.errors)
            label = {"seed_05": "C", "seed_02": "D"}.get(name, "C/D") if scenario == "C/D" else scenario
            print(f"seed {seed:2} scenario {label:4} {name:8} encounters {score.encounters:3} detected "
                  f"{score.detection_rate:.3f}  calls/s {score.calls_per_s:.2f}  error median "
                  f"{fmt(median)} p95 {fmt(p95)} >1m {over:3} (alarms {len(score.errors)}, no distance "
                  f"{score.no_distance}, overlapping {score.overlapping}, through robot "
                  f"{score.through_robot})  waypoints reached {score.reached} skipped {score.skipped}  "
                  f"[{score.sim_seconds:.0f} s simulated, {score.wall_seconds:.1f} s wall]", flush=True)
    print(f"detector: {note}")
    summary: dict[str, Any] = {}
    for name in CONFIGS:
        runs = [s for s in scores if s.config == name]
        errors = [e for s in runs for e in s.errors]
        bearings = [b for s in runs for b in s.bearings]
        median, p95, over = stats(errors)
        encounters_n = sum(s.encounters for s in runs)
        rate = sum(s.detected for s in runs) / encounters_n if encounters_n else float("nan")
        calls = sum(s.calls for s in runs) / sum(s.sim_seconds for s in runs)
        per_bin = {}
        for lo, hi in zip(BEARING_BINS, BEARING_BINS[1:], strict=False):
            chosen = [e for e, b in zip(errors, bearings, strict=True) if lo <= math.degrees(b) < hi]
            m, p, o = stats(chosen)
            per_bin[f"{lo}..{hi}"] = {"n": len(chosen), "median_m": json_number(m), "p95_m": json_number(p),
                                      "over_1m": o}
        summary[name] = {
            "detection_rate": round(rate, 4), "model_calls_per_s": round(calls, 3),
            "distance_error_median_m": json_number(median), "distance_error_p95_m": json_number(p95),
            "errors_over_1m": over, "alarms": len(errors), "no_distance": sum(s.no_distance for s in runs),
            "overlapping_not_scored": sum(s.overlapping for s in runs),
            "through_robot_not_scored": sum(s.through_robot for s in runs),
            "encounters": encounters_n, "waypoints_reached": sum(s.reached for s in runs),
            "waypoints_skipped": sum(s.skipped for s in runs), "by_bearing_deg": per_bin,
        }
        print(f"{name:8} detection {rate:.3f}  calls/s {calls:.2f}  error median {fmt(median)} p95 {fmt(p95)}"
              f"  >1m {over}  waypoints reached {summary[name]['waypoints_reached']} skipped "
              f"{summary[name]['waypoints_skipped']}")
        print("         by bearing (deg): " + "  ".join(
            f"{k}: n={v['n']} med={v['median_m']} p95={v['p95_m']}" for k, v in per_bin.items()))
    for reference in ("seed_05", "seed_02"):
        ratios_err, ratios_det = [], []
        for seed, (scenario, *_) in ((seed, sc) for seed in seeds for sc in SCENARIOS):
            ours = next(s for s in scores if (s.seed, s.scenario, s.config) == (seed, scenario, "ours"))
            ref = next(s for s in scores if (s.seed, s.scenario, s.config) == (seed, scenario, reference))
            m_ours, m_ref = stats(ours.errors)[0], stats(ref.errors)[0]
            if m_ours > 0 and math.isfinite(m_ref):
                ratios_err.append(m_ref / m_ours)
            if ref.detection_rate > 0:
                ratios_det.append(ours.detection_rate / ref.detection_rate)
        for label, ratios in (("median error, reference/ours", ratios_err),
                              ("detection, ours/reference", ratios_det)):
            if ratios:
                print(f"ratio {label} vs {reference}: min {min(ratios):.2f} "
                      f"median {float(np.median(ratios)):.2f} max {max(ratios):.2f} "
                      f"over {len(ratios)} scenario runs")
    summary["detector"] = note
    summary["wall_seconds"] = round(time.perf_counter() - started, 1)
    print(json.dumps(summary, sort_keys=True))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
