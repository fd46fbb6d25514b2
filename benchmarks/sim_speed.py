"""How much faster than real time the simulator runs a patrol, with numba and with numpy alone.

60 simulated seconds of patrol in the `combined` world (the patrol-robot thesis's scenario C waypoint loop,
driven with navigate_to), lidar 360 beams at 10 Hz, RGB-D 320x240 at 5 Hz, three people walking.
The numba-accelerated run (the default) and the numpy-only reference are measured in the same
process, over the same stretch of simulated time (``--seconds``, both: a shorter numpy window would
compare the start of the loop, where the robot turns at its first waypoint, with the whole loop),
alternating and with the order turning each repetition. The speed-up is taken on CPU time (the
process's), the wall clock's beside it. Prints per-run lines, then one JSON line with the figures.

    .venv/bin/python benchmarks/sim_speed.py [--reps 5] [--seconds 30]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import time
from typing import Any

import yaml

from missiontree.backends.sim import create_robot
from missiontree.backends.sim.raycast import HAVE_NUMBA
from missiontree.paths import REPO_ROOT
from missiontree.types import Pose2D, Tolerance

TICK = 0.1


def patrol(seconds: float, accelerate: bool, seed: int = 0) -> dict[str, Any]:
    """Run the scenario C loop for ``seconds`` of simulated time; return speed and per-call costs."""
    route = yaml.safe_load((REPO_ROOT / "config" / "waypoints" / "scenario_c.yaml").read_text())
    points = {w["name"]: Pose2D(w["pose"][0], w["pose"][1]) for w in route["waypoints"]}
    order = route["order"][1:] + route["order"][:1]
    robot = create_robot({"world": "combined", "seed": seed, "config": {"accelerate": accelerate}})
    assert len(robot.world.crowd) == 3
    tolerance = Tolerance(0.25, 2 * math.pi)
    handle, goals, reached = None, 0, 0
    wall0, cpu0 = time.perf_counter(), time.process_time()
    while robot.now() < seconds - 1e-9:
        if handle is None or handle.status().done:
            if handle is not None and handle.result().succeeded:
                reached += 1
            handle = robot.navigate_to(points[order[goals % len(order)]], tolerance)
            goals += 1
        robot.spin_until(robot.now() + TICK)
        robot.scan()   # what a patrol's leaves read every tick
        robot.rgbd()
    wall, cpu = time.perf_counter() - wall0, time.process_time() - cpu0
    t = robot.timings
    return {
        "realtime_factor": robot.now() / wall,
        "realtime_factor_cpu": robot.now() / cpu,
        "lidar_ms": statistics.median(t["lidar"]),
        "camera_ms": statistics.median(t["camera"]),
        "planner_ms": statistics.median(t["planner"]) if t["planner"] else float("nan"),
        "scans": t["lidar"].count,
        "frames": t["camera"].count,
        "plans": t["planner"].count,
        "goals_reached": reached,
        "bumps": robot.bumps,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--reps", type=int, default=5, help="runs of each variant (alternating)")
    parser.add_argument("--seconds", type=float, default=30.0,
                        help="simulated seconds per run, of each variant (default 30)")
    args = parser.parse_args()
    if not HAVE_NUMBA:
        print("numba is not installed: only the numpy path is measured (pip install 'missiontree[accel]')")
    patrol(2.0, True)    # warm-up: load or compile the numba kernels
    patrol(1.0, False)
    fast: list[dict[str, Any]] = []
    slow: list[dict[str, Any]] = []
    for rep in range(args.reps):
        variants = [True, False] if HAVE_NUMBA else [False]
        if rep % 2:
            variants.reverse()
        for accelerate in variants:
            run = patrol(args.seconds, accelerate)
            (fast if accelerate else slow).append(run)
            print(f"run {rep + 1} {'numba' if accelerate else 'numpy'}: {run['realtime_factor']:7.1f}x real "
                  f"time (cpu {run['realtime_factor_cpu']:.1f}x)  lidar {run['lidar_ms']:.3f} ms  "
                  f"camera {run['camera_ms']:.3f} ms  planner {run['planner_ms']:.3f} ms  "
                  f"scans {run['scans']} frames {run['frames']} goals reached {run['goals_reached']}")
    main_runs = fast or slow

    def stat(runs: list[dict[str, Any]], key: str) -> tuple[float, float, float]:
        values = [r[key] for r in runs]
        return min(values), statistics.median(values), max(values)

    rf = stat(main_runs, "realtime_factor")
    speedups = [f["realtime_factor_cpu"] / s["realtime_factor_cpu"] for f, s in zip(fast, slow, strict=False)]
    wall_speedups = [f["realtime_factor"] / s["realtime_factor"] for f, s in zip(fast, slow, strict=False)]
    result: dict[str, Any] = {
        "benchmark": "sim_speed",
        "world": "combined", "sim_seconds": args.seconds, "people": 3, "lidar_hz": 10, "camera_hz": 5,
        "image": "320x240", "numba": HAVE_NUMBA, "reps": args.reps,
        "realtime_factor_min": round(rf[0], 1), "realtime_factor_median": round(rf[1], 1),
        "realtime_factor_max": round(rf[2], 1),
        "realtime_factor_cpu_median": round(stat(main_runs, "realtime_factor_cpu")[1], 1),
        "lidar_ms": round(stat(main_runs, "lidar_ms")[1], 4),
        "camera_ms": round(stat(main_runs, "camera_ms")[1], 4),
        "planner_ms": round(stat(main_runs, "planner_ms")[1], 4),
        "numpy_sim_seconds": args.seconds,
        "numpy_realtime_factor_median": round(stat(slow, "realtime_factor")[1], 2),
        "numpy_realtime_factor_cpu_median": round(stat(slow, "realtime_factor_cpu")[1], 2),
        "numpy_lidar_ms": round(stat(slow, "lidar_ms")[1], 4),
        "numpy_camera_ms": round(stat(slow, "camera_ms")[1], 4),
        "numpy_planner_ms": round(stat(slow, "planner_ms")[1], 4),
        "goals_reached_median": stat(main_runs, "goals_reached")[1],
        "load_average_1min": round(os.getloadavg()[0], 2),
    }
    if speedups:
        result.update({"numba_speedup_min": round(min(speedups), 1),
                       "numba_speedup_median": round(statistics.median(speedups), 1),
                       "numba_speedup_max": round(max(speedups), 1),
                       "numba_speedup_basis": "CPU time, same simulated seconds",
                       "numba_speedup_wall_median": round(statistics.median(wall_speedups), 1)})
    print(json.dumps(result))


if __name__ == "__main__":
    main()
