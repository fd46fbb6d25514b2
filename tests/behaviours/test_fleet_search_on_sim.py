"""trees/fleet_find_object.yaml, two robots on the simulator: the first find ends it for all; absent said."""

from __future__ import annotations

import io
import json
import math
import sys
from pathlib import Path
from typing import Any

from missiontree.session import MissionRequest, run_mission
from missiontree.testing import clean_state

sys.path.insert(0, str(Path(__file__).resolve().parent))
from test_search_mission import TARGET, corner_world  # noqa: E402  (the single robot's search world)

REPO = Path(__file__).resolve().parents[2]
MISSION = REPO / "trees" / "fleet_find_object.yaml"


def _run(world: Path, tmp: Path) -> tuple[str, list[dict[str, Any]], dict[str, Any]]:
    clean_state()
    log = io.StringIO()
    result = run_mission(MissionRequest(
        mission=MISSION, world=str(world), params={"target": "red backpack"}, robots=2, quiet=True,
        log_stream=log, handle_signals=False, max_duration=600, out=tmp / "run",
        config={"camera": {"rate": 2.0}}))
    assert result.stopped_by == "status", f"stopped by {result.stopped_by}, not by the tree"
    events = [json.loads(line) for line in log.getvalue().splitlines() if line.strip()]
    return result.status.name, events, result.summary["fleet"]


def test_the_first_confirmed_find_ends_the_search_for_both_robots(tmp_path: Path) -> None:
    """SUCCESS; one fleet_found names the finder near the backpack; the other robot's watch ends it."""
    status, events, fleet = _run(corner_world(tmp_path), tmp_path)
    assert status == "SUCCESS"
    finds = [e for e in events if e.get("event") == "fleet_found" and e.get("first")]
    assert len(finds) == 1
    finder = finds[0]["finder"]
    assert math.hypot(finds[0]["x"] - TARGET[0], finds[0]["y"] - TARGET[1]) < 1.0
    other = "robot2" if finder == "robot1" else "robot1"
    assert fleet["robots"][other]["status"] == "SUCCESS"
    ended = [e for e in events if e.get("event") == "fleet_search_ended"]
    assert [e["robot"] for e in ended] == [other] and ended[0]["finder"] == finder
    assert fleet["dispatchers"]["search_board"]["found"]["robot"] == finder


def test_an_absent_target_ends_not_found_for_the_fleet_and_never_found(tmp_path: Path) -> None:
    """No red backpack: FAILURE, each robot 'not found', no fleet_found."""
    status, events, fleet = _run(corner_world(tmp_path, with_target=False), tmp_path)
    assert status == "FAILURE"
    assert not [e for e in events if e.get("event") == "fleet_found"]
    for end in fleet["robots"].values():
        assert end["status"] == "FAILURE" and "not found" in end["reason"], end
