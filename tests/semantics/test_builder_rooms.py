"""Instances are placed in the room whose floor holds them, furniture that covers the floor included."""

from __future__ import annotations

import pytest

from missiontree.backends.sim.world import load_world
from missiontree.semantics.builder import SceneBuilder


@pytest.mark.parametrize("world_name", ["generated:100", "generated:101", "generated:104"])
def test_a_bed_is_in_its_bedroom(world_name: str) -> None:
    """Every object at its true place and size gets the room it stands in, beds (1.6 x 2 m) included.

    A bed is an obstacle of the map: its middle lies a metre from any room's floor, beyond the
    0.8 m a small object's room is looked for in; it used to hang under the building, no room.
    """
    world = load_world(world_name)
    builder = SceneBuilder()
    builder.update_rooms(world.grid, (world.start.x, world.start.y), 0.0)
    placed = {}
    for obj in world.objects:
        inst = builder.scene.map.add(obj.label, (obj.pose.x, obj.pose.y, obj.elevation), 0.0, size=obj.size)
        placed[inst.id] = obj
    builder.step(1.0)
    room_names = {}  # segmented room id -> true room name, by the room holding its middle
    for room in builder.scene.rooms:
        true_room = world.room_at(*room.centroid)
        room_names[room.id] = true_room.name if true_room else None
    beds = 0
    for inst in builder.scene.map:
        obj = placed[inst.id]
        truth = world.room_at(obj.pose.x, obj.pose.y)
        assert inst.room is not None, f"{inst.id} at {obj.pose.x:.2f}, {obj.pose.y:.2f}: no room"
        assert room_names[inst.room] == truth.name, inst.id
        beds += obj.label == "bed"
    assert beds >= 1
