"""The learned map's cells are re-read only inside the box a scan can change, and stay exact."""

from __future__ import annotations

import math

import numpy as np

from missiontree.backends.sim import create_robot
from missiontree.backends.sim.robot import _scan_box
from missiontree.mapping.grid import LogOddsGrid
from missiontree.types import LaserScan, Pose2D


def test_the_learned_map_matches_a_full_reread_after_every_scan_while_driving() -> None:
    """Driving and turning on an unknown map, the kept cells equal the grid's trinary after each step."""
    robot = create_robot({"world": "office", "seed": 3, "unknown_map": True})
    try:
        for step in range(40):
            robot.drive(0.3, 0.6 if step % 10 < 5 else -0.4)
            robot.spin_until(robot.now() + 0.1)
            robot.scan()
            assert np.array_equal(robot._known, robot._learned.trinary()), f"step {step}"  # type: ignore[union-attr]
    finally:
        robot.close()


def test_the_box_holds_every_beam_end_and_a_no_return_beam_at_full_range() -> None:
    """A short return and a beam with no return: the box reaches the latter's full range."""
    grid = LogOddsGrid(0.05, 40.0, 40.0)
    scan = LaserScan(stamp=0.0, angle_min=0.0, angle_increment=math.pi / 2, range_min=0.1, range_max=12.0,
                     ranges=np.array([2.0, math.inf, 1.0, 3.0], np.float32))
    x0, y0, x1, y1 = _scan_box(scan, Pose2D(1.0, 1.0, 0.0), grid)
    assert x1 >= 1.0 + 2.0 and x0 <= 1.0 - 1.0
    assert y1 >= 1.0 + 12.0 and y0 <= 1.0 - 3.0
    assert y1 - y0 < 16.0 + 0.5 and x1 - x0 < 3.0 + 0.5  # not the 24 m square of the whole range
