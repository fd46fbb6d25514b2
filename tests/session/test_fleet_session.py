"""Fleet runs through the session: N robots, the tree once per robot, losses recorded, one robot unchanged."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from missiontree.errors import ConfigError
from missiontree.session import MissionRequest, run_mission
from missiontree.session.fleet import Kill, parse_kill, robot_count
from missiontree.testing import clean_state

# four waypoints near the office world's start: a short patrol a fleet finishes in seconds
MISSION = """\
version: 1
params:
  laps: 1
run:
  backend: sim
  world: office
  tick_hz: 10
  max_duration: 240
  seed: 2
{extra}
root:
  FleetPatrol:
    name: patrol
    laps: ${{laps}}
    waypoints: [[1.5, 3.0, 0.0], [3.5, 3.0, 0.0], [3.5, 6.0, 0.0], [1.5, 6.0, 0.0]]
"""


@pytest.fixture(autouse=True)
def _clean() -> None:
    clean_state()


def _mission(tmp_path: Path, extra: str = "") -> Path:
    path = tmp_path / "fleet.yaml"
    path.write_text(MISSION.format(extra=extra), encoding="utf-8")
    return path


def _events(run_dir: Path) -> list[dict[str, object]]:
    lines = (run_dir / "ticks.jsonl").read_text(encoding="utf-8").splitlines()
    return [json.loads(line) for line in lines if '"event":"tick"' not in line]


def test_robot_count_takes_the_flag_then_set_then_the_run_section() -> None:
    """--robots beats --set robots=, which beats run: robots:, else one robot."""
    assert robot_count(3, "2", 4) == 3
    assert robot_count(None, "2", 4) == 2
    assert robot_count(None, None, 4) == 4
    assert robot_count(None, None, None) == 1
    with pytest.raises(ConfigError):
        robot_count(None, "two", None)


def test_parse_kill_reads_name_at_seconds() -> None:
    """robot2@12.5 is a kill of robot2 at 12.5 s; a malformed one is a ConfigError."""
    assert parse_kill("robot2@12.5") == Kill("robot2", 12.5)
    with pytest.raises(ConfigError):
        parse_kill("robot2")


def test_two_robots_share_the_patrol_and_every_event_names_its_robot(tmp_path: Path) -> None:
    """--robots 2: both robots visit waypoints, each visit carries its robot, the summary has both."""
    out = tmp_path / "run"
    result = run_mission(MissionRequest(mission=_mission(tmp_path), robots=2, out=out))
    assert result.status.name == "SUCCESS"
    reached = [e for e in _events(out) if e["event"] == "waypoint_reached"]
    assert {e["robot"] for e in reached} == {"robot1", "robot2"}
    assert len({e["waypoint"] for e in reached}) == 4
    fleet = json.loads((out / "summary.json").read_text(encoding="utf-8"))["fleet"]
    assert set(fleet["robots"]) == {"robot1", "robot2"}
    assert all(r["status"] == "SUCCESS" for r in fleet["robots"].values())


def test_a_killed_robots_waypoints_are_reassigned_and_the_mission_still_succeeds(tmp_path: Path) -> None:
    """robot2 killed at 1 s: robot_lost and fleet_rebalanced are logged, the loss is in the summary."""
    out = tmp_path / "run"
    result = run_mission(MissionRequest(mission=_mission(tmp_path), robots=2, out=out,
                                        kill_robots=["robot2@1"]))
    assert result.status.name == "SUCCESS"
    kinds = [e["event"] for e in _events(out)]
    assert "robot_lost" in kinds and "fleet_rebalanced" in kinds
    fleet = json.loads((out / "summary.json").read_text(encoding="utf-8"))["fleet"]
    assert fleet["lost"] == ["robot2"]
    assert fleet["robots"]["robot2"]["status"] == "FAILURE"
    assert "killed" in fleet["robots"]["robot2"]["reason"]
    visits = next(iter(fleet["dispatchers"].values()))["visits"]
    assert all(v >= 1 for v in visits.values())


def test_a_fleet_whose_every_robot_is_killed_fails(tmp_path: Path) -> None:
    """Both robots killed: nobody can finish, the mission ends FAILURE."""
    out = tmp_path / "run"
    result = run_mission(MissionRequest(mission=_mission(tmp_path), robots=2, out=out,
                                        kill_robots=["robot1@1", "robot2@1"]))
    assert result.status.name == "FAILURE"


def test_run_robots_in_the_mission_file_builds_the_fleet(tmp_path: Path) -> None:
    """run: robots: 2 is a fleet run without any flag."""
    out = tmp_path / "run"
    run_mission(MissionRequest(mission=_mission(tmp_path, extra="  robots: 2"), out=out, max_duration=2))
    summary = json.loads((out / "summary.json").read_text(encoding="utf-8"))
    assert summary["fleet"]["count"] == 2


def test_one_robot_runs_the_single_robot_path(tmp_path: Path) -> None:
    """Without robots (or with 1) the summary has no fleet section and a single robot's final pose."""
    out = tmp_path / "run"
    run_mission(MissionRequest(mission=_mission(tmp_path), out=out, max_duration=2))
    summary = json.loads((out / "summary.json").read_text(encoding="utf-8"))
    assert "fleet" not in summary and "true_final_pose" in summary


def test_a_kill_without_a_fleet_is_refused(tmp_path: Path) -> None:
    """--kill-robot on a single robot is a ConfigError."""
    with pytest.raises(ConfigError):
        run_mission(MissionRequest(mission=_mission(tmp_path), out=tmp_path / "r", kill_robots=["robot1@1"]))


def test_a_killed_robots_clock_goes_on_with_the_fleets() -> None:
    """After a kill, the dead robot's now() follows the fleet's clock while its pose stamp stays put."""
    from missiontree.backends.sim.fleet import create_fleet

    fleet = create_fleet("office", robots=2, seed=1)
    try:
        fleet.spin_until(1.0)
        fleet.kill("robot2")
        fleet.spin_until(5.0)
        dead = fleet["robot2"]
        stamped = dead.pose()
        assert dead.now() == pytest.approx(5.0)
        assert stamped is not None and stamped.stamp == pytest.approx(1.0)
    finally:
        fleet.close()
