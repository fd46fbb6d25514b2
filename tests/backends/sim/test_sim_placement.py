"""Placement: objects added to any world (drawn walls or a real map) without blocking the robot."""

from __future__ import annotations

import itertools
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest

from missiontree.backends.sim.generator import FURNITURE, generate_world
from missiontree.backends.sim.placement import (
    EXTRA_FURNITURE,
    SEGMENTED_TYPES,
    keep_fitting,
    map_world,
    place_objects,
    small_kinds,
    unreachable_rooms,
)
from missiontree.backends.sim.placer import box, build
from missiontree.backends.sim.world import World
from missiontree.paths import REPO_ROOT

MAZE = REPO_ROOT / "config" / "worlds" / "maps" / "maze.yaml"
TWO_ROOMS: dict[str, Any] = {
    "name": "two_rooms",
    "robot": {"profile": "turtlebot4", "start": {"x": 1.5, "y": 1.5}},
    "walls": {
        "segments": [
            [[0, 0], [8, 0]],
            [[8, 0], [8, 4]],
            [[8, 4], [0, 4]],
            [[0, 4], [0, 0]],
            [[4, 0], [4, 1.575]],
            [[4, 2.425], [4, 4]],
        ]
    },  # a 0.85 m door at y 2
    "rooms": [
        {"name": "west", "type": "office", "polygon": [[0, 0], [4, 0], [4, 4], [0, 4]]},
        {"name": "east", "type": "kitchen", "polygon": [[4, 0], [8, 0], [8, 4], [4, 4]]},
    ],
}


@pytest.fixture(scope="module")
def maze_world() -> tuple[dict[str, Any], World]:
    """TurtleBot 4's maze map with a seeded start, segmented rooms and placed objects."""
    data = map_world(MAZE, 3, small=12)
    return data, build(data)


def _chair(x: float, y: float, name: str) -> dict[str, Any]:
    return {"id": name, "label": "chair", "color": "black", "size": [0.5, 0.5, 1.0], "pose": {"x": x, "y": y}}


def _overlap(a: Any, b: Any) -> float:
    area, _ = cv2.intersectConvexConvex(a.footprint().astype(np.float32), b.footprint().astype(np.float32))
    return float(area)


def _assert_clear(world: World) -> None:
    """No object covers a wall cell (shrunk by one cell) and no two objects on one level overlap."""
    grid = world.grid
    for obj in world.objects:
        mask = np.zeros(grid.data.shape, np.uint8)
        pts = ((obj.footprint() - [grid.origin.x, grid.origin.y]) / grid.resolution * 16).astype(np.int32)
        cv2.fillPoly(mask, [pts], 1, cv2.LINE_8, shift=4)
        mask = cv2.erode(mask, np.ones((3, 3), np.uint8))
        assert not (mask.astype(bool) & world.walls_grid).any(), obj.id
        assert not (mask.astype(bool) & (grid.data < 0)).any(), obj.id
    for a, b in itertools.combinations(world.objects, 2):
        if a.elevation == b.elevation:
            assert _overlap(a, b) < 1e-4, (a.id, b.id)


def test_map_world_is_seeded_with_typed_rooms_and_objects(maze_world: tuple[dict[str, Any], World]) -> None:
    """A real map gets rooms from segmentation, each typed, and objects in them."""
    data, world = maze_world
    assert len(world.rooms) >= 3
    assert {r.type for r in world.rooms} <= set(SEGMENTED_TYPES)
    assert len([o for o in world.objects if o.label in small_kinds()]) >= 12
    assert Path(data["map"]["yaml"]).is_absolute()


def test_objects_on_a_real_map_clear_walls_unknown_and_each_other(
    maze_world: tuple[dict[str, Any], World],
) -> None:
    """No placed object overlaps a wall, unknown space or another object on its level."""
    _assert_clear(maze_world[1])


def test_every_room_of_a_real_map_stays_reachable(maze_world: tuple[dict[str, Any], World]) -> None:
    """After placement the planner still reaches every room of the map."""
    assert unreachable_rooms(maze_world[1]) == []


def test_same_seed_same_objects_other_seed_other_objects() -> None:
    """Placement depends on the world and the seed alone."""
    assert place_objects(TWO_ROOMS, 7, small=6) == place_objects(TWO_ROOMS, 7, small=6)
    assert place_objects(TWO_ROOMS, 7, small=6) != place_objects(TWO_ROOMS, 8, small=6)


def test_placement_on_a_generated_world_keeps_it_valid_and_connected() -> None:
    """Placing many more objects into a generated apartment keeps it loadable and every room reachable."""
    data = generate_world(4, people=0)
    placed = place_objects(data, 4, small=30)
    world = build(placed)
    assert len(world.objects) > len(data["objects"]) + 20
    assert unreachable_rooms(world) == []
    _assert_clear(world)


def test_objects_stand_on_furniture_against_walls_and_in_corners() -> None:
    """Small objects are placed on low furniture, against walls and in corners, not only on open floor."""
    placed = place_objects(generate_world(5, people=0), 5, small=40)
    text = " ".join(o.get("description", "") for o in placed["objects"])
    assert "against a wall" in text and "in a corner" in text
    assert any(o.get("elevation", 0) > 0.3 for o in placed["objects"])
    assert all(o["size"][2] <= 0.5 for o in placed["objects"] if o.get("elevation", 0) > 0)


def test_small_objects_come_in_their_class_colours() -> None:
    """Random and decoy colours stay plausible for the class: laptops only silver, black, grey, white."""
    placed = place_objects(generate_world(6, people=0), 6, small=40)
    laptops = {o["color"] for o in placed["objects"] if o["label"] == "laptop"}
    assert laptops and laptops <= {"silver", "black", "grey", "white"}


def test_decoys_share_the_class_or_the_colour() -> None:
    """A decoy of the same class in another colour and one of the same colour of another class exist."""
    placed = place_objects(TWO_ROOMS, 1, furniture=False, small=4, decoys=True)
    small = [o for o in placed["objects"] if o["label"] in small_kinds()]
    pairs = list(itertools.combinations(small, 2))
    assert any(a["label"] == b["label"] and a["color"] != b["color"] for a, b in pairs)
    assert any(a["color"] == b["color"] and a["label"] != b["label"] for a, b in pairs)


def test_an_object_that_would_block_the_door_is_not_kept() -> None:
    """A chair in the only door is dropped; one in the open room is kept."""
    kept = keep_fitting(TWO_ROOMS, [_chair(4.2, 2.0, "in_door"), _chair(6.0, 3.0, "in_room")])
    assert [o["id"] for o in kept["objects"]] == ["in_room"]


def test_furniture_uses_the_generator_classes() -> None:
    """Every furniture label placed is one of the apartment generator's (the detector knows only those)."""
    placed = place_objects(TWO_ROOMS, 2, small=0, decoys=False)
    generator = {f[0] for items in FURNITURE.values() for f in items}
    assert {f[0] for items in EXTRA_FURNITURE.values() for f in items} <= generator
    assert placed["objects"]
    assert {o["label"] for o in placed["objects"]} <= generator | set(small_kinds())


def test_a_shipped_map_loads_by_name_and_seed() -> None:
    """`map:<name>:<seed>` builds a shipped map with a start, rooms and objects; a wrong name is refused."""
    from missiontree.backends.sim import load_world
    from missiontree.errors import WorldFileError

    world = load_world("map:tb3_sandbox:1")
    assert world.name == "map_tb3_sandbox_1" and world.rooms and world.objects
    with pytest.raises(WorldFileError, match="tb3_sandbox"):
        load_world("map:no_such_map:1")


def test_a_turned_chair_whose_corner_reaches_into_a_wall_cell_is_not_kept(tmp_path: Path) -> None:
    """On a 10 cm map a chair turned 18 degrees with a corner 7 cm into a lone occupied cell is dropped.

    (The corner of such a chair was missed by the outline's raster on MRPT's Malaga campus map.)
    """
    image = np.full((60, 90), 254, np.uint8)  # 9 x 6 m, 10 cm cells
    image[:2, :] = image[-2:, :] = 0
    image[:, :2] = image[:, -2:] = 0
    image[60 - 1 - 30, 50] = 0  # one occupied cell: x 5.0-5.1, y 3.0-3.1
    cv2.imwrite(str(tmp_path / "coarse.pgm"), image)
    (tmp_path / "coarse.yaml").write_text(
        "image: coarse.pgm\nresolution: 0.1\norigin: [0, 0, 0]\nnegate: 0\noccupied_thresh: 0.65\n"
        "free_thresh: 0.196\n"
    )
    data = {
        "name": "coarse",
        "robot": {"profile": "turtlebot4", "start": {"x": 2.0, "y": 2.0}},
        "map": {"yaml": str(tmp_path / "coarse.yaml")},
    }
    turned = _chair(4.75, 3.25, "turned")
    turned["pose"]["yaw"] = 0.3218
    kept = keep_fitting(data, [turned, _chair(7.0, 4.0, "free")])
    assert [o["id"] for o in kept["objects"]] == ["free"]
    build(kept)  # the loader checks every object against the map's walls


def test_a_footprint_drawn_in_its_window_covers_the_cells_of_the_whole_map_mask() -> None:
    """footprint_window's mask, put back in its window, is footprint_mask's (outlines off the edge too)."""
    from missiontree.backends.sim.placer import footprint_mask, footprint_window

    world = build(TWO_ROOMS)
    grid, shape = world.grid, world.grid.data.shape
    rng = np.random.default_rng(5)
    for _ in range(200):
        x, y = rng.uniform(-1.0, 9.0), rng.uniform(-1.0, 5.0)
        poly = box(x, y, rng.uniform(-3, 3), rng.uniform(0.05, 3.0), rng.uniform(0.05, 3.0))
        mask, window = footprint_window(shape, grid, poly)
        whole = np.zeros(shape, bool)
        whole[window] = mask
        assert np.array_equal(whole, footprint_mask(shape, grid, poly)), (x, y)


def test_an_outline_traced_in_a_window_is_the_outline_on_the_whole_map() -> None:
    """A room's outline from its bounding box with the margin is the one traced on a map-sized mask."""
    from missiontree.backends.sim.map_rooms import _MARGIN, _outline

    grid = build(TWO_ROOMS).grid
    mask = np.zeros(grid.data.shape, bool)
    mask[10:50, 12:40] = True
    mask[30:45, 40:70] = True
    mask[20, 5] = True
    rows, cols = np.nonzero(mask)
    r0, c0 = max(rows.min() - _MARGIN, 0), max(cols.min() - _MARGIN, 0)
    window = mask[r0 : rows.max() + 1 + _MARGIN, c0 : cols.max() + 1 + _MARGIN]
    assert _outline(window, grid, (r0, c0)) == _outline(mask, grid)


def test_an_obstacle_whose_window_splits_the_reach_is_judged_as_on_the_whole_map(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The grown windows decide chairs in, beside and near the door as the whole map's labelling does."""
    from missiontree.backends.sim import placer as placer_module

    chairs = [_chair(x, y, f"c{i}") for i, (x, y) in enumerate(
        [(4.2, 2.0), (3.7, 2.0), (4.5, 1.2), (4.5, 2.8), (3.6, 0.6), (4.4, 3.4), (6.0, 3.0), (2.0, 2.0)])]
    # by the dividing wall, 1 m from the door: its own window holds both rooms' reach, unjoined
    chairs.insert(0, _chair(3.65, 1.0, "by_wall"))
    kept = keep_fitting(TWO_ROOMS, chairs)
    assert "by_wall" in [o["id"] for o in kept["objects"]]
    monkeypatch.setattr(placer_module, "_REACH_WINDOWS", (0,))
    assert keep_fitting(TWO_ROOMS, chairs) == kept


def test_a_map_world_is_built_once_and_handed_out_as_copies() -> None:
    """The same map and arguments give the document again without a build; a caller's edits stay its own."""
    from missiontree.backends.sim import placement as placement_module

    first = map_world(MAZE, 11)
    first["objects"].clear()
    built = placement_module._map_world
    try:
        placement_module._map_world = None  # type: ignore[assignment]  # a second build would fail
        second = map_world(MAZE, 11)
    finally:
        placement_module._map_world = built
    assert second["objects"] and second == map_world(MAZE, 11)
