"""mapping.planner: Nav2-style costs tile by tile, A* and one-search path lengths, updates in place."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from missiontree.mapping import planner
from missiontree.mapping.planner import INSCRIBED, LETHAL, NO_INFORMATION, TILE, Costmap, path_lengths, plan
from missiontree.types import OccupancyGrid, Pose2D

RES = 0.05


def grid_of(data: np.ndarray, res: float = RES) -> OccupancyGrid:
    return OccupancyGrid(0.0, res, Pose2D(0.0, 0.0), data)


def two_rooms(door: bool = True) -> np.ndarray:
    """10 x 6 m: outer walls, a wall at x = 5 m with a 1 m door at y = 4.5..5.5 m (when ``door``)."""
    data = np.zeros((120, 200), np.int8)
    data[0, :], data[-1, :], data[:, 0], data[:, -1] = 100, 100, 100, 100
    data[:, 100] = 100
    if door:
        data[90:110, 100] = 0
    return data


def whole_grid_costs(grid: OccupancyGrid, radius: float, inflation: float, scaling: float) -> np.ndarray:
    """The textbook whole-grid inflation (what the tiles must reproduce)."""
    lethal = grid.data >= 50
    dist = cv2.distanceTransform((~lethal).astype(np.uint8), cv2.DIST_L2, 5) * grid.resolution
    cost = np.zeros(lethal.shape, np.uint8)
    band = (dist <= inflation) & (dist >= radius)
    cost[band] = (252.0 * np.exp(-scaling * (dist[band] - radius))).astype(np.uint8)
    cost[dist < radius] = INSCRIBED
    cost[lethal] = LETHAL
    return cost


def test_tiled_costs_equal_the_whole_grid_inflation() -> None:
    """Tiles computed one by one give the same costs as inflating the whole map at once."""
    rng = np.random.default_rng(3)
    data = np.zeros((150, 230), np.int8)   # not a multiple of the tile size
    for _ in range(40):
        r, c = rng.integers(0, 150), rng.integers(0, 230)
        data[r:r + rng.integers(1, 8), c:c + rng.integers(1, 8)] = 100
    grid = grid_of(data)
    costmap = Costmap(grid, 0.17, 0.45, 3.0)
    assert np.array_equal(costmap.dense(), whole_grid_costs(grid, 0.17, 0.45, 3.0))


@pytest.mark.parametrize("accelerate", [True, False])
def test_path_goes_through_the_door_and_has_its_length(accelerate: bool) -> None:
    """From the left room to the right one the path passes the door; its length is the polyline's."""
    costmap = Costmap(grid_of(two_rooms()), 0.17, accelerate=accelerate)
    path = costmap.plan((2.0, 1.0), (8.0, 1.0))
    assert path is not None
    near_wall = path.points[np.abs(path.points[:, 0] - 5.0) < 0.1]
    assert len(near_wall) and np.all((near_wall[:, 1] > 4.5) & (near_wall[:, 1] < 5.5))
    assert tuple(path.points[0]) == (2.0, 1.0) and tuple(path.points[-1]) == (8.0, 1.0)
    assert path.length == pytest.approx(float(np.hypot(*np.diff(path.points, axis=0).T).sum()))
    # near the straight-line length through the door (it keeps off the door posts, 8 directions)
    best = math.dist((2, 1), (5, 5)) + math.dist((5, 5), (8, 1))
    assert best - 0.05 < path.length < best * 1.15


def test_no_door_no_path_and_blocked_goals_are_refused() -> None:
    """A sealed wall gives no path; goals inside walls, their inscribed zone or off the map give None."""
    costmap = Costmap(grid_of(two_rooms(door=False)), 0.17)
    assert costmap.plan((2.0, 1.0), (8.0, 1.0)) is None
    assert costmap.plan((2.0, 1.0), (5.0, 3.0)) is None     # in the wall
    assert costmap.plan((2.0, 1.0), (4.9, 3.0)) is None     # 0.1 m from it: inscribed
    assert costmap.plan((2.0, 1.0), (20.0, 3.0)) is None    # off the map


def test_unknown_cells_are_traversable_only_when_allowed() -> None:
    """With a learned map, unknown space is planned through (allow_unknown) or not."""
    data = two_rooms(door=False)
    data[:, 100] = -1   # the wall has not been seen: unknown
    data[:, 150:] = -1
    open_ = Costmap(grid_of(data), 0.17, allow_unknown=True)
    assert open_.plan((2.0, 1.0), (8.0, 1.0)) is not None
    closed = Costmap(grid_of(data), 0.17, allow_unknown=False)
    assert closed.plan((2.0, 1.0), (8.0, 1.0)) is None
    assert closed.cost_at(8.0, 1.0) == NO_INFORMATION


def test_update_recomputes_only_near_the_change_and_plans_see_it() -> None:
    """Closing the door in place, then update(region): the next plan finds no way; tiles far away stay."""
    data = two_rooms()
    grid = grid_of(data)
    costmap = Costmap(grid, 0.17)
    assert costmap.plan((2.0, 1.0), (8.0, 1.0)) is not None
    computed = costmap.tiles_computed
    data[90:110, 100] = 100
    costmap.update(grid, (90, 110, 100, 101))
    assert costmap.plan((2.0, 1.0), (8.0, 1.0)) is None
    # the door lies in one or two tiles' reach: the rest were kept
    assert costmap.tiles_computed - computed <= 4
    assert costmap.blocked_along(np.array([[5.0, 5.0]]))


def test_extra_points_block_a_corridor_for_a_replan_only() -> None:
    """with_points makes a person lethal in a copy; the kept costmap is unchanged."""
    costmap = Costmap(grid_of(two_rooms()), 0.17)
    person = np.array([[5.0 + 0.05 * math.cos(a), 5.0 + 0.45 * math.sin(a)] for a in np.linspace(0, 6.2, 24)])
    assert costmap.with_points(person, radius=0.3).plan((2.0, 1.0), (8.0, 1.0)) is None
    assert costmap.plan((2.0, 1.0), (8.0, 1.0)) is not None


def test_path_lengths_is_one_search_for_many_goals() -> None:
    """Lengths match single plans (Dijkstra is exact, A* weighted); unreachable and bad goals are None."""
    grid = grid_of(two_rooms())
    goals = [(8.0, 1.0), (3.0, 5.0), (9.0, 5.0), (5.0, 3.0), (30.0, 0.0)]
    lengths = path_lengths(grid, (2.0, 1.0), goals)
    assert lengths[3] is None and lengths[4] is None
    for goal, length in zip(goals[:3], lengths[:3], strict=True):
        single = plan(grid, (2.0, 1.0), goal)
        assert single is not None and length is not None
        assert length == pytest.approx(single.length, rel=0.05)
    sealed = path_lengths(grid_of(two_rooms(door=False)), (2.0, 1.0), [(8.0, 1.0), (3.0, 3.0)])
    assert sealed[0] is None and sealed[1] == pytest.approx(math.dist((2, 1), (3, 3)), rel=0.1)


def test_start_inside_the_inscribed_zone_may_leave_it() -> None:
    """A robot standing too close to a wall (drift) still gets a path out."""
    costmap = Costmap(grid_of(two_rooms()), 0.17)
    assert costmap.cost_at(4.9, 2.0) == INSCRIBED
    assert costmap.plan((4.9, 2.0), (2.0, 2.0)) is not None


def test_a_plan_touches_tiles_along_its_way_not_the_whole_map() -> None:
    """On a 60 x 60 m map at 3 cm (4 M cells) a 3 m plan computes a handful of cost tiles."""
    data = np.zeros((2000, 2000), np.int8)
    data[1000:1040, 900:1100] = 100
    costmap = Costmap(grid_of(data, 0.03), 0.17)
    path = costmap.plan((29.0, 29.0), (31.0, 31.5))
    assert path is not None
    total = costmap.ntr * costmap.ntc
    assert costmap.tiles_computed < 0.02 * total
    assert path.expanded < 0.01 * data.size
    assert planner.TILE == TILE


def test_a_replan_overlay_reuses_tiles_and_equals_a_fresh_costmap() -> None:
    """with_points starts from the kept tiles, recomputes only near the points: the costs of a fresh one."""
    grid = grid_of(two_rooms())
    kept = Costmap(grid, 0.17)
    kept.plan((2.0, 1.0), (8.0, 1.0))
    person = np.array([[5.2, 5.0], [3.0, 1.2]])
    overlay = kept.with_points(person, radius=0.3)
    assert overlay.tiles_computed == 0 and (overlay.cost_slot >= 0).any()
    fresh = Costmap(grid, 0.17, extra_lethal=person, extra_radius=0.3)
    assert np.array_equal(overlay.dense(), fresh.dense())
    assert kept.cost_at(3.0, 1.2) < LETHAL   # the kept costmap is untouched


def test_update_changed_finds_the_change_itself_and_equals_a_fresh_costmap() -> None:
    """A new snapshot with the door closed and a wall gone: only tiles near them recompute, costs as new."""
    before = np.full((256, 512), -1, np.int8)   # 4 x 8 tiles, the two rooms in a corner
    before[:120, :200] = two_rooms()
    costmap = Costmap(grid_of(before), 0.2, allow_unknown=True)
    costmap.dense()
    computed = costmap.tiles_computed
    data = before.copy()
    data[90:110, 100] = 100      # the door closes
    data[0, 10:30] = -1          # a stretch of outer wall becomes unknown
    changed = grid_of(data)
    costmap.update_changed(changed)
    np.testing.assert_array_equal(costmap.dense(), Costmap(changed, 0.2, allow_unknown=True).dense())
    assert costmap.tiles_computed - computed == 9   # the changed tiles and their neighbours, of 32
    assert costmap.path_lengths((2.0, 1.0), [(8.0, 1.0)]) == [None]


@pytest.mark.parametrize("accelerate", [True, False])
def test_a_narrow_door_beside_the_goal_is_not_left_for_the_way_round(accelerate: bool) -> None:
    """Old: the coarse guide closed a 0.5 m door at its block scale and A* went round (13 m for 3 m).

    Now a guided path that is a detour is checked by an unguided search; the shorter is taken, and
    it is as long as the Dijkstra path (path_lengths) through the door.
    """
    data = two_rooms(door=False)
    data[12:22, 100] = 0            # a 0.5 m door at y = 0.6..1.1 m, across two blocks of the guide
    data[90:110, 100] = 0           # and the 1 m door far up the wall
    costmap = Costmap(grid_of(data), 0.17, accelerate=accelerate)
    path = costmap.plan((4.0, 0.85), (6.0, 0.85))
    shortest = costmap.path_lengths((4.0, 0.85), [(6.0, 0.85)])[0]
    assert path is not None and shortest is not None
    assert path.length < 2.5 and path.length == pytest.approx(shortest, abs=0.15)
