"""SceneBuilder.step rebuilds on changes and on refined positions, never for an unchanged scene."""

from __future__ import annotations

import numpy as np

from missiontree.semantics.builder import BuilderParams, SceneBuilder
from missiontree.semantics.rooms import RoomRegion

KITCHEN = RoomRegion("room_1", "kitchen", np.array([[0, 0], [5, 0], [5, 4], [0, 4]], float), 20.0, (2.5, 2.0))


def builder_with_two_objects() -> SceneBuilder:
    builder = SceneBuilder(BuilderParams(refresh=5.0), rooms=[KITCHEN])
    builder.scene.map.add("table", (2.0, 1.0, 0.375), 0.0, size=(1.2, 0.8, 0.75), room="room_1")
    builder.scene.map.add("cup", (2.1, 1.0, 0.8), 0.0, size=(0.1, 0.1, 0.1), room="room_1")
    return builder


def frames_with_detections_arrived(builder: SceneBuilder) -> None:
    """What add_frame does when a frame's detections project into the map (no camera needed here)."""
    builder._dirty = True


def test_an_added_object_rebuilds_at_once() -> None:
    """The first step after adds rebuilds and returns the added changes."""
    builder = builder_with_two_objects()
    changes = builder.step(1.0)
    assert changes is not None and [c.kind for c in changes] == ["added", "added"]
    assert builder.scene.version == 1
    assert {e["relation"] for e in builder.scene.graph.edges} == {"contains", "on"}


def test_an_unchanged_scene_is_not_rebuilt_while_frames_keep_coming() -> None:
    """Frames with detections but nothing different: no rebuild at the refresh, no new version."""
    builder = builder_with_two_objects()
    builder.step(1.0)
    for t in (2.0, 7.0, 13.0, 30.0):
        frames_with_detections_arrived(builder)
        assert builder.step(t) is None
    assert builder.scene.version == 1


def test_a_refined_position_is_rebuilt_at_the_next_refresh() -> None:
    """A position refined without a change record shows in the graph after ``refresh`` seconds."""
    builder = builder_with_two_objects()
    builder.step(1.0)
    builder.scene.map.update("cup_1", position=(4.0, 3.0, 0.05))  # fusion refines silently
    frames_with_detections_arrived(builder)
    assert builder.step(3.0) is None  # refresh not yet due
    frames_with_detections_arrived(builder)
    assert builder.step(6.5) == []  # a refresh: rebuilt, no change to report
    cup = builder.scene.graph.node("cup_1")
    assert cup is not None and cup["coordinates"] == [4.0, 3.0, 0.05]
    assert builder.scene.version == 2
    assert "on" not in {e["relation"] for e in builder.scene.graph.edges}


def test_a_new_room_type_is_rebuilt_at_the_next_refresh() -> None:
    """A room typed differently (e.g. by the VLM's votes) refreshes the graph's room label."""
    votes = {"room_1": ("kitchen", 0.5)}
    builder = SceneBuilder(
        BuilderParams(refresh=5.0),
        rooms=[RoomRegion("room_1", "unknown", KITCHEN.polygon, 20.0, (2.5, 2.0))],
        room_typer=lambda room, labels: (*votes[room.id], ["votes"]),
    )
    builder.scene.map.add("cup", (2.1, 1.0, 0.8), 0.0, size=(0.1, 0.1, 0.1), room="room_1")
    builder.step(1.0)
    assert builder.scene.graph.node("room_1")["label"] == "kitchen"
    votes["room_1"] = ("dining_room", 0.7)
    frames_with_detections_arrived(builder)
    assert builder.step(7.0) == []
    assert builder.scene.graph.node("room_1")["label"] == "dining_room"


def test_only_instances_that_changed_are_described_again() -> None:
    """After a rebuild, only a new instance and one whose colour changed are described again."""
    asked: list[str] = []

    def describer(inst):
        asked.append(inst.id)
        return f"a {inst.colour} {inst.label}", "boxy", "small"

    builder = SceneBuilder(BuilderParams(refresh=5.0), rooms=[KITCHEN], describer=describer)
    builder.scene.map.add("table", (2.0, 1.0, 0.375), 0.0, size=(1.2, 0.8, 0.75), room="room_1")
    builder.scene.map.add("cup", (2.1, 1.0, 0.8), 0.0, size=(0.1, 0.1, 0.1), room="room_1")
    builder.step(1.0)
    assert sorted(asked) == ["cup_1", "table_1"]
    asked.clear()
    builder.scene.map.add("chair", (1.0, 3.0, 0.45), 2.0, size=(0.5, 0.5, 0.9), room="room_1")
    builder.scene.map.update("cup_1", colour="red")  # measured anew, no change record
    builder.step(2.0)
    assert sorted(asked) == ["chair_1", "cup_1"]
    assert builder.scene.graph.node("cup_1")["description"] == "a red cup"
