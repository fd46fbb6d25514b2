"""Standoff geometry: where the robot may stand to look at an object, on hand-made maps."""

from __future__ import annotations

import math

import numpy as np

from missiontree.reasoning.standoff import (
    MAX_REACH,
    STANDOFF_REACH,
    object_extent,
    outside_known_map,
    prepare_space,
    standoff_cells,
    view_distance,
)
from missiontree.types import OccupancyGrid, Pose2D

RES = 0.05
RADIUS = 0.17


def _room(table: bool = True, wall_at: int | None = None) -> OccupancyGrid:
    """A 4 x 4 m free room with a 0.4 m table at (2, 2) and optionally a wall across row ``wall_at``."""
    data = np.zeros((80, 80), dtype=np.int8)
    data[0, :] = data[-1, :] = data[:, 0] = data[:, -1] = 100
    if table:
        data[36:44, 36:44] = 100
    if wall_at is not None:
        data[wall_at, :] = 100
    return OccupancyGrid(0.0, RES, Pose2D(0.0, 0.0), data)


def test_standoff_cells_are_free_near_the_object_and_beyond_its_edge():
    space = prepare_space(_room(), RADIUS)
    extent = object_extent(space, (2.0, 2.0))
    assert 0.15 <= extent <= 0.25  # the table's half side, measured from the map
    cells = standoff_cells(space, (2.0, 2.0), RADIUS)
    assert cells
    for row, col, penalty in cells:
        x, y = space.grid.cell_to_world(row, col)
        d = math.hypot(x - 2.0, y - 2.0)
        assert extent + RADIUS <= d + 1e-6 <= extent + RADIUS + STANDOFF_REACH + 0.3 + 1e-6
        assert space.clearance[row, col] >= RADIUS and penalty >= 0.0


def test_a_wall_between_removes_the_cells_behind_it():
    open_cells = standoff_cells(prepare_space(_room(table=False), RADIUS), (2.0, 2.0), RADIUS)
    walled = standoff_cells(prepare_space(_room(table=False, wall_at=34), RADIUS), (2.0, 2.0), RADIUS)
    assert any(r < 34 for r, _, _ in open_cells)
    assert walled and not any(r < 34 for r, _, _ in walled)


def test_view_distance_keeps_a_low_object_in_the_cameras_view():
    assert view_distance(None, 0.0) == 0.0
    near_floor = view_distance((0.3, math.tan(math.radians(20))), 0.0)
    on_table = view_distance((0.3, math.tan(math.radians(20))), 0.3)
    assert near_floor > on_table > 0.0
    space = prepare_space(_room(table=False), RADIUS)
    cells = standoff_cells(space, (2.0, 2.0), RADIUS, near_floor)
    places = [space.grid.cell_to_world(r, c) for r, c, _ in cells]
    distances = [math.hypot(x - 2.0, y - 2.0) for x, y in places]
    assert distances and min(distances) >= near_floor - RES


def test_outside_known_map_names_why():
    grid = _room()
    space = prepare_space(grid, RADIUS)
    assert outside_known_map(space, (2.0, 1.0)) == ""
    assert "not in" in outside_known_map(space, (9.0, 1.0))
    data = np.full((80, 80), -1, dtype=np.int8)
    data[:10, :10] = 0
    unknown = prepare_space(OccupancyGrid(0.0, RES, Pose2D(0.0, 0.0), data), RADIUS)
    assert "unexplored" in outside_known_map(unknown, (3.0, 3.0))


def _alcove() -> OccupancyGrid:
    """A 4 x 4 m room with a 0.05 m post at the back of a 0.4 m wide, 0.7 m deep alcove at (2, 0)."""
    data = np.zeros((80, 80), dtype=np.int8)
    data[0, :] = data[-1, :] = data[:, 0] = data[:, -1] = 100
    data[:14, 35] = data[:14, 44] = 100
    data[1:3, 40] = 100
    return OccupancyGrid(0.0, RES, Pose2D(0.0, 0.0), data)


def test_no_place_within_half_a_metre_searches_farther_rings():
    """An object at the back of a narrow alcove is looked at from its mouth, beyond the first 0.5 m."""
    space = prepare_space(_alcove(), RADIUS)
    cells = standoff_cells(space, (2.025, 0.1), RADIUS)
    assert cells
    extent = object_extent(space, (2.025, 0.1))
    places = [space.grid.cell_to_world(r, c) for r, c, _ in cells]
    distances = [math.hypot(x - 2.025, y - 0.1) for x, y in places]
    assert min(distances) > extent + RADIUS + STANDOFF_REACH  # none in the first band: it has no room
    assert max(distances) <= extent + RADIUS + MAX_REACH + 1e-6


def test_the_nearest_ring_with_a_place_wins():
    """With room close by, no cell of a farther ring is offered."""
    space = prepare_space(_room(), RADIUS)
    extent = object_extent(space, (2.0, 2.0))
    cells = standoff_cells(space, (2.0, 2.0), RADIUS)
    far = extent + RADIUS + STANDOFF_REACH
    assert all(math.hypot(*(np.subtract(space.grid.cell_to_world(r, c), (2.0, 2.0)))) <= far + 0.3 + 1e-6
               for r, c, _ in cells)


def _outline(middle_known: bool = False, unexplored_beyond: bool = False) -> OccupancyGrid:
    """A free room with a 0.5 m chair drawn as an outline round an unknown middle at (2, 2)."""
    data = np.zeros((80, 80), dtype=np.int8)
    data[0, :] = data[-1, :] = data[:, 0] = data[:, -1] = 100
    data[35:46, 35:46] = 100
    data[36:45, 36:45] = 0 if middle_known else -1
    if unexplored_beyond:   # the outline open on one side to unexplored space
        data[38:43, 45] = -1
        data[:, 46:79] = -1
    return OccupancyGrid(0.0, RES, Pose2D(0.0, 0.0), data)


def test_an_outline_round_an_unknown_middle_has_a_place_to_stand():
    """A chair the lidar drew as an outline round an unseen middle gets standoff cells across its outline."""
    space = prepare_space(_outline(), RADIUS)
    assert 0.2 <= object_extent(space, (2.0, 2.0)) <= 0.4
    assert standoff_cells(space, (2.0, 2.0), RADIUS)


def test_an_object_in_unexplored_space_gets_no_outline_footprint():
    """An object whose unknown cell runs on into unexplored space keeps no footprint and no place in sight."""
    space = prepare_space(_outline(unexplored_beyond=True), RADIUS)
    assert object_extent(space, (2.0, 2.0)) == 0.0
    assert not standoff_cells(space, (2.0, 2.0), RADIUS)
