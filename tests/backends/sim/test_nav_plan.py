"""The navigator's planning on a learned map: gaps the body fits through, detours, ways out."""

from __future__ import annotations

import math

from missiontree.backends.sim import create_robot
from missiontree.types import Pose2D, Tolerance

GAP = """\
name: gap
robot: {profile: turtlebot4, start: {x: 1.5, y: 1.5, yaw: 0.0}}
walls:
  height: 2.5
  polygons:
    - [[0, 0], [6, 0], [6, 5], [0, 5]]
  segments:
    - [[3.0, 0], [3.0, 1.24]]
    - [[3.0, 1.76], [3.0, 5.0]]
"""


def test_a_gap_the_body_fits_through_is_passed_on_a_learned_map(write_world):
    """A 0.42 m gap (the body is 0.34 m, the padded footprint 0.54 m) is the only way to the goal.

    Old: the padded costmap closed it; "proved unreachable: no path" after 10 s. Now the tighter
    costmap's plan is taken where the padded one finds no way, and the robot passes untouched.
    """
    robot = create_robot({"world": str(write_world(GAP)), "unknown_map": True})
    handle = robot.navigate_to(Pose2D(4.5, 1.5, 0.0), Tolerance(0.3, 2 * math.pi))
    while not handle.status().done and robot.now() < 60.0:
        robot.spin_until(robot.now() + 0.1)
    result = handle.result()
    assert result is not None and result.succeeded, result
    assert robot._nav.planning.tight_plans >= 1 and robot.bumps == 0
    assert robot.truth.robot_pose().x > 4.0
