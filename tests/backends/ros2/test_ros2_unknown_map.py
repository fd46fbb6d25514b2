"""`missiontree sim-ros --unknown-map`: /map is the map the robot learns, read by a Ros2Robot over DDS."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

pytest.importorskip("rclpy", reason="ROS 2 extra not installed: pip install -e .[ros2]; setup-ros2.sh")
pytest.importorskip("nav2_msgs.action", reason="nav2_msgs not built: run scripts/setup-ros2.sh")
pytestmark = [pytest.mark.ros2, pytest.mark.slow]

from missiontree.robot.actions import ActionStatus  # noqa: E402
from missiontree.types import Pose2D, Tolerance  # noqa: E402

SIM_ROS_FLAGS = ["--unknown-map", "--rate", "3", "--sim-time"]


def _known(grid: Any) -> int:
    return int(np.count_nonzero(grid.data >= 0))


def test_map_topic_carries_the_learned_map_as_it_grows(sim_ros: Any, make_robot: Callable,
                                                       wait_until: Callable) -> None:
    """occupancy() reads /map: mostly unknown at first, more known cells after a drive, newer stamps."""
    robot = make_robot(sim_ros.domain_id, use_sim_time=True)
    wait_until(lambda: robot.pose() and robot.scan(), 20.0,
               f"sim-ros to publish; its output: {sim_ros.output()}")
    first = wait_until(robot.occupancy, 10.0, "the learned map on /map")
    assert first.resolution == pytest.approx(0.05)
    assert np.count_nonzero(first.data < 0) > 0.3 * first.data.size     # most of the office not seen yet
    assert first.data.max() == 100                                       # but the walls in view are
    handle = robot.navigate_to(Pose2D(8.5, 5.5, 0.0), Tolerance(0.3, 2 * math.pi))
    wait_until(lambda: handle.status().done, 90.0, "the goal through the door to end")
    assert handle.status() is ActionStatus.SUCCEEDED, handle.result()
    later = wait_until(lambda: (g := robot.occupancy()) is not None and g.stamp > first.stamp + 1.0 and g,
                       10.0, "a newer /map")
    assert _known(later) > _known(first) * 1.3, (_known(first), _known(later))
    office = later.data[later.world_to_cell(8.5, 5.5)]
    assert office == 0   # the office it drove into is now mapped free
