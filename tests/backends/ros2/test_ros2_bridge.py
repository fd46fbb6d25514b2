"""`missiontree sim-ros` in another process, driven by a Ros2Robot over DDS (office world, real time).

What the conformance suite (test_ros2_conformance.py) does not cover: the TurtleBot 4 specifics of
what is served, Nav2's error code reaching the client, and the /goal_pose fallback.
"""

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

ANY_HEADING = Tolerance(xy=0.25, yaw=2 * math.pi)


@pytest.fixture
def robot(sim_ros: Any, make_robot: Callable, wait_until: Callable) -> Any:
    """A Ros2Robot on the sim-ros process's domain, once it sees a pose and a scan."""
    r = make_robot(sim_ros.domain_id)
    wait_until(lambda: r.pose() and r.scan(), 20.0, f"sim-ros to publish; its output: {sim_ros.output()}")
    return r


def _drive_to(robot: Any, goal: Pose2D, wait_until: Callable, timeout: float = 30.0) -> Any:
    handle = robot.navigate_to(goal, ANY_HEADING)
    wait_until(lambda: handle.status().done, timeout, f"the goal {goal} to end")
    return handle


def test_sim_ros_serves_turtlebot4_sensors_tf_and_map(robot: Any, wait_until: Callable) -> None:
    """The served robot looks like a TurtleBot 4: 360-beam scan with the lidar mount from TF, RGB-D, map."""
    scan = robot.scan()
    assert len(scan.ranges) == 360 and scan.frame_id == "rplidar_link"
    assert scan.mount_yaw == pytest.approx(math.pi / 2)  # from /tf_static, index 0 looks right
    assert robot.now() - scan.stamp < 1.0
    frame = wait_until(robot.rgbd, 10.0, "an RGB-D frame")
    assert frame.color.shape == (240, 320, 3) and frame.depth.shape == (240, 320)
    assert np.nanmax(frame.depth) < 12.0 and np.isfinite(frame.depth).any()
    assert frame.camera_pose.distance_to(robot.pose().pose) == pytest.approx(0.06, abs=0.01)
    grid = wait_until(robot.occupancy, 10.0, "the map")
    assert grid.resolution == pytest.approx(0.05) and grid.data.max() == 100
    pose = robot.pose().pose
    assert 0.0 < pose.x < 12.0 and 0.0 < pose.y < 8.0


def test_unreachable_goal_aborts_with_the_servers_reason(robot: Any, wait_until: Callable) -> None:
    """A goal outside the map is aborted by the server, and its error message comes back as the reason."""
    handle = _drive_to(robot, Pose2D(40.0, 40.0, 0.0), wait_until)
    result = handle.result()
    assert result.status is ActionStatus.ABORTED
    assert result.reason and result.code != 0


def test_goal_pose_fallback_reaches_the_goal(sim_ros: Any, make_robot: Callable,
                                             wait_until: Callable) -> None:
    """Without the action (nav2_msgs absent), /goal_pose plus the status topic drives the goal to success."""
    robot = make_robot(sim_ros.domain_id, navigation={"interface": "topic"})
    wait_until(lambda: robot.pose() and robot.scan(), 20.0, "sim-ros to publish")
    assert robot.nav_interface == "topic"
    goal = Pose2D(2.8, 4.3, 0.0)
    handle = _drive_to(robot, goal, wait_until)
    assert handle.result().status is ActionStatus.SUCCEEDED, handle.result()
    assert robot.pose().pose.distance_to(goal) <= 0.3


def test_goal_pose_fallback_cancels_through_the_cancel_service(sim_ros: Any, make_robot: Callable,
                                                               wait_until: Callable) -> None:
    """Without the action, cancel() goes through the action's cancel service and the goal ends CANCELED."""
    robot = make_robot(sim_ros.domain_id, navigation={"interface": "topic"})
    wait_until(lambda: robot.pose() and robot.scan(), 20.0, "sim-ros to publish")
    handle = robot.navigate_to(Pose2D(4.3, 5.5, 0.0), ANY_HEADING)
    wait_until(lambda: handle.status() is ActionStatus.RUNNING, 10.0, "the goal to run")
    handle.cancel()
    wait_until(lambda: handle.status().done, 10.0, "the cancel to take effect")
    assert handle.result().status is ActionStatus.CANCELED, handle.result()
