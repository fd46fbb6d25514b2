"""The dense costmap view and planning helpers the world checks use."""

from __future__ import annotations

import numpy as np

from missiontree.backends.sim.nav_costmap import Costmap, path_length, plan
from missiontree.backends.sim.schema import NavigationSpec
from missiontree.mapping.planner import LETHAL
from missiontree.types import OccupancyGrid, Pose2D


def _room() -> OccupancyGrid:
    data = np.zeros((40, 40), np.int8)
    data[0, :] = data[-1, :] = data[:, 0] = data[:, -1] = 100
    data[:30, 20] = 100  # a wall with a gap at the top
    return OccupancyGrid(data=data, resolution=0.1, origin=Pose2D(0.0, 0.0, 0.0), stamp=0.0)


def test_a_plan_goes_round_the_wall_and_outside_the_map_is_lethal() -> None:
    costmap = Costmap(_room(), 0.2, NavigationSpec())
    path = plan(costmap, costmap.cost, Pose2D(1.0, 1.0, 0.0), Pose2D(3.0, 1.0, 0.0))
    assert path is not None and path_length(path) > 2.0 + 2 * 1.5  # up past the wall's end and down
    assert costmap.cell_cost(costmap.cost, -1.0, 1.0) == LETHAL
    assert path_length(np.zeros((1, 2))) == 0.0


def test_a_goal_in_the_inscribed_zone_moves_to_the_nearest_free_point_within_reach() -> None:
    """A goal 0.1 m from a wall (robot radius 0.2) becomes the nearest free point; out of reach, none."""
    from missiontree.backends.sim.nav_costmap import free_goal_within
    from missiontree.mapping import planner

    costmap = planner.Costmap(_room(), 0.2, 0.45, 3.0, allow_unknown=True)
    goal = Pose2D(1.95, 1.5, 0.5)                      # the wall at x 2.0 .. 2.1
    moved = free_goal_within(costmap, goal, 0.25)
    assert moved is not None and moved.yaw == 0.5
    assert costmap.cost_at(moved.x, moved.y) < planner.INSCRIBED
    assert 0.0 < goal.distance_to(moved) <= 0.25 and moved.x < goal.x
    assert free_goal_within(costmap, goal, 0.05) is None
    free = Pose2D(1.0, 1.0, 0.0)
    assert free_goal_within(costmap, free, 0.25) is free
