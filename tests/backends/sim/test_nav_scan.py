"""The lidar's geometry for the simulated navigator's follower (ScanView)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from missiontree.backends.sim import create_robot
from missiontree.backends.sim.nav_scan import ScanView
from missiontree.mapping import planner
from missiontree.types import LaserScan, Pose2D


def _view() -> ScanView:
    robot = create_robot({"world": "conformance"})
    costmap = planner.Costmap(robot.world.grid, robot.profile.body.radius)
    return ScanView(costmap, robot.profile.navigation, robot.profile.body.radius)


def _scan(points: dict[int, float]) -> LaserScan:
    """360 beams, one a degree from straight ahead, no returns but ``{degree: range}``."""
    ranges = np.full(360, np.inf, np.float32)
    for degree, r in points.items():
        ranges[degree % 360] = r
    return LaserScan(0.0, 0.0, math.radians(1.0), 0.05, 12.0, ranges)


def test_a_point_straight_ahead_within_stopping_reach_is_in_the_way() -> None:
    """Driving straight, a return 0.3 m ahead is swept; one 0.3 m to the side at 90 degrees is not."""
    view = _view()
    hit = view.obstacle_ahead(_scan({0: 0.3}), 0.2)
    assert hit is not None and hit[0] == pytest.approx(0.3, abs=1e-6)
    assert view.obstacle_ahead(_scan({90: 0.3}), 0.2) is None


def test_the_room_behind_is_the_gap_to_the_nearest_point_in_the_footprints_path() -> None:
    """Reversing meets a point 0.5 m behind after 0.5 m less the footprint; with no scan it is unbounded."""
    view = _view()
    room = view.rear_room(_scan({180: 0.5}))
    assert room == pytest.approx(0.5 - view.radius - 0.03, abs=1e-6)
    assert view.rear_room(None) == math.inf


def test_world_points_are_the_returns_in_the_map_frame() -> None:
    """A return 1 m straight ahead of a robot at (2, 3) facing +y lies at (2, 4)."""
    points = ScanView.world_points(_scan({0: 1.0}), Pose2D(2.0, 3.0, math.pi / 2))
    assert points.shape == (1, 2)
    assert points[0] == pytest.approx([2.0, 4.0], abs=1e-6)
