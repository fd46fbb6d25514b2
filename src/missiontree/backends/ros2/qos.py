"""The QoS profiles the ROS 2 backend and the simulator's bridge subscribe and publish with."""

from __future__ import annotations

from typing import TYPE_CHECKING

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

if TYPE_CHECKING:
    from missiontree.backends.ros2.profile import Ros2Profile

__all__ = ["latched_qos", "qos_named", "reliable_qos", "sensor_qos"]


def sensor_qos(depth: int) -> QoSProfile:
    """Best effort, volatile: matches both best-effort and reliable sensor publishers."""
    return QoSProfile(reliability=ReliabilityPolicy.BEST_EFFORT, durability=DurabilityPolicy.VOLATILE,
                      history=HistoryPolicy.KEEP_LAST, depth=depth)


def latched_qos(depth: int = 1) -> QoSProfile:
    """Reliable, transient local: /map, /tf_static, /amcl_pose and action status topics."""
    return QoSProfile(reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL,
                      history=HistoryPolicy.KEEP_LAST, depth=depth)


def reliable_qos(depth: int = 10) -> QoSProfile:
    """Reliable, volatile: commands and /tf."""
    return QoSProfile(reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE,
                      history=HistoryPolicy.KEEP_LAST, depth=depth)


def qos_named(name: str, profile: Ros2Profile) -> QoSProfile:
    """The QoS of a plugin sensor's :class:`~missiontree.robot.sensors.Ros2Source` (``sensor``...)."""
    if name == "latched":
        return latched_qos()
    if name == "reliable":
        return reliable_qos()
    return sensor_qos(profile.sensor_qos_depth)
