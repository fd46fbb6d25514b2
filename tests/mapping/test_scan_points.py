"""The report's scan points on small grids: erosion, components, centroids ranked by size."""

from __future__ import annotations

import numpy as np
import pytest

from missiontree.mapping.scan_points import eroded_free, scan_points
from missiontree.types import OccupancyGrid, Pose2D


def two_rooms(door_cells: int = 4) -> OccupancyGrid:
    """A 4 x 2 m room and a 2 x 2 m room (0.1 m cells) joined by a door ``door_cells`` wide."""
    data = np.full((22, 63), 100, np.int8)
    data[1:21, 1:41] = 0          # big room: x 0.1-4.1
    data[1:21, 42:62] = 0         # small room: x 4.2-6.2, wall column at 41
    mid = 11
    data[mid - door_cells // 2: mid - door_cells // 2 + door_cells, 41] = 0
    return OccupancyGrid(0.0, 0.1, Pose2D(0.0, 0.0), data)


def test_erosion_cuts_rooms_apart_at_the_door_and_ranks_them_by_size() -> None:
    """With an erosion wider than half the door, each room gives one point; the larger room first."""
    points = scan_points(two_rooms(door_cells=4), erosion_m=0.3, min_area_m2=0.1)
    assert len(points) == 2
    big, small = points
    assert big.cells > small.cells
    assert big.x == pytest.approx(2.1, abs=0.06) and big.y == pytest.approx(1.1, abs=0.06)
    assert small.x == pytest.approx(5.2, abs=0.06) and small.y == pytest.approx(1.1, abs=0.06)
    assert big.area_m2 == pytest.approx(big.cells * 0.01)


def test_without_erosion_a_door_joins_the_rooms_into_one_region() -> None:
    """No erosion: the door connects both rooms, so there is one scan point."""
    assert len(scan_points(two_rooms(), erosion_m=0.0, min_area_m2=0.1)) == 1


def test_unknown_cells_are_not_free_space() -> None:
    """Only known-free cells count: an unknown grid has no scan point."""
    g = OccupancyGrid(0.0, 0.1, Pose2D(0.0, 0.0), np.full((20, 20), -1, np.int8))
    assert scan_points(g) == []
    assert not eroded_free(g, 0.2).any()


def test_small_regions_and_max_points_limit_the_list() -> None:
    """Regions under min_area_m2 give no point; max_points keeps the largest."""
    g = two_rooms()
    assert len(scan_points(g, erosion_m=0.3, min_area_m2=3.0)) == 1
    assert len(scan_points(g, erosion_m=0.3, min_area_m2=0.1, max_points=1)) == 1


def test_centroid_outside_its_region_is_moved_into_it() -> None:
    """An L-shaped region's centroid lies in the corner it wraps around; the point is put on a free cell."""
    data = np.full((30, 30), 100, np.int8)
    data[1:8, 1:29] = 0     # bottom bar
    data[1:29, 1:8] = 0     # left bar
    g = OccupancyGrid(0.0, 0.1, Pose2D(0.0, 0.0), data)
    (p,) = scan_points(g, erosion_m=0.1, min_area_m2=0.1)
    r, c = g.world_to_cell(p.x, p.y)
    assert eroded_free(g, 0.1)[r, c]


def test_negative_erosion_is_refused() -> None:
    """A negative erosion radius raises ValueError."""
    with pytest.raises(ValueError, match="erosion_m"):
        scan_points(two_rooms(), erosion_m=-0.1)
