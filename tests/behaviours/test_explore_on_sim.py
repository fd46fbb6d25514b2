"""Explore on the simulator in unknown-map mode: a door the robot cannot see from the start is found."""

from __future__ import annotations

import io
import json
from pathlib import Path

import numpy as np
import pytest
import yaml

from missiontree.errors import ConfigError
from missiontree.mapping.mapfile import read_map

# Two rooms, x 0-4 (west) and 4-8 (east), joined by a door at x 4, y 0.1-1.2. A partition at
# x 2.5 from the floor up to y 2.5 hides the door from the start (1.0, 3.0): the robot has to
# go round it, see the door, and go through to map the east room.
HIDDEN_DOOR = {
    "name": "hidden_door",
    "robot": {"profile": "turtlebot4", "start": {"x": 1.0, "y": 3.0, "yaw": 0.0}},
    "walls": {
        "polygons": [[[0.0, 0.0], [8.0, 0.0], [8.0, 4.0], [0.0, 4.0]]],
        "segments": [[[4.0, 1.2], [4.0, 4.0]], [[4.0, 0.0], [4.0, 0.1]], [[2.5, 0.0], [2.5, 2.5]]],
    },
}


def mission(tmp: Path, **params: object) -> Path:
    path = tmp / "explore.yaml"
    path.write_text(yaml.safe_dump({
        "version": 1, "run": {"backend": "sim", "map": "unknown", "tick_hz": 10},
        "root": {"Explore": {"name": "explore", **params}}}, sort_keys=False))
    return path


def unknown_map_available() -> bool:
    from missiontree.backends.sim import create_robot

    try:
        create_robot({"world": "office", "unknown_map": True}).close()
    except ConfigError:
        return False
    return True


pytestmark = pytest.mark.skipif(not unknown_map_available(), reason="the simulator has no unknown-map mode")


def test_a_door_not_seen_from_the_start_is_found_and_the_room_behind_it_mapped(tmp_path: Path) -> None:
    """Starting blind behind a partition, Explore finds the door, maps the east room and saves the map."""
    from missiontree.session import MissionRequest, Session

    world = tmp_path / "hidden_door.yaml"
    world.write_text(yaml.safe_dump(HIDDEN_DOOR, sort_keys=False))
    log = io.StringIO()
    request = MissionRequest(mission=mission(tmp_path), world=str(world), seed=3, unknown_map=True,
                             max_duration=240, out=tmp_path / "run", log_stream=log, handle_signals=False,
                             config={"camera": {"rate": 0.5, "width": 64, "height": 48}})
    with Session.open(request) as session:
        robot = session.robot
        start_map = robot.occupancy()
        r, c = start_map.world_to_cell(6.0, 2.0)
        assert start_map.data[r, c] == -1  # the east room is unknown at the start
        result = session.run()
        learned = robot.occupancy()
        trajectory = np.array([(x, y) for _, x, y in robot.trajectory])
    assert result.status.name == "SUCCESS", result.summary
    # the robot went round the partition (into the pocket in front of the door) ...
    assert ((trajectory[:, 0] > 2.6) & (trajectory[:, 1] < 2.4)).any()
    # ... and the east room, seen only through the door, is mapped free
    for x, y in [(5.0, 1.0), (6.0, 2.0), (7.0, 3.0)]:
        r, c = learned.world_to_cell(x, y)
        assert learned.data[r, c] == 0, (x, y)
    events = [json.loads(line) for line in log.getvalue().splitlines()]
    goals = [e for e in events if e["event"] == "explore_goal"]
    assert any(e["x"] > 2.5 and e["y"] < 2.5 for e in goals)
    saved = read_map(tmp_path / "run" / "map.yaml")
    r, c = saved.world_to_cell(6.0, 2.0)
    assert saved.data[r, c] == 0
