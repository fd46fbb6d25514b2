"""trees/patrol.yaml over ROS 2 reaches the same waypoints as in-process on the simulator.

The ROS 2 run is `missiontree run trees/patrol.yaml --backend ros2` against `missiontree sim-ros` in
another process, over DDS; the reference is the same command with the simulator in-process.
"""

from __future__ import annotations

import json
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
#: Seconds of the mission's clock each run gets: a few waypoints of the route, not the whole lap.
DURATION = 20.0

_RUN = (yaml.safe_load(PATROL.read_text(encoding="utf-8")) or {}).get("run", {}) if PATROL.exists() else {}
#: sim-ros serves the world and seed the mission runs on in-process.
SIM_ROS_WORLD = str(_RUN.get("world", "office"))
SIM_ROS_SEED = int(_RUN.get("seed", 0))


def _reached(run_dir: Path) -> list[str]:
    """Names of the waypoints reached, in order, from a run's tick log."""
    names = []
    for line in (run_dir / "ticks.jsonl").read_text(encoding="utf-8").splitlines():
        event = json.loads(line)
        if event.get("event") == "waypoint_reached":
            names.append(event["waypoint"])
    return names


def _run(args: list[str], env: dict[str, str] | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "missiontree.cli.main", "run", str(PATROL), *args],
                          capture_output=True, text=True, cwd=REPO, env=env, timeout=DURATION + 90)


def test_patrol_over_ros2_reaches_the_same_waypoints_as_in_process(request: pytest.FixtureRequest,
                                                                    tmp_path: Path) -> None:
    """The ROS 2 run's waypoints are the in-process run's, in order (one more or fewer at the time limit)."""
    if not PATROL.exists():
        pytest.skip("trees/patrol.yaml is not there yet")
    in_process = _run(["--out", str(tmp_path / "sim"), "--max-duration", str(DURATION)])
    expected = _reached(tmp_path / "sim")
    if len(expected) < 2:
        pytest.skip(f"the patrol reaches fewer than 2 waypoints in-process ({in_process.stdout.strip()} "
                    f"{in_process.stderr.strip()[-500:]}); nothing to compare over ROS 2")

    import os

    sim_ros: Any = request.getfixturevalue("sim_ros")  # started only once there is something to compare
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST", ROS_DOMAIN_ID=str(sim_ros.domain_id))
    over_ros = _run(["--backend", "ros2", "--out", str(tmp_path / "ros2"), "--max-duration", str(DURATION)],
                    env=env)
    reached = _reached(tmp_path / "ros2")
    why = f"{over_ros.stdout}\n{over_ros.stderr[-2000:]}\nsim-ros: {sim_ros.output()[-1000:]}"
    assert len(reached) >= 2, why
    shorter, longer = sorted([expected, reached], key=len)
    assert longer[: len(shorter)] == shorter, f"in-process {expected}, over ROS 2 {reached}"
    assert len(longer) - len(shorter) <= 1, f"in-process {expected}, over ROS 2 {reached}"
