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


def explore_world(tmp_path: Path, world_doc: dict[str, object], max_duration: float,
                  **params: object) -> tuple[object, object, dict[str, float], list[dict[str, object]]]:
    """Run Explore on a world from no map: (result, learned map, share of each room seen free, events)."""
    from missiontree.session import MissionRequest, Session

    world = tmp_path / "world.yaml"
    world.write_text(yaml.safe_dump(world_doc, sort_keys=False))
    log = io.StringIO()
    request = MissionRequest(mission=mission(tmp_path, **params), world=str(world), seed=1, unknown_map=True,
                             max_duration=max_duration, out=tmp_path / "run", log_stream=log,
                             handle_signals=False, quiet=True,
                             config={"camera": {"rate": 0.5, "width": 64, "height": 48}})
    with Session.open(request) as session:
        result = session.run()
        learned = session.robot.occupancy()
        truth = session.robot.world
        seen: dict[str, float] = {}
        g = truth.grid
        inside = (g.data >= 0) & (g.data < 50)
        for room in truth.rooms:   # the truth scores what was seen; the leaf never reads it
            rows, cols = np.nonzero(inside)
            xs = g.origin.x + (cols + 0.5) * g.resolution
            ys = g.origin.y + (rows + 0.5) * g.resolution
            mine = np.array([room.contains(x, y) for x, y in zip(xs, ys, strict=True)])
            lr = np.floor((ys[mine] - learned.origin.y) / learned.resolution).astype(int)
            lc = np.floor((xs[mine] - learned.origin.x) / learned.resolution).astype(int)
            values = learned.data[lr, lc]
            seen[room.name] = float(np.mean((values >= 0) & (values < 50)))
    events = [json.loads(line) for line in log.getvalue().splitlines()]
    return result, learned, seen, events


@pytest.mark.slow
def test_every_room_behind_the_narrow_doors_of_a_corridor_is_explored(tmp_path: Path) -> None:
    """Rooms behind 0.8-0.9 m doors and rooms off them (a held-out kind of flat): each one seen, then SUCCESS.

    The old leaf gave up the inner room's doorway ('no progress toward it for 15 s' on the straight
    line, while the path led out of the room and round) and called the place explored with it unseen.
    """
    from explore_worlds import corridor_world

    result, _, seen, _ = explore_world(tmp_path, corridor_world(), max_duration=600)
    assert result.status.name == "SUCCESS", result.summary.get("failure_reasons")
    assert min(seen.values()) >= 0.9, seen


def test_a_door_the_robot_cannot_pass_while_the_map_shows_it_open_ends_partial(tmp_path: Path) -> None:
    """A low cable cover the lidar cannot see blocks the door: FAILURE 'partial' naming it, never SUCCESS.

    summary.json carries the reason, exploration.json the frontier left and the area behind it.
    """
    world = {**HIDDEN_DOOR, "name": "hidden_door_blocked",
             "objects": [{"label": "cable cover", "size": [0.3, 1.0, 0.08], "movable": False,
                          "pose": {"x": 4.0, "y": 0.65, "yaw": 0.0}}]}
    walls = dict(HIDDEN_DOOR["walls"])  # type: ignore[arg-type]
    # a partition behind the door: the east room is not seen through it
    walls["segments"] = [*walls["segments"], [[5.0, 0.0], [5.0, 3.0]]]
    world["walls"] = walls
    result, _, _, events = explore_world(tmp_path, world, max_duration=240)
    assert result.status.name == "FAILURE"
    reason = result.summary["failure_reasons"]["explore"][-1]
    assert reason.startswith("partial: 1 frontier left unexplored though the map shows a way ((4.")
    assert "m^2 unknown behind it" in reason
    report = json.loads((tmp_path / "run" / "exploration.json").read_text())
    assert report["outcome"] == "partial" and report["complete"] is False
    assert len(report["frontiers_left"]) == 1 and 4.0 <= report["frontiers_left"][0]["x"] <= 5.0
    assert report["unknown_left_m2"] > 5.0
    # the doorway's frontier may come in one piece or two (tried apart); the one left was tried three times
    assert len([e for e in events if e["event"] == "explore_try_failed"]) >= 2
    given_up = [e for e in events if e["event"] == "explore_blacklist"]
    assert len(given_up) == 1 and "after 3 tries" in given_up[0]["reason"]
