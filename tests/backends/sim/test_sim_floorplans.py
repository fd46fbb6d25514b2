"""Floorplans: a second world family (corridors, suites, open plan, clutter, warehouse), seeded and valid."""

from __future__ import annotations

import time
from collections import defaultdict
from typing import Any

import cv2
import numpy as np
import pytest
import yaml

from missiontree.backends.sim import load_world
from missiontree.backends.sim.floorplans import DOOR_MAX, DOOR_MIN, KINDS, floorplan_world, kind_of
from missiontree.backends.sim.placement import unreachable_rooms
from missiontree.backends.sim.placer import build
from missiontree.backends.sim.world import World
from missiontree.errors import WorldFileError


@pytest.fixture(scope="module")
def worlds(tmp_path_factory: pytest.TempPathFactory) -> dict[str, tuple[dict[str, Any], World]]:
    """One floorplan of every kind (seeds 0-6), as data and as loaded from a world file by load_world."""
    folder = tmp_path_factory.mktemp("floorplans")
    out = {}
    for seed in range(len(KINDS)):
        data = floorplan_world(seed)
        path = folder / f"floorplan_{seed}.yaml"
        path.write_text(yaml.dump(data, Dumper=getattr(yaml, "CSafeDumper", yaml.SafeDumper)))
        out[kind_of(seed)] = (data, load_world(path))
    return out


def _room_of(data: dict[str, Any], x: float, y: float) -> str | None:
    for room in data["rooms"]:
        if cv2.pointPolygonTest(np.array(room["polygon"], np.float32), (x, y), False) > 0:
            return str(room["name"])
    return None


def _gaps(data: dict[str, Any]) -> list[float]:
    """Widths of the gaps in wall lines that lead from one room into another (doors and openings)."""
    lines: dict[tuple[str, float], list[tuple[float, float]]] = defaultdict(list)
    for (ax, ay), (bx, by) in data["walls"]["segments"]:
        if ay == by:
            lines[("h", ay)].append((min(ax, bx), max(ax, bx)))
        else:
            lines[("v", ax)].append((min(ay, by), max(ay, by)))
    gaps = []
    for (axis, c), spans in lines.items():
        spans.sort()
        for a, b in zip(spans[:-1], spans[1:], strict=True):
            mid = (a[1] + b[0]) / 2
            sides = [(mid, c - 0.2), (mid, c + 0.2)] if axis == "h" else [(c - 0.2, mid), (c + 0.2, mid)]
            rooms = {_room_of(data, x, y) for x, y in sides}
            if b[0] - a[1] > 1e-6 and len(rooms) == 2 and None not in rooms:
                gaps.append(b[0] - a[1])
    return gaps


def test_same_seed_same_world_other_seed_other_world() -> None:
    """A floorplan depends on its seed alone."""
    assert floorplan_world(10, objects=False) == floorplan_world(10, objects=False)
    assert floorplan_world(10, objects=False) != floorplan_world(17, objects=False)


def test_every_kind_loads_with_rooms_and_objects(worlds: dict[str, tuple[dict[str, Any], World]]) -> None:
    """Each kind loads by name through the world checks, with typed rooms, objects and a clear start."""
    for kind, (data, world) in worlds.items():
        assert [r.name for r in world.rooms] == [r["name"] for r in data["rooms"]], kind
        assert len(world.rooms) >= 5 and len(world.objects) >= 10, kind
        assert {r.type for r in world.rooms} - {"corridor", "hall"}, kind
        assert world.clearance(world.start.x, world.start.y) > 0.4, kind


def test_every_room_of_every_kind_is_reachable(worlds: dict[str, tuple[dict[str, Any], World]]) -> None:
    """The planner reaches every room from the start, in every kind."""
    for kind, (_, world) in worlds.items():
        assert unreachable_rooms(world) == [], kind


@pytest.mark.parametrize("kind", ["corridor", "l_corridor", "t_corridor", "suites", "clutter"])
def test_corridor_doors_are_0_8_to_0_9_m(worlds: dict[str, tuple[dict[str, Any], World]], kind: str) -> None:
    """Every gap in a wall of the corridor kinds is a door 0.8-0.9 m wide, and there are many."""
    gaps = _gaps(worlds[kind][0])
    assert len(gaps) >= 8
    assert all(DOOR_MIN - 1e-6 <= g <= DOOR_MAX + 1e-6 for g in gaps), gaps


def test_suites_have_rooms_reached_only_through_a_room(
    worlds: dict[str, tuple[dict[str, Any], World]],
) -> None:
    """In the suites kind some room shares no wall with the corridor: it is reached through another room."""
    data, _ = worlds["suites"]
    corridor = next(r for r in data["rooms"] if r["type"] == "corridor")
    cy = sorted({y for _, y in corridor["polygon"]})
    inner = [r for r in data["rooms"] if r is not corridor
             and not {y for _, y in r["polygon"]} & set(cy)]
    assert inner


def test_clutter_stands_beside_doors(worlds: dict[str, tuple[dict[str, Any], World]]) -> None:
    """The clutter kind puts objects within a metre of its doors, and every room stays reachable."""
    data, world = worlds["clutter"]
    beside = [o for o in data["objects"] if "_door_" in o["id"]]
    assert len(beside) >= 4
    assert unreachable_rooms(world) == []


def test_open_plan_has_partial_partitions(worlds: dict[str, tuple[dict[str, Any], World]]) -> None:
    """The open plan's zones meet through openings wider than a door."""
    assert max(_gaps(worlds["open_plan"][0])) > 1.5


def test_warehouse_is_large_and_cheap_to_load(worlds: dict[str, tuple[dict[str, Any], World]]) -> None:
    """The warehouse is a floor of 20-30 x 30-50 m with shelving, drawn in few segments, loading in < 2 s."""
    data, world = worlds["warehouse"]
    xmin, ymin, xmax, ymax = world.bounds()
    assert 20 <= xmax - xmin <= 31 and 30 <= ymax - ymin <= 51
    assert len(data["walls"]["polygons"]) >= 6
    assert len(world.wall_segments) < 200
    began = time.process_time()  # CPU time, not wall time on a loaded machine
    build(data)
    assert time.process_time() - began < 2.0


def test_floorplan_name_loads_the_seeds_world(worlds: dict[str, tuple[dict[str, Any], World]]) -> None:
    """`floorplan:<seed>` is a world name load_world knows: the same world floorplan_world draws."""
    world = load_world("floorplan:3")
    data, _ = worlds[kind_of(3)]
    assert world.name == "floorplan_3"
    assert [r.name for r in world.rooms] == [r["name"] for r in data["rooms"]]
    assert [o.id for o in world.objects] == [o["id"] for o in data["objects"]]


def test_walkers_do_not_change_the_layout_or_objects(worlds: dict[str, tuple[dict[str, Any], World]]) -> None:
    """The same seed without people has the same walls, rooms and objects, and nobody walking."""
    with_people, _ = worlds[kind_of(3)]
    alone = floorplan_world(3, people=0)
    assert alone["people"] == [] and with_people["people"]
    assert {k: v for k, v in alone.items() if k != "people"} == {
        k: v for k, v in with_people.items() if k != "people"}


def test_bad_seed_is_a_world_file_error() -> None:
    """A floorplan name without a whole-number seed is refused with the expected form."""
    with pytest.raises(WorldFileError, match="floorplan:<seed>"):
        load_world("floorplan:twelve")
