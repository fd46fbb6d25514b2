"""The search leaves each alone on the simulator: full turn, colour mapper, locate.

The approach and the confirmation are in test_approach_confirm.py.
"""

from __future__ import annotations

import io
import json
import math
from pathlib import Path
from typing import Any

import pytest
import yaml

from missiontree.reasoning.search_priors import parse_target, region_score, room_priors
from missiontree.session import MissionRequest, Session

RED = (4.0, 2.5)
BLUE = (4.0, 4.2)


def room(tmp_path: Path, start: tuple[float, float, float], objects: list[dict[str, Any]]) -> Path:
    """A 6 x 6 m room with the given objects; the robot at ``start``."""
    world = {
        "name": "search_room",
        "description": "one room for the search leaves",
        "robot": {"profile": "turtlebot4", "start": {"x": start[0], "y": start[1], "yaw": start[2]}},
        "walls": {"height": 2.5, "thickness": 0.1, "polygons": [[[0, 0], [6, 0], [6, 6], [0, 6]]]},
        "rooms": [{"name": "office", "type": "office", "polygon": [[0, 0], [6, 0], [6, 6], [0, 6]]}],
        "objects": objects,
        "people": [],
    }
    path = tmp_path / "room.yaml"
    path.write_text(yaml.safe_dump(world))
    return path


def backpack(oid: str, colour: str, xy: tuple[float, float]) -> dict[str, Any]:
    return {
        "id": oid,
        "label": "backpack",
        "color": colour,
        "size": [0.32, 0.22, 0.45],
        "pose": {"x": xy[0], "y": xy[1]},
    }


def run(
    tmp_path: Path,
    world: Path,
    root: dict[str, Any],
    blackboard: dict[str, Any] | None = None,
    max_duration: float = 60,
    on_tick: Any = None,
) -> tuple[str, list[dict[str, Any]], Any]:
    """Run a one-leaf mission on ``world`` (known map); return status, events and the final true pose."""
    mission = {
        "version": 1,
        "description": "search leaf test",
        "run": {"backend": "sim", "tick_hz": 10, "seed": 1},
        "root": root,
    }
    if blackboard:
        mission["blackboard"] = blackboard
    path = tmp_path / "mission.yaml"
    path.write_text(yaml.safe_dump(mission, sort_keys=False))
    log = io.StringIO()
    request = MissionRequest(
        mission=path,
        world=str(world),
        quiet=True,
        log_stream=log,
        handle_signals=False,
        max_duration=max_duration,
        on_tick=on_tick,
    )
    with Session.open(request) as session:
        result = session.run()
        final = session.robot.truth.robot_pose()
    events = [json.loads(line) for line in log.getvalue().splitlines() if line.strip()]
    return result.status.name, events, final


def of(events: list[dict[str, Any]], kind: str) -> list[dict[str, Any]]:
    return [e for e in events if e.get("event") == kind]


def test_scan_rotate_really_turns_a_full_circle_with_a_look_at_each_stop(tmp_path: Path) -> None:
    """The heading integrated from the simulator's truth turns 360 deg; one look per stop, turning stopped."""
    world = room(tmp_path, (3.0, 3.0, 0.4), [])
    state: dict[str, float] = {}

    def follow(session: Session) -> None:
        yaw = session.robot.truth.robot_pose().yaw
        if "last" in state:
            state["turned"] = state.get("turned", 0.0) + math.remainder(yaw - state["last"], 2 * math.pi)
        state["last"] = yaw

    status, events, final = run(
        tmp_path, world, {"ScanRotate": {"name": "scan", "steps": 6, "pause": 0.5}}, on_tick=follow
    )
    assert status == "SUCCESS"
    assert math.degrees(state["turned"]) == pytest.approx(360.0, abs=8.0)
    looks = of(events, "scan_look")
    assert len(looks) == 7  # before turning and after each of the six steps
    assert [round(e["turned_deg"] / 60.0) for e in looks] == list(range(7))


@pytest.mark.parametrize(("yaw", "where"), [(0.0, "centre"), (-0.45, "left"), (0.45, "right")])
def test_colour_attention_places_the_red_region_left_centre_or_right(
    tmp_path: Path, yaw: float, where: str
) -> None:
    """The report's HSV mapper: the red backpack 2 m ahead, the robot turned so it shows left or right."""
    world = room(tmp_path, (2.0, 2.5, yaw), [backpack("red_bag", "red", RED)])
    status, events, _ = run(
        tmp_path,
        world,
        {"ColourAttention": {"name": "colour", "target": "red backpack", "wait": True}},
        max_duration=10,
    )
    assert status == "SUCCESS"
    seen = of(events, "colour_attention")[0]
    assert seen["position"] == where and seen["colour"] == "red" and seen["fraction"] >= 0.01


def test_colour_attention_fails_when_the_colour_covers_too_little(tmp_path: Path) -> None:
    """No red in view (a blue backpack only): FAILURE naming the colour and the threshold."""
    world = room(tmp_path, (1.0, 2.5, 0.0), [backpack("blue_bag", "blue", RED)])
    status, events, _ = run(
        tmp_path, world, {"ColourAttention": {"name": "colour", "colour": "red"}}, max_duration=10
    )
    assert status == "FAILURE" and not of(events, "colour_attention")


def test_the_target_phrase_and_the_room_priors() -> None:
    """The phrase "red backpack" reads as class and colour; a cup is likelier near a refrigerator."""
    target = parse_target("the red backpack", ["backpack", "cup", "person"])
    assert (target.label, target.colours, target.wanted) == ("backpack", ("red",), "red backpack")
    with pytest.raises(ValueError, match="names no class"):
        parse_target("a purple giraffe", ["backpack", "cup"])
    priors = room_priors("cup")
    assert max(priors, key=lambda r: priors[r]) == "kitchen"
    near_fridge = region_score((1.0, 1.0), priors, [("refrigerator", (1.5, 1.0))])
    near_bed = region_score((1.0, 1.0), priors, [("bed", (1.5, 1.0))])
    assert near_fridge > near_bed


def test_locate_takes_a_candidate_from_a_loaded_scene_graph_before_exploring(tmp_path: Path) -> None:
    """A graph naming a red backpack: Locate hands it over at once (no exploration), colour match first."""
    world = room(
        tmp_path, (1.0, 1.0, 0.0), [backpack("red_bag", "red", RED), backpack("blue_bag", "blue", BLUE)]
    )
    graph = {
        "nodes": [
            {"id": 0, "type": "building", "label": "Building", "description": ""},
            {
                "id": "bp_blue",
                "type": "object",
                "label": "backpack",
                "description": "a blue backpack",
                "coordinates": [BLUE[0], BLUE[1], 0.2],
            },
            {
                "id": "bp_red",
                "type": "object",
                "label": "backpack",
                "description": "a red backpack",
                "coordinates": [RED[0], RED[1], 0.2],
            },
        ],
        "edges": [],
    }
    graph_path = tmp_path / "graph.json"
    graph_path.write_text(json.dumps(graph))
    status, events, _ = run(
        tmp_path,
        world,
        {"Locate": {"name": "locate", "target": "red backpack", "scene_graph": str(graph_path)}},
        max_duration=10,
    )
    assert status == "SUCCESS"
    picked = of(events, "search_candidate")[0]
    assert (picked["id"], picked["source"]) == ("bp_red", "scene graph")
    assert not of(events, "explore_goal")
