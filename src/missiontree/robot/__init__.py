"""The abstract robot: what every backend provides (see :mod:`missiontree.robot.interface`)."""

from missiontree.robot.actions import ActionHandle, ActionResult, ActionStatus, NavFeedback
from missiontree.robot.interface import Robot

__all__ = ["ActionHandle", "ActionResult", "ActionStatus", "NavFeedback", "Robot"]
