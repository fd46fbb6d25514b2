"""A fleet over ROS 2 as the session wires it: one namespaced robot per member (runs without ROS)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from missiontree.errors import ConfigError
from missiontree.session.fleet import Ros2FleetClock, ros2_member_options
from missiontree.session.mission import MissionRequest, Session

REPO = Path(__file__).resolve().parents[2]


def test_each_member_gets_its_namespace_and_name_over_the_run_config() -> None:
    """robot2's options put it under /robot2, named robot2, keeping the run config's other ROS 2 keys."""
    options: dict[str, Any] = {"seed": 1, "config": {"ros2": {"use_sim_time": True, "namespace": "/other"},
                                                     "x": 1}}
    member = ros2_member_options(options, "robot2")
    assert member["config"]["ros2"] == {"use_sim_time": True, "namespace": "/robot2", "name": "robot2"}
    assert member["config"]["x"] == 1 and member["seed"] == 1
    assert options["config"]["ros2"]["namespace"] == "/other"  # the run's options are not changed


class _Clocked:
    def __init__(self) -> None:
        self.t = 5.0
        self.calls: list[str] = []

    def now(self) -> float:
        return self.t

    def spin_until(self, t: float) -> None:
        self.t = t

    def stop(self) -> None:
        self.calls.append("stop")

    def close(self) -> None:
        self.calls.append("close")


def test_the_ros2_fleet_clock_follows_the_first_robot_and_stops_every_robot() -> None:
    """The fleet's time is the first robot's ROS time; stop and close reach every robot."""
    robots = [_Clocked(), _Clocked()]
    clock = Ros2FleetClock(robots)
    clock.spin_until(7.5)
    assert clock.now() == 7.5 and clock.truth is None
    clock.stop()
    clock.close()
    assert robots[1].calls == ["stop", "close"]


def test_a_kill_over_ros2_is_refused_before_any_robot_is_built(tmp_path: Path) -> None:
    """--kill-robot with --backend ros2 is a ConfigError naming sim-ros' --kill-robot."""
    request = MissionRequest(mission=REPO / "trees" / "fleet_patrol.yaml", backend="ros2",
                             robots=2, kill_robots=["robot2@10"], out=tmp_path / "run", quiet=True)
    with pytest.raises(ConfigError, match="sim-ros"):
        Session.open(request)
