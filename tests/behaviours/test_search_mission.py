"""trees/find_object.yaml end to end on the simulator, on a map the robot has never seen."""

from __future__ import annotations

import io
import json
import math
from pathlib import Path
from typing import Any

import yaml

from missiontree.session import MissionRequest, Session

REPO = Path(__file__).resolve().parents[2]
MISSION = REPO / "trees" / "find_object.yaml"
#: Where the red backpack stands: behind the wall that hides the east part from the start.
TARGET = (6.6, 1.0)


def corner_world(folder: Path, with_target: bool = True) -> Path:
    """An 8 x 5 m room split by a wall from the south side up to y 3.4: the east part is out of sight.

    The robot starts in the west part facing west. There: a blue backpack (same class, other colour)
    and a red umbrella (same colour, other class). Round the wall's end, in the east part: the red
    backpack (with ``with_target``).
    """
    objects: list[dict[str, Any]] = [
        {
            "id": "backpack_blue",
            "label": "backpack",
            "color": "blue",
            "size": [0.32, 0.22, 0.45],
            "pose": {"x": 2.6, "y": 4.2},
        },
        {
            "id": "umbrella_red",
            "label": "umbrella",
            "color": "red",
            "shape": "cylinder",
            "size": [0.1, 0.1, 0.9],
            "pose": {"x": 0.6, "y": 0.6},
        },
    ]
    if with_target:
        objects.append(
            {
                "id": "backpack_red",
                "label": "backpack",
                "color": "red",
                "size": [0.32, 0.22, 0.45],
                "pose": {"x": TARGET[0], "y": TARGET[1]},
            }
        )
    world = {
        "name": "search_corner",
        "description": "the target is round a corner",
        "robot": {"profile": "turtlebot4", "start": {"x": 1.8, "y": 1.6, "yaw": math.pi}},
        "walls": {
            "height": 2.5,
            "thickness": 0.1,
            "polygons": [[[0, 0], [8, 0], [8, 5], [0, 5]]],
            "segments": [[[4.0, 0.0], [4.0, 3.4]]],
        },
        "rooms": [
            {"name": "west", "type": "office", "polygon": [[0, 0], [4, 0], [4, 5], [0, 5]]},
            {"name": "east", "type": "bedroom", "polygon": [[4, 0], [8, 0], [8, 5], [4, 5]]},
        ],
        "objects": objects,
        "people": [],
    }
    path = folder / ("corner.yaml" if with_target else "corner_absent.yaml")
    path.write_text(yaml.safe_dump(world, sort_keys=False))
    return path


def run(world: Path, target: str, max_duration: float = 500) -> tuple[str, list[dict[str, Any]], Any]:
    log = io.StringIO()
    request = MissionRequest(
        mission=MISSION,
        world=str(world),
        params={"target": target},
        quiet=True,
        log_stream=log,
        handle_signals=False,
        max_duration=max_duration,
        config={"camera": {"rate": 2.0}},
    )
    with Session.open(request) as session:
        result = session.run()
        final = session.robot.truth.robot_pose()
        stopped_by = result.stopped_by
    events = [json.loads(line) for line in log.getvalue().splitlines() if line.strip()]
    assert stopped_by == "status", f"stopped by {stopped_by}, not by the tree"
    return result.status.name, events, final


def of(events: list[dict[str, Any]], kind: str) -> list[dict[str, Any]]:
    return [e for e in events if e.get("event") == kind]


def failure_text(events: list[dict[str, Any]]) -> str:
    return " | ".join(
        str(c.get("feedback", ""))
        for e in of(events, "tick")
        for c in e.get("changed", [])
        if c.get("status") == "FAILURE"
    )


def test_the_red_backpack_round_a_corner_is_found_and_faced_within_a_metre(tmp_path: Path) -> None:
    """The decoys in view are passed over or rejected; the robot goes round the wall and faces the target."""
    status, events, final = run(corner_world(tmp_path), "red backpack")
    assert status == "SUCCESS", failure_text(events)[-1500:]
    found = of(events, "object_found")
    assert found and math.hypot(found[-1]["x"] - TARGET[0], found[-1]["y"] - TARGET[1]) < 0.5
    assert math.hypot(final.x - TARGET[0], final.y - TARGET[1]) < 1.0
    assert abs(math.degrees(final.bearing_to(*TARGET))) < 20.0
    for rejected in of(events, "candidate_rejected"):  # only decoys were ever rejected
        assert math.hypot(rejected["x"] - TARGET[0], rejected["y"] - TARGET[1]) > 0.5


def test_an_absent_target_ends_not_found_after_exploring(tmp_path: Path) -> None:
    """No red backpack anywhere (only decoys): FAILURE "not found" once explored, never a found."""
    status, events, _ = run(corner_world(tmp_path, with_target=False), "red backpack")
    assert status == "FAILURE"
    assert not of(events, "object_found")
    assert of(events, "search_explored")
    assert "not found" in failure_text(events)
