"""The ROS 2 command channel: ``std_msgs/String`` messages on ``/command``, one command a message.

:class:`TopicCommands` subscribes on the robot's node (reliable, depth 10, so commands published
just before the subscription matched are not lost to a slow discovery) and queues each message's
text stamped on the robot clock; :meth:`Ros2Robot.commands` takes them. The channel never closes.
"""

from __future__ import annotations

from collections.abc import Callable

from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import String

from missiontree.robot.commands import Command, CommandQueue

#: The topic NAIS-style command front ends (speech transcription, a terminal) publish on.
COMMAND_TOPIC = "/command"


class TopicCommands:
    """Commands from a ``std_msgs/String`` topic.

    Args:
        node: The robot's node (its executor delivers the messages).
        clock: The robot clock that stamps each command.
        topic: The topic name.
    """

    def __init__(self, node: Node, clock: Callable[[], float], topic: str = COMMAND_TOPIC) -> None:
        self.topic = topic
        self._queue = CommandQueue(clock, source=topic)
        qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10, reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.VOLATILE)
        self._subscription = node.create_subscription(String, topic, self._on_message, qos)

    def _on_message(self, msg: String) -> None:
        self._queue.push(str(msg.data))

    def poll(self, now: float) -> list[Command]:
        """The commands received since the last poll."""
        return self._queue.poll(now)
