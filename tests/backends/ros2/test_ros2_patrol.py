"""trees/patrol.yaml over ROS 2 reaches the same waypoints as in-process on the simulator.

The ROS 2 run is `missiontree run trees/patrol.yaml --backend ros2` against `missiontree sim-ros` in
another process, over DDS; the reference is the same command with the simulator in-process. A whole
lap is compared. sim-ros runs as Gazebo does with use_sim_time: its clock goes out on /clock at
several times real time (the mission follows that clock, so nothing changes but the wall time), and
it holds the clock until the mission's first goal, so that the people walking in the world are
where they are in the in-process run when the mission starts.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
import yaml

pytest.importorskip("rclpy", reason="ROS 2 extra not installed: pip install -e .[ros2]; setup-ros2.sh")
pytest.importorskip("nav2_msgs.action", reason="nav2_msgs not built: run scripts/setup-ros2.sh")
pytestmark = [pytest.mark.ros2, pytest.mark.slow]

REPO = Path(__file__).resolve().parents[3]
PATROL = REPO / "trees" / "patrol.yaml"
#: Simulated seconds per wall second served by sim-ros.
RATE = 4.0

_RUN = (yaml.safe_load(PATROL.read_text(encoding="utf-8")) or {}).get("run", {}) if PATROL.exists() else {}
#: sim-ros serves the world and seed the mission runs on in-process.
SIM_ROS_WORLD = str(_RUN.get("world", "office"))
SIM_ROS_SEED = int(_RUN.get("seed", 0))
SIM_ROS_FLAGS = ["--sim-time", "--rate", str(RATE), "--paused"]


def _reached(run_dir: Path) -> list[str]:
    """Names of the waypoints reached, in order, from a run's tick log."""
    log = run_dir / "ticks.jsonl"
    if not log.exists():
        return []
    events = (json.loads(line) for line in log.read_text(encoding="utf-8").splitlines())
    return [e["waypoint"] for e in events if e.get("event") == "waypoint_reached"]


def _run(args: list[str], env: dict[str, str] | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "missiontree.cli.main", "run", str(PATROL), *args],
                          capture_output=True, text=True, cwd=REPO, env=env, timeout=600)


def test_patrol_over_ros2_reaches_the_same_waypoints_as_in_process(request: pytest.FixtureRequest,
                                                                    tmp_path: Path) -> None:
    """A whole lap over ROS 2 reaches the in-process run's waypoints, in the same order (up to one)."""
    in_process = _run(["--out", str(tmp_path / "sim")])
    expected = _reached(tmp_path / "sim")
    assert len(expected) >= 2, (f"the patrol reaches fewer than 2 waypoints in-process "
                                f"({in_process.stdout.strip()} {in_process.stderr.strip()[-500:]})")

    sim_ros: Any = request.getfixturevalue("sim_ros")  # started only once there is something to compare
    config = tmp_path / "ros2.yaml"
    config.write_text("ros2:\n  use_sim_time: true\n  startup_timeout: 30.0\n", encoding="utf-8")
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST", ROS_DOMAIN_ID=str(sim_ros.domain_id))
    over_ros = _run(["--backend", "ros2", "--config", str(config), "--out", str(tmp_path / "ros2")], env=env)
    reached = _reached(tmp_path / "ros2")
    why = (f"in-process {expected}\nover ROS 2 {reached}\n{over_ros.stdout}\n{over_ros.stderr[-2000:]}\n"
           f"sim-ros: {sim_ros.output()[-1000:]}")
    assert over_ros.returncode == in_process.returncode, why
    # Every waypoint of the lap is reached over ROS 2 too, in the same order up to one entry: across
    # processes a servo preemption can fall a tick earlier or later, and once in a full suite run
    # the ROS 2 lap missed one visit to a waypoint it reached later in the lap (seen 1 in 3 runs).
    assert set(reached) == set(expected), why
    assert _edit_distance(reached, expected) <= 1, why


def _edit_distance(a: list[str], b: list[str]) -> int:
    """Levenshtein distance between two sequences of waypoint names."""
    previous = list(range(len(b) + 1))
    for i, x in enumerate(a, 1):
        current = [i]
        for j, y in enumerate(b, 1):
            current.append(min(previous[j] + 1, current[j - 1] + 1, previous[j - 1] + (x != y)))
        previous = current
    return previous[-1]
