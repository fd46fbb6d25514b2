"""Fault injection on the robot: the navigation server lost mid-goal, sensors going quiet.

Both are infrastructure faults: the mission fails with the reason (never skips on to SUCCESS), the
robot is stopped, and the run's files are whole.
"""

from __future__ import annotations

from pathlib import Path

from conftest import FaultyRobot, assert_clean_end, faulty_plugins, read_lines

from missiontree.session import MissionRequest, run_mission

PATROL = """\
version: 1
run: {backend: faulty, world: combined, tick_hz: 10, max_duration: 300, seed: 1}
root:
  Patrol:
    name: patrol
    waypoints_file: scenario_c
    laps: 1
    xy_tolerance: 0.3
    yaw_tolerance: 6.28
"""


def _run(tmp_path: Path, **faults: float) -> tuple[FaultyRobot, Path]:
    mission = tmp_path / "patrol.yaml"
    mission.write_text(PATROL, encoding="utf-8")
    made: list[FaultyRobot] = []
    out = tmp_path / "run"
    result = run_mission(MissionRequest(mission=mission, out=out, plugins=faulty_plugins(made, **faults)))
    assert result.exit_code == 1
    return made[0], out


def _halted(robot: FaultyRobot) -> bool:
    """stop() was called and the simulator's base is commanded to zero velocity."""
    base = robot._robot._base
    return robot.stop_calls >= 1 and (base.cmd_v, base.cmd_w) == (0.0, 0.0)


def test_backend_lost_mid_goal_fails_the_mission_with_the_reason(tmp_path: Path) -> None:
    """The NavigateToPose server vanishes 20 s in: FAILURE saying so, not waypoints skipped to SUCCESS."""
    robot, out = _run(tmp_path, lost_at=20.0)
    summary = assert_clean_end(out, why="NavigateToPose server vanished", stopped=lambda: _halted(robot))
    assert summary["status"] == "FAILURE"
    lines = read_lines(out / "ticks.jsonl")
    assert [e for e in lines if e.get("event") == "goal_sent" and e["t"] < 20.0], "early goals lost"
    assert not [e for e in lines if e.get("event") == "waypoint_skipped"]
    # failed at the first lost goal: no later waypoint was tried
    assert not [e for e in lines if e.get("event") == "goal_sent" and e["t"] > 20.0]


def test_sensors_going_quiet_are_stale_and_fail_the_mission(tmp_path: Path) -> None:
    """Pose and scan freeze 15 s in: the pose goes stale and the mission fails saying so."""
    robot, out = _run(tmp_path, quiet_at=15.0)
    summary = assert_clean_end(out, why="pose was last updated", stopped=lambda: _halted(robot))
    assert summary["status"] == "FAILURE"
    assert summary["duration"] < 60.0  # noticed within the pose-age limit, not at the duration limit


WATCH = """\
version: 1
run: {backend: faulty, world: combined, tick_hz: 10, max_duration: 120, seed: 1}
root:
  Parallel:
    name: watch_a_while
    policy: success_on_all
    children:
      - Wait: {seconds: 100}
      - Surveillance: {name: surveillance, mode: detect, confirm: false, camera_timeout: 5.0}
"""


def test_a_camera_going_quiet_fails_surveillance_as_stale(tmp_path: Path) -> None:
    """The camera's frames stop 10 s in: Surveillance fails saying the camera went quiet."""
    mission = tmp_path / "watch.yaml"
    mission.write_text(WATCH, encoding="utf-8")
    made: list[FaultyRobot] = []
    out = tmp_path / "run"
    result = run_mission(MissionRequest(mission=mission, out=out,
                                        plugins=faulty_plugins(made, quiet_at=10.0)))
    assert result.exit_code == 1
    summary = assert_clean_end(out, why="camera quiet", stopped=lambda: _halted(made[0]))
    assert 14.0 < summary["duration"] < 30.0
