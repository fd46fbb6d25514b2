"""`sim-ros --robots 2` over DDS: each robot under its own namespace, and one robot's server killed."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import pytest

pytest.importorskip("rclpy", reason="ROS 2 extra not installed: pip install -e .[ros2]; setup-ros2.sh")
pytest.importorskip("nav2_msgs.action", reason="nav2_msgs not built: run scripts/setup-ros2.sh")
pytestmark = pytest.mark.ros2

from std_msgs.msg import String  # noqa: E402

from missiontree.backends.ros2.robot import reliable_qos  # noqa: E402
from missiontree.robot.actions import INFRASTRUCTURE, ActionStatus  # noqa: E402
from missiontree.types import Pose2D  # noqa: E402

#: Wall seconds to wait for discovery and data on a loaded machine (a bound, not an expectation).
READY = 120.0


def _ready(robot: Any) -> bool:
    return not robot.missing()


def test_each_robot_is_served_under_its_namespace_and_a_kill_takes_only_its_server(
        start_sim_ros: Callable[..., Any], make_robot: Callable[..., Any], domain_id: int,
        wait_until: Callable[..., Any]) -> None:
    """/robot1 and /robot2 carry two robots' data and servers; 'kill' on /robot2 removes only its server."""
    start_sim_ros(domain_id, "--robots", "2", "--sim-time")
    one = make_robot(domain_id, namespace="/robot1", use_sim_time=True)
    two = make_robot(domain_id, namespace="/robot2", use_sim_time=True, navigation={"server_timeout": 3.0})
    wait_until(lambda: _ready(one) and _ready(two), READY, "both robots' pose, scan and action server")
    first, second = one.pose().pose, two.pose().pose
    assert first.distance_to(second) > 0.3  # two robots, each on its own /robotN/tf
    control = two.node.create_publisher(String, "missiontree/sim/control", reliable_qos())
    wait_until(lambda: control.get_subscription_count() > 0, READY, "/robot2's simulator control topic")
    control.publish(String(data="kill"))
    wait_until(lambda: two.missing() == ["NavigateToPose server on navigate_to_pose"], READY,
               "/robot2's NavigateToPose server to leave the graph")
    assert one.missing() == []
    seen = two.scan().stamp
    wait_until(lambda: two.scan().stamp > seen, READY, "/robot2's scans to go on after the kill")
    goal = two.navigate_to(Pose2D(second.x + 0.5, second.y, 0.0))
    wait_until(lambda: goal.status().done, READY, "the goal to the robot without a server to end")
    result = goal.result()
    assert (goal.status(), result.kind) == (ActionStatus.ABORTED, INFRASTRUCTURE), result
