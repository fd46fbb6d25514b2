"""FleetExplore on a simulated fleet: one merged map, explored together, a killed robot's claim released."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import yaml

from missiontree.session import MissionRequest, run_mission
from missiontree.testing import clean_state

# Two rooms joined by a door at x 4 (y 0.1-1.2); a partition at x 2.5 hides the door from the start.
TWO_ROOMS = {
    "name": "two_rooms",
    "robot": {"profile": "turtlebot4", "start": {"x": 1.0, "y": 3.0, "yaw": 0.0}},
    "walls": {
        "polygons": [[[0.0, 0.0], [8.0, 0.0], [8.0, 4.0], [0.0, 4.0]]],
        "segments": [[[4.0, 1.2], [4.0, 4.0]], [[4.0, 0.0], [4.0, 0.1]], [[2.5, 0.0], [2.5, 2.5]]],
    },
}


def _run(tmp: Path, robots: int, kills: list[str] | None = None,
         max_duration: float = 300) -> tuple[Any, dict]:
    clean_state()
    world = tmp / "two_rooms.yaml"
    world.write_text(yaml.safe_dump(TWO_ROOMS, sort_keys=False))
    mission = tmp / "fleet_explore.yaml"
    mission.write_text(yaml.safe_dump({
        "version": 1, "run": {"backend": "sim", "map": "unknown", "tick_hz": 10},
        "root": {"FleetExplore": {"name": "explore"}}}, sort_keys=False))
    out = tmp / "run"
    result = run_mission(MissionRequest(mission=mission, world=str(world), seed=1, robots=robots, out=out,
                                        max_duration=max_duration, quiet=True, kill_robots=kills or []))
    summary = json.loads((out / "summary.json").read_text())
    return result, summary


def _events(tmp: Path, kind: str) -> list[dict]:
    lines = (tmp / "run" / "ticks.jsonl").read_text().splitlines()
    return [e for e in map(json.loads, lines) if e.get("event") == kind]


def test_two_robots_explore_both_rooms_on_one_map_and_end_explored(tmp_path: Path) -> None:
    """SUCCESS 'explored' for the fleet; each robot's saved map (the fleet's) has the room behind the door."""
    result, summary = _run(tmp_path, robots=2)
    assert result.status.name == "SUCCESS", summary.get("reason")
    robots = summary["fleet"]["robots"]
    assert {r["status"] for r in robots.values()} == {"SUCCESS"}
    goals = _events(tmp_path, "explore_goal")
    assert {g["robot"] for g in goals} == {"robot1", "robot2"}
    from missiontree.mapping.mapfile import read_map

    for name in ("robot1", "robot2"):
        saved = read_map(tmp_path / "run" / name / "map.yaml")
        r, c = saved.world_to_cell(6.0, 2.0)
        assert saved.data[r, c] == 0  # the east room, behind the hidden door, is known free


def test_a_killed_robot_is_lost_its_claim_released_and_the_others_finish(tmp_path: Path) -> None:
    """robot2 killed at 3 s: recorded lost (taken over), its frontier released, the others explore all."""
    result, summary = _run(tmp_path, robots=2, kills=["robot2@3"])
    assert result.status.name == "SUCCESS", summary.get("reason")
    fleet = summary["fleet"]
    assert fleet["lost"] == ["robot2"]
    assert fleet["robots"]["robot2"]["lost"]["taken_over"] is True
    assert "robot lost" in fleet["robots"]["robot2"]["lost"]["reason"]
    released = fleet["dispatchers"]["frontier_claims"]["released"]
    assert [r["robot"] for r in released] == ["robot2"]
    assert fleet["robots"]["robot1"]["status"] == "SUCCESS"
