"""Room segmentation on shipped maps (doors and narrow passages as boundaries), polygons, stable ids."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from missiontree.backends.sim.world import load_world
from missiontree.errors import ConfigError
from missiontree.mapping.mapfile import read_map
from missiontree.paths import find_config
from missiontree.semantics.rooms import (
    RoomTracker,
    load_room_polygons,
    polygon_segmentation,
    segment_rooms,
)
from missiontree.types import OccupancyGrid


def true_rooms_of(world_name: str) -> tuple[list[str | None], list[str]]:
    """(true room of each segmented room's centroid, true room names) for a shipped world's map."""
    world = load_world(world_name)
    seg = segment_rooms(world.grid, inside=(world.start.x, world.start.y))
    found = [(world.room_at(*r.centroid).name if world.room_at(*r.centroid) else None) for r in seg.rooms]
    return sorted(found, key=str), sorted(r.name for r in world.rooms)


@pytest.mark.parametrize("world", ["office", "corridor", "generated:1", "generated:2", "generated:4"])
def test_segmented_rooms_pair_one_to_one_with_the_true_rooms(world: str) -> None:
    """Each room of the map is found once: the door between them is the boundary, furniture is not."""
    found, truth = true_rooms_of(world)
    assert found == truth


def test_the_small_office_map_splits_at_its_door() -> None:
    """The map_server map of two rooms joined by a 1 m door gives two rooms, west and east of x = 4."""
    grid = read_map(find_config("worlds", "map_example").parent / "maps" / "small_office.yaml")
    seg = segment_rooms(grid, inside=(2.0, 2.0))
    assert len(seg.rooms) == 2
    xs = sorted(r.centroid[0] for r in seg.rooms)
    assert xs[0] < 4.0 < xs[1]
    assert seg.room_at(2.0, 2.0) is not seg.room_at(6.0, 2.0)
    assert seg.room_at(2.0, 2.0) is not None


def test_a_learned_map_with_holes_in_its_walls_still_splits_at_the_door() -> None:
    """Gaps narrower than close_gaps in a wall (lidar grazing it) do not join the rooms either side."""
    world = load_world("office")
    data = np.array(world.grid.data)
    res = world.grid.resolution
    col = int((5.0 - world.grid.origin.x) / res)
    for y in (1.0, 6.0, 7.0):  # three 0.2 m holes in the kitchen | office wall
        row = int((y - world.grid.origin.y) / res)
        data[row : row + 4, col - 3 : col + 3] = 0
    grid = OccupancyGrid(0.0, res, world.grid.origin, data)
    seg = segment_rooms(grid, inside=(2.5, 4.0))
    assert len(seg.rooms) == 2


def test_free_space_outside_the_building_is_no_room() -> None:
    """The simulator's map is free outside the walls: that space is left out, not made a room."""
    world = load_world("office")
    seg = segment_rooms(world.grid, inside=(2.5, 4.0))
    assert seg.room_at(-0.3, -0.3, reach=0.1) is None
    assert sum(r.area for r in seg.rooms) < 12 * 8


def test_room_ids_stay_stable_while_the_map_grows() -> None:
    """A room keeps its id (and type) when the map is segmented again with more of it known."""
    world = load_world("office")
    full = world.grid
    partial = np.array(full.data)
    partial[:, int((8.0 - full.origin.x) / full.resolution) :] = -1  # the east part not yet seen
    tracker = RoomTracker()
    first = tracker.update(OccupancyGrid(0.0, full.resolution, full.origin, partial), inside=(2.5, 4.0))
    kitchen = first.room_at(2.5, 4.0)
    kitchen.type = "kitchen"
    second = tracker.update(full, inside=(2.5, 4.0))
    again = second.room_at(2.5, 4.0)
    assert again.id == kitchen.id and again.type == "kitchen"
    assert len({r.id for r in second.rooms}) == len(second.rooms) == 2


def test_room_polygons_from_a_file(tmp_path: Path) -> None:
    """A YAML list of {name, type, polygon} gives rooms; a malformed file is a clear error."""
    path = tmp_path / "rooms.yaml"
    path.write_text(
        "rooms:\n  - {name: lab, type: office, polygon: [[0, 0], [4, 0], [4, 3], [0, 3]]}\n"
        "  - {name: store, polygon: [[4, 0], [6, 0], [6, 3], [4, 3]]}\n"
    )
    rooms = load_room_polygons(path)
    assert [(r.name, r.type, r.area) for r in rooms] == [("lab", "office", 12.0), ("store", "unknown", 6.0)]
    world = load_world("office")
    seg = polygon_segmentation(world.grid, rooms)
    assert seg.room_at(1.0, 1.0).name == "lab"
    (tmp_path / "bad.yaml").write_text("rooms:\n  - {name: lab, polygon: [[0, 0], [1, 1]]}\n")
    with pytest.raises(ConfigError, match="at least 3 points"):
        load_room_polygons(tmp_path / "bad.yaml")
    with pytest.raises(ConfigError, match="cannot read"):
        load_room_polygons(tmp_path / "missing.yaml")


def test_a_room_from_a_file_has_its_middle_at_its_centre_of_mass(tmp_path: Path) -> None:
    """An L-shaped room's middle is its centre of mass, and extra corners on one wall do not move it."""
    path = tmp_path / "rooms.yaml"
    path.write_text(
        "- {name: ell, type: office, polygon: [[0, 0], [4, 0], [4, 1], [1, 1], [1, 4], [0, 4]]}\n"
        "- {name: box, polygon: [[0, 0], [1, 0], [2, 0], [3, 0], [4, 0], [4, 2], [0, 2]]}\n"
    )
    ell, box = load_room_polygons(path)
    assert ell.area == pytest.approx(7.0)
    assert ell.centroid == pytest.approx((9.5 / 7, 9.5 / 7))  # (4 * 2 + 3 * 0.5) / 7, the same in y
    assert box.area == pytest.approx(8.0)
    assert box.centroid == pytest.approx((2.0, 1.0))  # the mean of the corners would say y = 0.57
