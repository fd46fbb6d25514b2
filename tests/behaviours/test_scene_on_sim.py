"""BuildSceneGraph on the simulator: trees/map_scene.yaml end to end, and the leaf beside a known-map turn."""

from __future__ import annotations

import json
import math
from pathlib import Path

from missiontree.backends.sim.world import load_world
from missiontree.semantics.scene_graph import SceneGraph
from missiontree.session import MissionRequest, Session, run_mission

REPO = Path(__file__).resolve().parents[2]
ALIAS = {"desk": "table", "dining table": "table"}


def events(run_dir: Path, kind: str) -> list[dict]:
    lines = (run_dir / "ticks.jsonl").read_text().splitlines()
    return [e for e in map(json.loads, lines) if e.get("event") == kind]


def test_map_scene_explores_and_writes_a_true_scene_graph(tmp_path: Path) -> None:
    """Exploring the unknown office builds rooms and objects; its scene_graph.json is NAIS-shaped."""
    result = run_mission(
        MissionRequest(mission=REPO / "trees/map_scene.yaml", out=tmp_path, max_duration=150, quiet=True)
    )
    assert result.run_dir == tmp_path
    graph = SceneGraph.load(tmp_path / "scene_graph.json")
    assert graph.building()["id"] == 0
    assert graph.rooms() and len(graph.objects()) >= 5
    assert all(graph.room_of(o["id"]) is not None for o in graph.objects())
    assert (tmp_path / "scene_graph.png").stat().st_size > 0
    changed = events(tmp_path, "scene_graph_changed")
    assert changed and sum(len(e["added"]) for e in changed) >= len(graph.objects())
    # scoring reads the truth: most objects stand where an object of their class really is
    world = load_world("office")
    right = sum(
        1
        for o in graph.objects()
        if any(
            ALIAS.get(t.label, t.label) == o["label"]
            and math.hypot(t.pose.x - o["coordinates"][0], t.pose.y - o["coordinates"][1]) <= 0.6
            for t in world.objects
        )
    )
    assert right >= 0.7 * len(graph.objects())


def test_the_leaf_beside_a_turn_on_a_known_map_shares_the_scene(tmp_path: Path) -> None:
    """With room polygons from a file, the live scene on the context has those rooms and the objects seen."""
    rooms = tmp_path / "rooms.yaml"
    rooms.write_text(
        "rooms:\n"
        "  - {name: kitchen, type: kitchen, polygon: [[0, 0], [5, 0], [5, 8], [0, 8]]}\n"
        "  - {name: office, type: office, polygon: [[5, 0], [12, 0], [12, 8], [5, 8]]}\n"
    )
    mission = tmp_path / "turn_and_map.yaml"
    mission.write_text(f"""version: 1
run: {{backend: sim, world: office, tick_hz: 10, seed: 4}}
root:
  Parallel:
    name: turn_and_map
    policy: success_on_one
    children:
      - Sequence:
          name: turns
          memory: true
          children:
            - Rotate: {{name: turn1, angle: 3.1, max_speed: 0.5, timeout: 30}}
            - Rotate: {{name: turn2, angle: 3.1, max_speed: 0.5, timeout: 30}}
      - BuildSceneGraph: {{name: scene, rooms: {rooms}}}
""")
    with Session.open(MissionRequest(mission=mission, out=tmp_path / "run", quiet=True)) as session:
        result = session.run()
        scene = session.context.scene
    assert result.status.name == "SUCCESS"
    assert {r["label"] for r in scene.graph.rooms()} <= {"kitchen", "office"}
    assert len(scene.map) >= 3 and scene.version >= 1
    kitchen_objects = [i for i in scene.map if i.room == "room_1"]
    assert kitchen_objects and all(i.description for i in scene.map)
    on_disk = SceneGraph.load(tmp_path / "run" / "scene_graph.json")
    assert {str(n["id"]) for n in on_disk.objects()} == {i.id for i in scene.map}
    assert events(tmp_path / "run", "scene_graph")  # the whole graph for ROS and viewers


def test_room_types_and_descriptions_can_come_from_the_vision_language_model(tmp_path: Path) -> None:
    """room_types/describe vlm: frames in the room and 20 % crops go to the VLM role, never blocking."""
    mission = tmp_path / "vlm.yaml"
    mission.write_text("""version: 1
run: {backend: sim, world: office, tick_hz: 10, seed: 4}
root:
  Parallel:
    name: turn_and_map
    policy: success_on_one
    children:
      - Rotate: {name: turn, angle: 6.2, max_speed: 0.5, timeout: 30}
      - BuildSceneGraph: {name: scene, room_types: vlm, describe: vlm, room_query_every: 3.0}
""")
    result = run_mission(MissionRequest(mission=mission, out=tmp_path / "run", quiet=True))
    assert result.status.name == "SUCCESS"
    calls = [e for e in events(tmp_path / "run", "model_call") if e.get("node") == "scene"]
    assert calls and all(e.get("role") == "vlm" for e in calls)
    graph = SceneGraph.load(tmp_path / "run" / "scene_graph.json")
    assert [r for r in graph.rooms() if r["label"] != "room"], "no room was typed by the VLM"
    assert all(o["description"] for o in graph.objects())


def test_the_scene_mission_reports_its_explored_share_from_its_own_map(tmp_path: Path) -> None:
    """A short run on an unknown map reports a share below one, in an event and scene_coverage.json."""
    mission = tmp_path / "turn_and_map.yaml"
    mission.write_text("""version: 1
run: {backend: sim, world: office, map: unknown, tick_hz: 10, seed: 4}
root:
  Parallel:
    name: turn_and_map
    policy: success_on_one
    children:
      - Rotate: {name: turn, angle: 3.1, max_speed: 0.5, timeout: 30}
      - BuildSceneGraph: {name: scene}
""")
    result = run_mission(MissionRequest(mission=mission, out=tmp_path / "run", quiet=True))
    assert result.status.name == "SUCCESS"
    reported = json.loads((tmp_path / "run" / "scene_coverage.json").read_text())
    assert 0.0 < reported["explored_share"] < 0.9 and reported["open_frontiers"] >= 1
    assert reported["known_free_m2"] > 1.0
    (event,) = events(tmp_path / "run", "scene_graph_explored")
    assert event["explored_share"] == reported["explored_share"]
    outcome = result.summary["outcome"]["scene_graph"]  # and in summary.json, with a line for the terminal
    assert outcome["explored_share"] == reported["explored_share"]
    assert "of the place explored" in outcome["text"]


def _still_scene(tmp_path: Path, gate: str) -> tuple[int, int]:
    """(frames looked at, frames skipped) by BuildSceneGraph on a robot standing still for 4 s."""
    tmp_path.mkdir(parents=True, exist_ok=True)
    mission = tmp_path / "still.yaml"
    mission.write_text(f"""version: 1
run: {{backend: sim, world: office, tick_hz: 10, seed: 4}}
root:
  Parallel:
    name: stand_and_map
    policy: success_on_one
    children:
      - Wait: {{name: stand, seconds: 4}}
      - BuildSceneGraph: {{name: scene{gate}}}
""")
    with Session.open(MissionRequest(mission=mission, out=tmp_path / "run", quiet=True)) as session:
        result = session.run()
        leaf = next(n for n in session.root.iterate() if n.name == "scene")
    assert result.status.name == "SUCCESS"
    return leaf.frames, leaf.skipped


def test_a_still_camera_is_not_detected_on_every_frame(tmp_path: Path) -> None:
    """With view_move/view_turn set, a still robot's frames go to the detector once a still_period."""
    every, skipped_none = _still_scene(tmp_path / "every", "")
    gated, skipped = _still_scene(tmp_path / "gated", ", view_move: 0.2, view_turn: 10, still_period: 1.0")
    assert skipped_none == 0 and every >= 15
    assert gated <= 6 and skipped >= every - gated - 1
