"""Whole missions' speed: real-time factor, CPU per robot-second, memory and where the time goes.

Each shipped mission (patrol, explore, map_scene, go_to_intent, find_object, map_and_go_to_intent)
runs on its default world and on a generated 30 x 50 m floor (``generated`` apartments' layout at
that size), for ``--seeds`` seeds, each run a process of its own (``missiontree run``), so its
start-up and its peak memory are its own. Every run's ``summary.json`` carries its profile
(:mod:`missiontree.engine.profile`); from it the benchmark prints, per mission and world:

- the real-time factor (robot seconds per wall second) min / median / max, and the same in CPU
  terms (robot seconds per CPU second of the run: what the mission would reach on an idle core);
- CPU seconds per robot second (the run's, and the whole process's with start-up);
- the peak RSS;
- the top cost centres of the median run (nodes, model roles, the simulator's stepping, the engine).

The reference, in the same invocation and alternating with the missions: **the simulator alone** on
the same world, map mode and seed, for as long as the mission's run: the robot stepped at the
mission's 10 Hz with its lidar scan and RGB-D frame read every tick (what the missions' leaves
read), nothing else; the robot stands (its sensors render as much as when it drives). Timed in
this process's CPU, after the robot was made. ``overhead_vs_sim`` is the mission's CPU per
robot-second over the simulator's alone (1.0: the mission costs nothing on top of its world).

Each run is capped at ``--max-duration`` robot seconds (a search that would explore the whole
floor is measured over its first stretch); the table says how each run ended. ``--quick`` is the
CI size: one seed, the default worlds, 60 robot seconds.

The 30 x 50 m floor's patrol route is made from the robot's own map (room spots, nearest first, as
the patrol benchmark's test split makes its routes). ``go_to_intent`` there uses the scene graph the
``map_scene`` run of the same seed wrote; without one it is left out (said so).

Last line: one JSON object with ``rtf_median.<mission>.<world>``, ``cpu_rtf_median.<mission>.<world>``,
``rss_peak_mb.<mission>.<world>``, ``overhead_vs_sim_median`` (per mission and world) and the runs.

    python benchmarks/mission_speed.py --quick
    python benchmarks/mission_speed.py --seeds 3 --max-duration 300
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))
sys.path.insert(0, str(ROOT / "benchmarks"))

from missiontree.engine.profile import cost_centres  # noqa: E402

#: The shipped missions and their default worlds (their ``run:`` sections'), in the issue's order.
MISSIONS = ("patrol", "explore", "map_scene", "go_to_intent", "find_object", "map_and_go_to_intent")

#: The large floor: width x height in metres, rooms, the generator's seed.
LARGE_SIZE = (50.0, 30.0)
LARGE_ROOMS = 24
LARGE_SEED = 30050
LARGE = "floor30x50"

#: What the intent missions are asked (without a command they serve stdin, which is empty here).
COMMAND = "I'm thirsty"

#: The missions' tick period (s): the simulator alone is stepped and read at it.
TICK = 0.1


@dataclass
class Run:
    """One finished run's figures."""

    mission: str
    world: str
    seed: int
    status: str
    stopped_by: str
    robot_s: float
    wall_s: float
    cpu_s: float
    process_cpu_s: float
    rss_peak_mb: float
    sim_cpu_s: float
    centres: list[tuple[str, float, float]] = field(default_factory=list)

    @property
    def rtf(self) -> float:
        """Robot seconds per wall second of the run."""
        return self.robot_s / self.wall_s if self.wall_s > 0 else 0.0

    @property
    def cpu_rtf(self) -> float:
        """Robot seconds per CPU second of the run."""
        return self.robot_s / self.cpu_s if self.cpu_s > 0 else 0.0

    @property
    def cpu_per_robot_s(self) -> float:
        """CPU seconds of the run per robot second."""
        return self.cpu_s / self.robot_s if self.robot_s > 0 else 0.0


def _params(mission: str) -> dict[str, str]:
    """The mission's parameters for the benchmark: a command for the intent missions."""
    return {"command": COMMAND} if mission in ("go_to_intent", "map_and_go_to_intent") else {}


def _default_world(mission: str) -> str:
    data = yaml.safe_load((ROOT / "trees" / f"{mission}.yaml").read_text(encoding="utf-8"))
    return str((data.get("run") or {}).get("world", "office"))


def _unknown_map(mission: str) -> bool:
    data = yaml.safe_load((ROOT / "trees" / f"{mission}.yaml").read_text(encoding="utf-8"))
    return (data.get("run") or {}).get("map") == "unknown"


def large_world(work: Path) -> tuple[Path, Path | None]:
    """The 30 x 50 m floor's world file and a patrol route from the robot's map (None: no route)."""
    from missiontree.backends.sim import create_robot
    from missiontree.backends.sim.generator import write_world_file

    world = write_world_file(LARGE_SEED, work / f"{LARGE}.yaml", size=LARGE_SIZE, rooms=LARGE_ROOMS)
    try:
        from patrol_eval import map_route
    except ImportError:  # the patrol benchmark's route maker is not beside this file
        return world, None
    robot = create_robot({"world": str(world), "seed": 0})
    try:
        grid, pose, profile = robot.occupancy(), robot.pose(), robot.profile
    finally:
        robot.close()
    if grid is None or pose is None:
        return world, None
    route = map_route(grid, (pose.pose.x, pose.pose.y), profile)
    if not route.waypoints:
        return world, None
    route_file = work / f"{LARGE}_route.yaml"
    route_file.write_text(yaml.safe_dump({
        "source": "generated from the robot's map of the 30 x 50 m floor: room spots, nearest first",
        "waypoints": [{"name": f"R{i + 1}", "x": x, "y": y, "yaw": 0.0}
                      for i, (x, y) in enumerate(route.waypoints)]}, sort_keys=False), encoding="utf-8")
    return world, route_file


def run_one(tree: Path, out: Path, *, world: str, seed: int, max_duration: float, unknown: bool,
            params: dict[str, str] | None = None) -> Run | str:
    """Run one mission as its own process; its figures, or why it gave none."""
    cmd = [sys.executable, "-m", "missiontree", "run", str(tree), "--out", str(out), "--world", world,
           "--seed", str(seed), "--max-duration", str(max_duration), "-q"]
    if unknown:
        cmd.append("--unknown-map")
    for key, value in (params or {}).items():
        cmd += ["--set", f"{key}={value}"]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    done = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT, check=False,
                          env={**os.environ, "PYTHONHASHSEED": "0"})
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    process_cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    try:
        summary = json.loads((out / "summary.json").read_text(encoding="utf-8"))
        profile = summary["profile"]
        figures = profile["run"]
    except (OSError, ValueError, KeyError):
        tail = (done.stderr or done.stdout).strip().splitlines()[-1:] or ["no output"]
        return f"exit {done.returncode}: {tail[0][:200]}"
    return Run(mission=str(summary.get("mission", tree.stem)), world=world, seed=seed,
               status=str(summary.get("status")), stopped_by=str(summary.get("stopped_by")),
               robot_s=float(figures["robot_s"]), wall_s=float(figures["wall_s"]),
               cpu_s=float(figures["cpu_s"]), process_cpu_s=process_cpu,
               rss_peak_mb=float(figures["rss_peak_mb"]), sim_cpu_s=float(figures.get("sim_cpu_s", 0.0)),
               centres=cost_centres(profile, top=4))


def sim_alone(world: str, seed: int, seconds: float, unknown: bool) -> Run:
    """The simulator alone for ``seconds`` robot seconds: stepped at TICK, lidar and camera read each tick."""
    from missiontree.backends.sim import create_robot

    robot = create_robot({"world": world, "seed": seed, "unknown_map": unknown})
    try:
        robot.scan()
        robot.rgbd()  # the first frame's one-time costs (kernels loaded) are not the stepping's
        start = robot.now()
        cpu0, wall0 = time.process_time(), time.perf_counter()
        while robot.now() - start < seconds - 1e-9:
            robot.spin_until(robot.now() + TICK)
            robot.scan()
            robot.rgbd()
        cpu, wall = time.process_time() - cpu0, time.perf_counter() - wall0
        robot_s = robot.now() - start
    finally:
        robot.close()
    return Run(mission="sim_alone", world=world, seed=seed, status="", stopped_by="", robot_s=robot_s,
               wall_s=wall, cpu_s=cpu, process_cpu_s=cpu, rss_peak_mb=0.0, sim_cpu_s=cpu)


def _spread(values: list[float]) -> str:
    if not values:
        return "-"
    return f"{min(values):.1f} / {statistics.median(values):.1f} / {max(values):.1f}"


@dataclass
class Case:
    """One mission on one world: its runs and its simulator-alone references."""

    mission: str
    world: str
    label: str
    runs: list[Run] = field(default_factory=list)
    sims: list[Run] = field(default_factory=list)
    skipped: list[str] = field(default_factory=list)


def run_case(case: Case, *, seeds: list[int], work: Path, max_duration: float, unknown: bool,
             params: dict[str, str]) -> None:
    """The mission's seeds, each followed by the simulator alone for as long (alternating)."""
    tree = ROOT / "trees" / f"{case.mission}.yaml"
    for seed in seeds:
        out = work / f"{case.mission}-{case.label}-{seed}"
        found = run_one(tree, out, world=case.world, seed=seed, max_duration=max_duration,
                        unknown=unknown, params=params)
        if isinstance(found, str):
            case.skipped.append(f"seed {seed}: {found}")
            continue
        case.runs.append(found)
        sim = sim_alone(case.world, seed, max(found.robot_s, TICK), unknown)
        case.sims.append(sim)
        print(f"  {case.mission} on {case.label} seed {seed}: {found.status} ({found.stopped_by}) "
              f"{found.robot_s:.0f} robot s, rtf {found.rtf:.1f} (CPU {found.cpu_rtf:.1f}), "
              f"sim alone CPU rtf {sim.cpu_rtf:.1f}", flush=True)


def overhead(case: Case) -> float | None:
    """Median over seeds of the mission's CPU per robot-second over the simulator's alone."""
    ratios = [r.cpu_per_robot_s / s.cpu_per_robot_s for r, s in zip(case.runs, case.sims, strict=False)
              if s.cpu_per_robot_s > 0]
    return statistics.median(ratios) if ratios else None


def report(cases: list[Case], load: tuple[float, float, float], args: argparse.Namespace) -> dict[str, Any]:
    """Print the table and return the JSON figures."""
    print()
    print(f"mission_speed: {args.seeds} seed(s), cap {args.max_duration:.0f} robot s a run; load average "
          f"{load[0]:.2f} {load[1]:.2f} {load[2]:.2f} on {os.cpu_count()} cores")
    print()
    print("| mission | world | runs (how ended) | rtf wall min/med/max | rtf CPU min/med/max | "
          "CPU s per robot s (run / process) | RSS peak MB | sim alone CPU rtf | overhead vs sim |")
    print("|---|---|---|---|---|---|---|---|---|")
    result: dict[str, Any] = {"rtf_median": {}, "cpu_rtf_median": {}, "rss_peak_mb": {},
                              "overhead_vs_sim_median": {}, "cpu_per_robot_s_median": {}}
    for case in cases:
        if not case.runs:
            print(f"| {case.mission} | {case.label} | none: {'; '.join(case.skipped) or 'skipped'} |"
                  " - | - | - | - | - | - |")
            continue
        ended = ", ".join(f"{r.status.lower()}/{r.stopped_by}" for r in case.runs)
        per = statistics.median(r.cpu_per_robot_s for r in case.runs)
        proc = statistics.median(r.process_cpu_s / r.robot_s for r in case.runs if r.robot_s > 0)
        ratio = overhead(case)
        rss = max(r.rss_peak_mb for r in case.runs)
        print(f"| {case.mission} | {case.label} | {ended} | {_spread([r.rtf for r in case.runs])} | "
              f"{_spread([r.cpu_rtf for r in case.runs])} | {per:.3f} / {proc:.3f} | {rss:.0f} | "
              f"{_spread([s.cpu_rtf for s in case.sims])} | "
              f"{'-' if ratio is None else f'{ratio:.1f}x'} |")
        for key, value in (("rtf_median", statistics.median(r.rtf for r in case.runs)),
                           ("cpu_rtf_median", statistics.median(r.cpu_rtf for r in case.runs)),
                           ("rss_peak_mb", rss), ("overhead_vs_sim_median", ratio),
                           ("cpu_per_robot_s_median", per)):
            result[key].setdefault(case.mission, {})[case.label] = None if value is None else round(value, 3)
    print()
    print("Top cost centres (share of the run's CPU, median run by CPU real-time factor):")
    for case in cases:
        if not case.runs:
            continue
        middle = sorted(case.runs, key=lambda r: r.cpu_rtf)[len(case.runs) // 2]
        centres = "; ".join(f"{name} {share:.0%}" for name, _, share in middle.centres)
        print(f"- {case.mission} on {case.label}: {centres}")
    for case in cases:
        for note in case.skipped:
            print(f"note: {case.mission} on {case.label}: {note}")
    result["runs"] = [{"mission": r.mission, "world": c.label, "seed": r.seed, "status": r.status,
                       "stopped_by": r.stopped_by, "robot_s": r.robot_s, "wall_s": round(r.wall_s, 3),
                       "cpu_s": round(r.cpu_s, 3), "process_cpu_s": round(r.process_cpu_s, 3),
                       "rss_peak_mb": r.rss_peak_mb, "sim_cpu_s": r.sim_cpu_s}
                      for c in cases for r in c.runs]
    result["load_average"] = [round(x, 2) for x in load]
    return result


def main(argv: list[str] | None = None) -> int:
    """Run the missions and the simulator alone; print the table and the JSON line."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=3, help="seeds per mission and world (default 3)")
    parser.add_argument("--max-duration", type=float, default=300.0,
                        help="robot seconds a run may take at most (default 300)")
    parser.add_argument("--missions", default=",".join(MISSIONS), help="comma-separated missions")
    parser.add_argument("--worlds", default="default,large", help="default, large or both (default both)")
    parser.add_argument("--quick", action="store_true",
                        help="CI size: one seed, the default worlds, 60 robot seconds a run")
    parser.add_argument("--work", type=Path, default=None, help="keep the runs here (default: a temp dir)")
    args = parser.parse_args(argv)
    if args.quick:
        args.seeds, args.max_duration, args.worlds = 1, min(args.max_duration, 60.0), "default"
    missions = [m.strip() for m in args.missions.split(",") if m.strip()]
    unknown_names = sorted(set(missions) - set(MISSIONS))
    if unknown_names:
        parser.error(f"unknown mission(s) {unknown_names}; known: {', '.join(MISSIONS)}")
    worlds = {w.strip() for w in args.worlds.split(",")}
    seeds = list(range(1, args.seeds + 1))
    with tempfile.TemporaryDirectory(prefix="mission_speed_") as temp:
        work = args.work or Path(temp)
        work.mkdir(parents=True, exist_ok=True)
        cases: list[Case] = []
        started = time.perf_counter()
        if "default" in worlds:
            for mission in missions:
                case = Case(mission, _default_world(mission), "default")
                cases.append(case)
                run_case(case, seeds=seeds, work=work, max_duration=args.max_duration,
                         unknown=_unknown_map(mission), params=_params(mission))
        if "large" in worlds:
            world, route = large_world(work)
            for mission in missions:
                case = Case(mission, str(world), LARGE)
                cases.append(case)
                params = _params(mission)
                if mission == "patrol":
                    if route is None:
                        case.skipped.append("no patrol route could be made from the robot's map")
                        continue
                    params["route"] = str(route)
                if mission == "go_to_intent":
                    graphs = sorted(work.glob(f"map_scene-{LARGE}-*/scene_graph.json"))
                    if not graphs:
                        case.skipped.append("no scene graph of this floor (run map_scene on it first)")
                        continue
                    params["scene_graph"] = str(graphs[0])
                run_case(case, seeds=seeds, work=work, max_duration=args.max_duration,
                         unknown=_unknown_map(mission), params=params)
        result = report(cases, os.getloadavg(), args)
        result["elapsed_s"] = round(time.perf_counter() - started, 1)
    print(json.dumps(result, sort_keys=True))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
