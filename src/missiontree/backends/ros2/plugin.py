"""Hooks of the ROS 2 backend: mirror a mission's events to the ROS world when it runs on ROS 2.

When a mission starts on a :class:`~missiontree.backends.ros2.robot.Ros2Robot`, its event sink is
wrapped in :class:`~missiontree.backends.ros2.publish.RosEvents`: alarms, confirmed objects and
scene graphs then also appear on ROS topics (RViz markers, /scene_graph, the alarms topic). On any
other backend nothing happens and rclpy is never imported.
"""

from __future__ import annotations

from typing import Any

from missiontree.plugins.hookspecs import hookimpl
from missiontree.robot.envelope import unwrap

ROBOT_MODULE = "missiontree.backends.ros2.robot"


@hookimpl
def missiontree_mission_started(context: Any, mission: Any) -> None:
    """Mirror the mission's events to ROS when its robot is a Ros2Robot."""
    robot = unwrap(context.robot)  # the backend's own robot inside a safety envelope
    if type(robot).__module__ != ROBOT_MODULE:
        return
    from missiontree.backends.ros2.publish import RosEvents

    if not isinstance(context.events, RosEvents):
        context.events = RosEvents(context.events, robot.world)
