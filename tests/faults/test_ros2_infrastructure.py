"""Infrastructure lost over ROS 2: `missiontree sim-ros` killed mid-run of the patrol.

`missiontree run trees/patrol.yaml --backend ros2` against sim-ros in another process; 20 s after the
first goal sim-ros is killed outright (SIGKILL: no goodbye on DDS). The run must end FAILURE with the
reason (it used to skip every later waypoint and end SUCCESS, exit 0), halting the tree and stopping
the robot, with a complete summary and the whole tick log.
"""

from __future__ import annotations

import importlib.util
import json
import subprocess
import sys
import time
from pathlib import Path

import pytest
from conftest import REPO, assert_clean_end, read_lines

pytest.importorskip("rclpy", reason="ROS 2 extra not installed: pip install -e .[ros2]; setup-ros2.sh")
pytest.importorskip("nav2_msgs.action", reason="nav2_msgs not built: run scripts/setup-ros2.sh")
pytestmark = [pytest.mark.ros2, pytest.mark.slow]

_FIXTURES = REPO / "tests" / "backends" / "ros2" / "conftest.py"  # SimRos, domain ids (not a plugin here)
_spec = importlib.util.spec_from_file_location("ros2_fixtures", _FIXTURES)
assert _spec is not None and _spec.loader is not None
ros2_fixtures = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(ros2_fixtures)


def _events(log: Path, kind: str) -> list[dict]:
    if not log.exists():
        return []
    found = []
    for line in log.read_text(encoding="utf-8").splitlines():
        try:
            entry = json.loads(line)
        except json.JSONDecodeError:  # a line being written
            continue
        if entry.get("event") == kind:
            found.append(entry)
    return found


def test_killing_sim_ros_mid_patrol_fails_the_run_with_the_reason(tmp_path: Path) -> None:
    """sim-ros SIGKILLed 20 s into the patrol: exit 1, FAILURE saying the robot was lost, never SUCCESS."""
    domain = ros2_fixtures.next_domain_id()
    server = ros2_fixtures.SimRos(domain, world="combined", seed=1)
    out = tmp_path / "run"
    run = subprocess.Popen(
        [sys.executable, "-m", "missiontree", "run", str(REPO / "trees" / "patrol.yaml"),
         "--backend", "ros2", "--out", str(out), "--quiet"],
        env=ros2_fixtures.ros_env(domain), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        cwd=REPO)
    try:
        ros2_fixtures.wait_until(lambda: _events(out / "ticks.jsonl", "goal_sent") or run.poll() is not None,
                                 120, "the patrol's first goal over ROS 2")
        assert run.poll() is None, run.communicate()
        time.sleep(20)
        server.process.kill()
        stdout, stderr = run.communicate(timeout=120)
    finally:
        if run.poll() is None:
            run.kill()
            run.communicate()
        server.stop()
    why = f"{stdout}\n{stderr[-2000:]}"
    assert run.returncode == 1, why
    assert "Traceback" not in stderr, why
    summary = assert_clean_end(out, why="lost", stopped_by="status")
    assert summary["status"] == "FAILURE", why
    lines = read_lines(out / "ticks.jsonl")
    assert any(line.get("event") == "patrol_lost" for line in lines), why
    assert not any(line.get("event") == "waypoint_skipped" for line in lines), why
