"""The battery plugin over ROS 2, against ``missiontree sim-ros`` in another process (real DDS).

sim-ros loads the installed plugins and publishes the simulated battery as ``sensor_msgs/BatteryState``
on ``/battery_state`` (the plugin's ``to_msg``); a Ros2Robot subscribes with the plugin's ``from_msg``.
Then the plugin's patrol_and_charge mission runs with ``--backend ros2`` and must end as it does
in-process: SUCCESS after its laps, having charged on the dock. sim-ros runs with ``--sim-time`` at
several times real time and ``--paused`` (the clock starts with the mission's first goal).
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("rclpy", reason="ROS 2 extra not installed: pip install -e .[ros2]; setup-ros2.sh")
pytest.importorskip("nav2_msgs.action", reason="nav2_msgs not built: run scripts/setup-ros2.sh")
battery = pytest.importorskip("missiontree_battery.battery",
                              reason="missiontree-battery is not installed (make setup installs it)")
pytestmark = [pytest.mark.ros2, pytest.mark.slow]

os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
REPO = Path(__file__).resolve().parents[2]
PLUGIN = REPO / "plugins" / "missiontree-battery"
MISSION = PLUGIN / "missions" / "patrol_and_charge.yaml"
WORLD = PLUGIN / "worlds" / "corridor_dock.yaml"
#: Simulated seconds per wall second served by sim-ros (modest: a loaded machine stalls pose messages).
RATE = 3.0
#: A domain no other test module of this run uses at the same time (those use 20-219).
DOMAIN = 220 + os.getpid() % 12


def _env() -> dict[str, str]:
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST", ROS_DOMAIN_ID=str(DOMAIN),
               PYTHONUNBUFFERED="1")
    env.pop("MISSIONTREE_DISABLE_PLUGIN_AUTOLOAD", None)
    return env


@pytest.fixture
def sim_ros(tmp_path: Path) -> Iterator[subprocess.Popen[str]]:
    log = open(tmp_path / "sim-ros.log", "w+")  # noqa: SIM115 - closed below
    process = subprocess.Popen(
        [sys.executable, "-m", "missiontree.cli.main", "sim-ros", "--world", str(WORLD), "--sim-time",
         "--rate", str(RATE), "--paused"],
        env=_env(), cwd=REPO, stdout=log, stderr=subprocess.STDOUT, text=True)
    process.log = log  # type: ignore[attr-defined]
    yield process
    if process.poll() is None:
        process.send_signal(signal.SIGINT)
        try:
            process.wait(timeout=10)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()
    log.close()


def _output(process: Any) -> str:
    process.log.flush()
    process.log.seek(0)
    return str(process.log.read())[-3000:]


def test_battery_state_from_sim_ros_reaches_a_ros2_robot(sim_ros: Any) -> None:
    """/battery_state carries the simulated charge; the robot's reading is stamped and converted."""
    from missiontree.backends.ros2.profile import load_profile
    from missiontree.backends.ros2.robot import Ros2Robot

    profile = load_profile("turtlebot4", {"domain_id": DOMAIN, "shutdown_timeout": 0.3, "use_sim_time": True})
    robot = Ros2Robot(profile, node_name="battery_test", install_signal_stop=False, sensors=[battery.BATTERY])
    try:
        assert robot.sensor_names() == ["battery"]
        deadline = time.monotonic() + 60
        while robot.sensor("battery") is None and time.monotonic() < deadline:
            time.sleep(0.05)
        reading = robot.sensor("battery")
        assert reading is not None, f"no /battery_state from sim-ros\n{_output(sim_ros)}"
        assert isinstance(reading.value, battery.BatteryReading)
        assert reading.value.percentage == pytest.approx(0.5, abs=0.01)  # the world's start: half full
        assert 12.0 < reading.value.voltage < 16.8 and not reading.value.charging
        assert reading.stamp >= 0.0
    finally:
        robot.close()


def test_patrol_and_charge_over_ros2(sim_ros: Any, tmp_path: Path) -> None:
    """The mission over ROS 2 ends SUCCESS after its laps, having charged on the dock."""
    config = tmp_path / "ros2.yaml"
    config.write_text("ros2:\n  use_sim_time: true\n  startup_timeout: 60.0\n", encoding="utf-8")
    out = tmp_path / "run"
    done = subprocess.run(
        [sys.executable, "-m", "missiontree.cli.main", "run", str(MISSION), "--backend", "ros2", "--config",
         str(config), "--out", str(out)], env=_env(), cwd=REPO, capture_output=True, text=True, timeout=900)
    why = f"{done.stdout[-2000:]}\n{done.stderr[-2000:]}\nsim-ros: {_output(sim_ros)}"
    assert done.returncode == 0, why
    events = [json.loads(line) for line in (out / "ticks.jsonl").read_text(encoding="utf-8").splitlines()]
    finished = [e for e in events if e.get("event") == "mission_finished"]
    assert finished and finished[-1]["status"] == "SUCCESS", why
    assert sum(e.get("event") == "lap_done" for e in events) == 2, why
    assert any(e.get("event") == "patrol_preempted" for e in events), why
    samples = [e["percentage"] for e in events if e.get("event") == "sensor" and e.get("sensor") == "battery"]
    low = samples.index(min(samples))
    assert max(samples[low:]) >= 0.85, f"no charge seen on the dock: {samples}\n{why}"
