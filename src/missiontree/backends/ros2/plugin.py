"""Hooks of the ROS 2 backend: mirror a mission's events to the ROS world when it runs on ROS 2.

When a mission starts on a :class:`~missiontree.backends.ros2.robot.Ros2Robot`, its event sink is
wrapped in :class:`~missiontree.backends.ros2.publish.RosEvents`: alarms, confirmed objects and
scene graphs then also appear on ROS topics (RViz markers, /scene_graph, the alarms topic). A fleet
over ROS 2 gets :class:`~missiontree.backends.ros2.publish.FleetRosEvents`: each robot's events on
that robot's topics (``/robot2/missiontree/alarms``). On any other backend nothing happens and rclpy
is never imported.
"""

from __future__ import annotations

from typing import Any

from missiontree.plugins.hookspecs import hookimpl
from missiontree.robot.envelope import unwrap

ROBOT_MODULE = "missiontree.backends.ros2.robot"


@hookimpl
def missiontree_mission_started(context: Any, mission: Any) -> None:
    """Mirror the mission's events to ROS when its robot is a Ros2Robot (in a fleet: every robot is)."""
    robot = unwrap(context.robot)  # the backend's own robot inside a safety envelope
    members = [unwrap(r) for r in getattr(robot, "robots", None) or []]  # a fleet's clock holds its robots
    if members and all(type(r).__module__ == ROBOT_MODULE for r in members):
        from missiontree.backends.ros2.publish import FleetRosEvents

        if not isinstance(context.events, FleetRosEvents):
            context.events = FleetRosEvents(context.events, {r.name: r.world for r in members})
        return
    if type(robot).__module__ != ROBOT_MODULE:
        return
    from missiontree.backends.ros2.publish import RosEvents

    if not isinstance(context.events, RosEvents):
        context.events = RosEvents(context.events, robot.world)
