"""Tests that room segmentation follows the known area, not the map's size."""

from __future__ import annotations

import numpy as np

from missiontree.backends.sim.world import load_world
from missiontree.semantics.rooms import RoomTracker, segment_rooms
from missiontree.types import OccupancyGrid, Pose2D


def _padded(grid: OccupancyGrid, pad: int) -> OccupancyGrid:
    """``grid`` in the middle of a map ``pad`` cells larger on every side, the rest unknown."""
    data = np.full((grid.data.shape[0] + 2 * pad, grid.data.shape[1] + 2 * pad), -1, np.int8)
    data[pad:-pad, pad:-pad] = grid.data
    origin = Pose2D(grid.origin.x - pad * grid.resolution, grid.origin.y - pad * grid.resolution)
    return OccupancyGrid(0.0, grid.resolution, origin, data)


def test_a_building_in_a_large_unknown_map_gives_the_same_rooms() -> None:
    """The office inside 400 cells of unknown map on each side is segmented as the office alone."""
    world = load_world("office")
    inside = (world.start.x, world.start.y)
    alone = segment_rooms(world.grid, inside=inside)
    padded = segment_rooms(_padded(world.grid, 400), inside=inside)
    assert np.array_equal(padded.labels[400:-400, 400:-400], alone.labels)
    assert not padded.labels[:400].any() and not padded.labels[:, -400:].any()
    assert [r.to_dict() for r in padded.rooms] == [r.to_dict() for r in alone.rooms]


def test_a_map_with_no_free_cell_has_no_room() -> None:
    """An all-unknown map gives no room (and a label image of its size)."""
    grid = OccupancyGrid(0.0, 0.05, Pose2D(0.0, 0.0), np.full((50, 60), -1, np.int8))
    seg = segment_rooms(grid)
    assert seg.rooms == [] and seg.labels.shape == (50, 60)


def test_the_tracker_keeps_ids_when_the_map_grows_around_the_building() -> None:
    """Room ids carry over from the office alone to the office inside a larger map (same overlap rule)."""
    world = load_world("office")
    inside = (world.start.x, world.start.y)
    tracker = RoomTracker()
    first = {r.id: r.centroid for r in tracker.update(world.grid, inside=inside).rooms}
    second = {r.id: r.centroid for r in tracker.update(_padded(world.grid, 50), inside=inside).rooms}
    assert first.keys() == second.keys()
    for room_id, (x, y) in first.items():
        assert np.allclose(second[room_id], (x, y))


def test_the_wave_in_a_corner_of_a_large_map_labels_as_on_the_small_map() -> None:
    """The wave works within its open cells' box: the same labels as on a map cropped to them."""
    from missiontree.semantics.room_watershed import wave

    small = np.zeros((6, 7), np.int32)
    small[2, 1] = 3
    small[4, 5] = 5
    open_small = small == 0
    open_small[0, :] = False
    large = np.zeros((60, 70), np.int32)
    large[40:46, 50:57] = small
    open_large = np.zeros((60, 70), bool)
    open_large[40:46, 50:57] = open_small
    wave(small, open_small)
    wave(large, open_large)
    assert np.array_equal(large[40:46, 50:57], small)
    assert not large[:40].any() and not large[:, :50].any()
