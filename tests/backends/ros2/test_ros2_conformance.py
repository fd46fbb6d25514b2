"""The robot conformance suite: Ros2Robot over DDS against `missiontree sim-ros` in another process.

One sim-ros process serves the conformance world for the whole module; before each test the robot
stops and the simulator is reset through its control topic (as Gazebo's reset service), so every
test starts with the robot at the world's start, exactly as the in-process suite does.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable, Iterator
from typing import Any

import pytest

pytest.importorskip("rclpy", reason="ROS 2 extra not installed: pip install -e .[ros2]; setup-ros2.sh")
pytest.importorskip("nav2_msgs.action", reason="nav2_msgs not built: run scripts/setup-ros2.sh")
pytestmark = [pytest.mark.ros2, pytest.mark.slow]

from std_msgs.msg import String  # noqa: E402

from missiontree.backends.ros2.bridge import CONTROL_TOPIC, STATUS_TOPIC  # noqa: E402
from missiontree.backends.ros2.robot import latched_qos, reliable_qos  # noqa: E402
from missiontree.backends.ros2.testing import SpinningPeer  # noqa: E402
from missiontree.robot.conformance import RobotConformance  # noqa: E402


class SimControl(SpinningPeer):
    """Sends simulator controls to sim-ros and follows its status topic."""

    def __init__(self, domain: int) -> None:
        super().__init__(domain, "sim_control")
        self.status: dict[str, int] = {}
        self.publisher = self.node.create_publisher(String, CONTROL_TOPIC, reliable_qos())
        self.node.create_subscription(String, STATUS_TOPIC, self._on_status, latched_qos())
        self.start()

    def _on_status(self, msg: String) -> None:
        self.status = json.loads(msg.data)

    def send(self, command: str, wait_until: Callable) -> None:
        """Send a control and wait until sim-ros reports it applied."""
        wait_until(lambda: self.status and self.publisher.get_subscription_count() > 0, 30.0,
                   "sim-ros's control topic")
        done = self.status["controls"] + 1
        self.publisher.publish(String(data=command))
        wait_until(lambda: self.status["controls"] >= done, 10.0, f"sim-ros to apply {command!r}")



#: What sim-ros serves to this module: the conformance world, with the in-process suite's seed.
SIM_ROS_WORLD = "conformance"
SIM_ROS_SEED = 3


@pytest.fixture(scope="module")
def conformance_server(sim_ros: Any) -> Iterator[tuple[Any, SimControl]]:
    """The module's sim-ros process and a client of its simulator controls."""
    control = SimControl(sim_ros.domain_id)
    yield sim_ros, control
    control.close()


@pytest.fixture(scope="module")
def shared_robot(conformance_server: tuple[Any, SimControl]) -> Iterator[Any]:
    """One Ros2Robot for the module (re-creating it per test would cost a DDS discovery each time)."""
    from missiontree.backends.ros2.profile import load_profile
    from missiontree.backends.ros2.robot import Ros2Robot

    server, _ = conformance_server
    robot = Ros2Robot(load_profile("turtlebot4", {"domain_id": server.domain_id}), node_name="conformance",
                      install_signal_stop=False)
    yield robot
    robot.close()


class TestRos2Conformance(RobotConformance):
    @pytest.fixture
    def robot(self, shared_robot: Any, conformance_server: tuple[Any, SimControl],
              wait_until: Callable) -> Iterator[Any]:
        server, control = conformance_server
        shared_robot.stop()
        control.send("reset", wait_until)
        reset_at = shared_robot.now()

        def fresh() -> bool:
            pose, scan, frame = shared_robot.pose(), shared_robot.scan(), shared_robot.rgbd()
            return None not in (pose, scan, frame) and min(pose.stamp, scan.stamp, frame.stamp) >= reset_at

        wait_until(fresh, 20.0, f"fresh data after the reset; sim-ros said: {server.output()[-2000:]}")
        yield shared_robot
        shared_robot.stop()

    @pytest.fixture
    def silence(self, conformance_server: tuple[Any, SimControl],
                wait_until: Callable) -> Callable[[str], None]:
        _, control = conformance_server

        def silence(sensor: str) -> None:
            control.send(f"silence {sensor}", wait_until)
            time.sleep(0.05)

        return silence
