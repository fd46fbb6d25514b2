"""The explored share, from the robot's own map."""

from __future__ import annotations

import numpy as np

from missiontree.semantics.coverage import explored_share
from missiontree.types import OccupancyGrid, Pose2D

RES = 0.1


def two_rooms(second_known: bool) -> OccupancyGrid:
    """Two 4 x 4 m rooms side by side, a 1 m door between them; the second room known or not."""
    data = np.full((42, 83), -1, np.int8)
    data[1:41, 1:41] = 0  # first room, free
    data[0, :42] = data[41, :42] = 100
    data[:, 0] = data[:, 41] = 100
    data[15:25, 41] = 0  # the door
    if second_known:
        data[1:41, 42:82] = 0
        data[0, 41:] = data[41, 41:] = 100
        data[:, 82] = 100
    return OccupancyGrid(0.0, RES, Pose2D(0.0, 0.0, 0.0), data)


def test_fully_known_map_is_explored() -> None:
    """A map with no frontier reads 1.0."""
    cov = explored_share(two_rooms(True), (2.0, 2.0))
    assert cov.share == 1.0
    assert cov.frontiers == 0


def test_unseen_room_behind_a_door_lowers_the_share() -> None:
    """Unknown beyond an open doorway counts as unexplored, within the known map's extent."""
    grid = two_rooms(False)
    grid.data[0, 41:] = grid.data[41, 41:] = 100  # the outer walls of the second room were seen
    grid.data[:, 82] = 100
    cov = explored_share(grid, (2.0, 2.0))
    assert cov.frontiers == 1
    assert 0.4 < cov.share < 0.6
    assert abs(cov.known_m2 - (16.0 + 1.0 * RES)) < 0.5


def test_unknown_behind_a_wall_is_not_open() -> None:
    """Unknown that touches no free cell (behind a known wall) is not counted."""
    grid = two_rooms(False)
    grid.data[15:25, 41] = 100  # the door closed: a wall
    grid.data[0, 41:] = grid.data[41, 41:] = 100
    grid.data[:, 82] = 100
    assert explored_share(grid, (2.0, 2.0)).share == 1.0


def test_unreachable_free_floor_is_not_known() -> None:
    """Free cells the robot cannot reach are not its explored floor."""
    grid = two_rooms(True)
    grid.data[15:25, 41] = 100  # no door: the second room is another component
    cov = explored_share(grid, (2.0, 2.0))
    assert abs(cov.known_m2 - 16.0) < 0.5


def test_small_unknown_speck_is_ignored() -> None:
    """An unknown speck inside a room (under furniture) is not unexplored space."""
    grid = two_rooms(True)
    grid.data[20:23, 20:23] = -1
    assert explored_share(grid, (2.0, 2.0)).share == 1.0
