"""`sim-ros --robots 2` over DDS: each robot under its own namespace, and one robot's server killed."""

from __future__ import annotations

import json
from collections.abc import Callable
from types import SimpleNamespace
from typing import Any

import pytest

pytest.importorskip("rclpy", reason="ROS 2 extra not installed: pip install -e .[ros2]; setup-ros2.sh")
pytest.importorskip("nav2_msgs.action", reason="nav2_msgs not built: run scripts/setup-ros2.sh")
pytestmark = pytest.mark.ros2

from std_msgs.msg import String  # noqa: E402

from missiontree.backends.ros2.plugin import missiontree_mission_started  # noqa: E402
from missiontree.backends.ros2.robot import reliable_qos  # noqa: E402
from missiontree.backends.ros2.testing import SpinningPeer  # noqa: E402
from missiontree.robot.actions import INFRASTRUCTURE, ActionStatus  # noqa: E402
from missiontree.session.fleet import Ros2FleetClock  # noqa: E402
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


class _Alarms(SpinningPeer):
    """Listens to /robot1/missiontree/alarms and /robot2/missiontree/alarms."""

    def __init__(self, domain: int) -> None:
        super().__init__(domain, "alarm_listener")
        self.got: dict[str, list[dict[str, Any]]] = {"robot1": [], "robot2": []}
        for name in self.got:
            self.node.create_subscription(String, f"/{name}/missiontree/alarms",
                                          lambda msg, n=name: self.got[n].append(json.loads(msg.data)),
                                          reliable_qos())
        self.start()


def test_a_ros2_fleets_alarms_go_to_the_raising_robots_namespace(
        make_robot: Callable[..., Any], domain_id: int, wait_until: Callable[..., Any]) -> None:
    """The start hook mirrors each robot's alarm on that robot's alarms topic only, and still records it."""
    one = make_robot(domain_id, namespace="/robot1", name="robot1")
    two = make_robot(domain_id, namespace="/robot2", name="robot2")
    listener = _Alarms(domain_id)
    try:
        wait_until(lambda: all(r.node.count_subscribers("missiontree/alarms") for r in (one, two)), READY,
                   "the listener on both robots' alarms topics")
        recorded: list[str] = []

        class Log:
            def emit(self, event: str, /, **fields: Any) -> None:
                recorded.append(f"{event}:{fields.get('robot')}")

        context = SimpleNamespace(robot=Ros2FleetClock([one, two]), events=Log())
        missiontree_mission_started(context=context, mission=None)
        context.events.emit("alarm", robot="robot2", alarm=7, x=1.0, y=2.0)
        context.events.emit("alarm", robot="robot1", alarm=3, x=0.0, y=0.0)
        wait_until(lambda: listener.got["robot1"] and listener.got["robot2"], READY, "both robots' alarms")
    finally:
        listener.close()
    assert [a["alarm"] for a in listener.got["robot2"]] == [7]
    assert [a["alarm"] for a in listener.got["robot1"]] == [3]
    assert recorded == ["alarm:robot2", "alarm:robot1"]
