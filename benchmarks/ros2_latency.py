"""How long a sensor message takes over DDS, across processes, until a leaf can see it.

A child process publishes TurtleBot 4-sized LaserScans (360 beams) stamped with the ROS time of
publication. This process holds a Ros2Robot polling ``scan()`` as a leaf would (every 0.5 ms)
and, as the reference, a bare rclpy subscription in its own context that records the arrival
time in its callback: the floor DDS and rclpy set. Rounds alternate which of the two is listening
(the other is destroyed), so they never compete for the interpreter. Printed: per-round medians,
the ratio Ros2Robot / bare rclpy (min/median/max over rounds), and the wall
time of trees/patrol.yaml over ROS 2 (real time) against the in-process simulator (as fast as it
goes) in the same run, with the waypoints each reached (skip it with ``--no-patrol``).

    ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST python benchmarks/ros2_latency.py [--rounds 6] [--no-patrol]

The last line is JSON: scan_latency_median_ms, scan_latency_p95_ms (target <= 10 ms), ...
"""

from __future__ import annotations

import argparse
import json
import os
import random
import statistics
import subprocess
import sys
import textwrap
import time
from pathlib import Path
from typing import Any

# Discovery must stay on this machine; a domain id of our own keeps other runs out.
os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
os.environ.setdefault("ROS_DOMAIN_ID", str(random.Random(os.getpid()).randint(150, 199)))
REPO = Path(__file__).resolve().parents[1]

PUBLISHER = textwrap.dedent("""
    import math, sys, time
    import numpy as np
    import rclpy
    from rclpy.node import Node
    from missiontree.backends.ros2 import conversions as conv
    from missiontree.backends.ros2.robot import reliable_qos
    from missiontree.types import LaserScan
    rclpy.init()
    node = Node("latency_publisher")
    pub = node.create_publisher(__import__("sensor_msgs.msg", fromlist=["LaserScan"]).LaserScan, "/scan",
                                reliable_qos(10))
    ranges = np.linspace(0.2, 8.0, 360, dtype=np.float32)
    period = 1.0 / float(sys.argv[1])
    print("ready", flush=True)
    while rclpy.ok():
        now = node.get_clock().now().nanoseconds * 1e-9
        pub.publish(conv.scan_to_msg(LaserScan(now, -math.pi, 2 * math.pi / 360, 0.15, 12.0, ranges)))
        time.sleep(period)
""")


def percentile(values: list[float], q: float) -> float:
    """The q-th percentile (0-100) by linear interpolation."""
    ordered = sorted(values)
    k = (len(ordered) - 1) * q / 100.0
    lo, hi = int(k), min(int(k) + 1, len(ordered) - 1)
    return ordered[lo] + (ordered[hi] - ordered[lo]) * (k - lo)


def measure_robot(samples: int, domain: int) -> list[float]:
    """Latencies (ms) from publication to Ros2Robot.scan() returning the scan, polled every 0.5 ms."""
    from missiontree.backends.ros2.profile import load_profile
    from missiontree.backends.ros2.robot import Ros2Robot

    robot = Ros2Robot(load_profile("turtlebot4", {"domain_id": domain}), node_name="latency_robot",
                      install_signal_stop=False)
    try:
        latencies: list[float] = []
        last_stamp = None
        deadline = time.monotonic() + 30.0
        while len(latencies) < samples + 5 and time.monotonic() < deadline:
            scan = robot.scan()
            if scan is not None and scan.stamp != last_stamp:
                latencies.append((robot.now() - scan.stamp) * 1000.0)
                last_stamp = scan.stamp
            time.sleep(0.0005)
        return latencies[5:]  # the first ones may predate the subscription's match
    finally:
        robot.close()


def measure_bare(samples: int, domain: int) -> list[float]:
    """Latencies (ms) from publication to a bare rclpy callback (the reference)."""
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from rclpy.qos import qos_profile_sensor_data
    from sensor_msgs.msg import LaserScan

    context = rclpy.Context()
    rclpy.init(context=context, domain_id=domain)
    node = Node("latency_bare", context=context)
    latencies: list[float] = []

    def on_scan(msg: Any) -> None:
        now = node.get_clock().now().nanoseconds * 1e-9
        latencies.append((now - (msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9)) * 1000.0)

    node.create_subscription(LaserScan, "/scan", on_scan, qos_profile_sensor_data)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    deadline = time.monotonic() + 30.0
    try:
        while len(latencies) < samples + 5 and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.1)
        return latencies[5:]
    finally:
        executor.shutdown()
        node.destroy_node()
        context.try_shutdown()


def _reached(run_dir: Path) -> list[str]:
    """Waypoints reached, in order, from a run's tick log."""
    log = run_dir / "ticks.jsonl"
    if not log.exists():
        return []
    events = (json.loads(line) for line in log.read_text(encoding="utf-8").splitlines())
    return [e["waypoint"] for e in events if e.get("event") == "waypoint_reached"]


def _mission_seconds(run_dir: Path) -> float:
    """The mission's duration on its robot clock, from the run's summary (nan when missing)."""
    summary = run_dir / "summary.json"
    if not summary.exists():
        return float("nan")
    return round(float(json.loads(summary.read_text(encoding="utf-8")).get("duration", "nan")), 3)


def _is_prefix(a: list[str], b: list[str]) -> bool:
    """True when the shorter sequence is the start of the longer one."""
    shorter, longer = sorted([a, b], key=len)
    return longer[: len(shorter)] == shorter


def patrol_wall_times(tree: Path, world: str, seed: int, domain: int,
                      max_duration: float | None) -> dict[str, Any]:
    """Wall seconds of the patrol in-process (simulator) and over ROS 2 against sim-ros, in one run."""
    import tempfile

    env = dict(os.environ, ROS_DOMAIN_ID=str(domain))
    exe = [sys.executable, "-m", "missiontree.cli.main"]
    common = ["run", str(tree), "--seed", str(seed)]
    if max_duration is not None:
        common += ["--max-duration", str(max_duration)]
    with tempfile.TemporaryDirectory(prefix="missiontree-bench-") as tmp:
        t0 = time.monotonic()
        subprocess.run([*exe, *common, "--out", f"{tmp}/sim"], env=env, check=False, cwd=REPO,
                       capture_output=True)
        in_process = time.monotonic() - t0
        # real time, clock held until the first goal: the world starts with the mission, as in-process
        serve = [*exe, "sim-ros", "--world", world, "--seed", str(seed), "--paused"]
        server = subprocess.Popen(serve, env=env, cwd=REPO, stdout=subprocess.DEVNULL,
                                  stderr=subprocess.DEVNULL)
        try:
            time.sleep(3.0)
            t0 = time.monotonic()
            subprocess.run([*exe, *common, "--backend", "ros2", "--out", f"{tmp}/ros2"], env=env, check=False,
                           cwd=REPO, capture_output=True)
            over_ros = time.monotonic() - t0
        finally:
            server.send_signal(2)
            server.wait(timeout=15)
        sim_reached, ros_reached = _reached(Path(tmp) / "sim"), _reached(Path(tmp) / "ros2")
        sim_clock, ros_clock = _mission_seconds(Path(tmp) / "sim"), _mission_seconds(Path(tmp) / "ros2")
    return {"patrol_wall_s_sim": round(in_process, 3), "patrol_wall_s_ros2": round(over_ros, 3),
            "patrol_wall_ratio_ros2_over_sim": round(over_ros / in_process, 3),
            "patrol_mission_clock_s_sim": sim_clock, "patrol_mission_clock_s_ros2": ros_clock,
            "patrol_waypoints_reached_sim": len(sim_reached),
            "patrol_waypoints_reached_ros2": len(ros_reached),
            # with a duration limit one run may stop a waypoint earlier: the order must still agree
            "patrol_waypoints_agree": _is_prefix(sim_reached, ros_reached)}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=6, help="alternating rounds (default 6)")
    parser.add_argument("--samples", type=int, default=100, help="scans per round (default 100)")
    parser.add_argument("--hz", type=float, default=50.0, help="publication rate (default 50)")
    parser.add_argument("--no-patrol", dest="patrol", action="store_false",
                        help="skip timing trees/patrol.yaml over ROS 2 against the in-process simulator")
    parser.add_argument("--tree", type=Path, default=REPO / "trees" / "patrol.yaml",
                        help="the patrol mission to time (default trees/patrol.yaml)")
    parser.add_argument("--patrol-max-duration", type=float, metavar="S",
                        help="stop each patrol run after S seconds of its clock (default: the mission's)")
    args = parser.parse_args()
    domain = int(os.environ["ROS_DOMAIN_ID"])
    print(f"ROS_DOMAIN_ID={domain}, discovery {os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE']}; "
          f"{args.rounds} rounds x {args.samples} scans at {args.hz:g} Hz from another process")
    publisher = subprocess.Popen([sys.executable, "-c", PUBLISHER, str(args.hz)], stdout=subprocess.PIPE,
                                 text=True, cwd=REPO)
    robot_all: list[float] = []
    bare_all: list[float] = []
    ratios: list[float] = []
    try:
        assert publisher.stdout is not None and publisher.stdout.readline().strip() == "ready"
        for i in range(args.rounds):
            order = [("robot", measure_robot), ("bare", measure_bare)]
            if i % 2:
                order.reverse()
            medians: dict[str, float] = {}
            for name, measure in order:
                values = measure(args.samples, domain)
                if not values:
                    raise SystemExit(f"round {i + 1}: no scans reached the {name} subscriber")
                (robot_all if name == "robot" else bare_all).extend(values)
                medians[name] = statistics.median(values)
            ratios.append(medians["robot"] / medians["bare"])
            print(f"round {i + 1}: Ros2Robot.scan() median {medians['robot']:.3f} ms, bare rclpy callback "
                  f"median {medians['bare']:.3f} ms, ratio {ratios[-1]:.2f}")
    finally:
        publisher.terminate()
        publisher.wait(timeout=10)
    figures: dict[str, Any] = {
        "scan_latency_median_ms": round(statistics.median(robot_all), 3),
        "scan_latency_p95_ms": round(percentile(robot_all, 95), 3),
        "scan_latency_max_ms": round(max(robot_all), 3),
        "bare_rclpy_latency_median_ms": round(statistics.median(bare_all), 3),
        "bare_rclpy_latency_p95_ms": round(percentile(bare_all, 95), 3),
        "ratio_robot_over_bare_min": round(min(ratios), 3),
        "ratio_robot_over_bare_median": round(statistics.median(ratios), 3),
        "ratio_robot_over_bare_max": round(max(ratios), 3),
        "samples": len(robot_all),
    }
    f = figures
    print(f"Ros2Robot.scan(): median {f['scan_latency_median_ms']} ms, p95 {f['scan_latency_p95_ms']} ms "
          f"(target <= 10 ms); bare rclpy median {f['bare_rclpy_latency_median_ms']} ms; ratio min/median/max"
          f" {f['ratio_robot_over_bare_min']}/{f['ratio_robot_over_bare_median']}/"
          f"{f['ratio_robot_over_bare_max']}")
    if args.patrol:
        tree = args.tree
        import yaml

        run = (yaml.safe_load(tree.read_text()) or {}).get("run", {})
        times = patrol_wall_times(tree, str(run.get("world", "office")), int(run.get("seed", 0)), domain,
                                  args.patrol_max_duration)
        t = times
        print(f"patrol wall time: in-process {t['patrol_wall_s_sim']:.1f} s "
              f"({t['patrol_waypoints_reached_sim']} waypoints), "
              f"over ROS 2 {t['patrol_wall_s_ros2']:.1f} s ({t['patrol_waypoints_reached_ros2']} waypoints), "
              f"ratio {t['patrol_wall_ratio_ros2_over_sim']:.1f}; "
              f"waypoint order agrees: {t['patrol_waypoints_agree']}")
        figures.update(times)
    print(json.dumps(figures))
    return 0


if __name__ == "__main__":
    sys.exit(main())
