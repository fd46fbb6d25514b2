"""The ROS 2 command channel: std_msgs/String on /command arrives as stamped commands, over DDS."""

from __future__ import annotations

import time

import pytest
from conftest import next_domain_id, wait_until

pytest.importorskip("rclpy", reason="ROS 2 extra not installed: pip install -e .[ros2]; setup-ros2.sh")
pytest.importorskip("std_msgs.msg", reason="ROS 2 message packages not installed: pip install -e .[ros2]")

from missiontree.backends.ros2.commands import TopicCommands  # noqa: E402
from missiontree.backends.ros2.testing import SpinningPeer  # noqa: E402


class _Publisher(SpinningPeer):
    def __init__(self, domain: int) -> None:
        from std_msgs.msg import String

        super().__init__(domain, "command_publisher")
        self.msg_type = String
        self.pub = self.node.create_publisher(String, "/command", 10)
        self.start()

    def say(self, text: str) -> None:
        self.pub.publish(self.msg_type(data=text))


class _Listener(SpinningPeer):
    def __init__(self, domain: int) -> None:
        super().__init__(domain, "command_listener")
        self.commands = TopicCommands(self.node, time.monotonic)
        self.start()


def test_commands_published_on_the_command_topic_arrive_in_order_with_stamps() -> None:
    """Two strings published on /command come out of poll() as two commands, oldest first."""
    domain = next_domain_id()
    listener, publisher = _Listener(domain), _Publisher(domain)
    try:
        wait_until(lambda: publisher.pub.get_subscription_count() > 0, 10.0, "the subscription to match")
        publisher.say("I'm thirsty")
        publisher.say("  the laptop in front of the sofa\n")
        got: list = []
        wait_until(lambda: got.extend(listener.commands.poll(time.monotonic())) or len(got) >= 2, 10.0,
                   "two commands")
        assert [c.text for c in got] == ["I'm thirsty", "the laptop in front of the sofa"]
        assert got[0].stamp <= got[1].stamp and got[0].source == "/command"
    finally:
        publisher.close()
        listener.close()


def test_a_ros2_robot_hears_commands_on_its_command_topic(make_robot) -> None:  # noqa: ANN001 - fixture
    """Ros2Robot.commands() returns what another node published on /command; the topic never closes."""
    domain = next_domain_id()
    robot = make_robot(domain)
    publisher = _Publisher(domain)
    try:
        wait_until(lambda: publisher.pub.get_subscription_count() > 0, 10.0, "the robot's subscription")
        publisher.say("I am bored")
        got: list = []
        wait_until(lambda: got.extend(robot.commands()) or got, 10.0, "the command")
        assert [c.text for c in got] == ["I am bored"] and got[0].source == "/command"
        assert robot.commands_closed() is False
    finally:
        publisher.close()
