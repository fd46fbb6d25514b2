"""LookAgain on a scripted robot: a stand at a good distance in sight of each doubtful place, a look."""

from __future__ import annotations

import math

import numpy as np
from patrol_doubles import Events, FakeRobot

from missiontree.behaviours.scene_look import LookAgain
from missiontree.engine.context import MissionContext
from missiontree.engine.leaf import Status
from missiontree.semantics.live import LiveScene
from missiontree.types import OccupancyGrid, Pose2D

RES = 0.05


class RoomRobot(FakeRobot):
    """A scripted robot in a free 6 x 4 m room walled round; goals succeed and put it there."""

    def occupancy(self) -> OccupancyGrid | None:  # type: ignore[override]
        data = np.zeros((80, 120), np.int8)
        data[0, :] = data[-1, :] = data[:, 0] = data[:, -1] = 100
        data[:, 60] = 100  # a wall across the room, a door at y 1.8-2.4
        data[36:48, 60] = 0
        return OccupancyGrid(self.time, RES, Pose2D(0.0, 0.0), data)

    def navigate_to(self, goal, tolerance=None):  # type: ignore[no-untyped-def, override]
        handle = super().navigate_to(goal, tolerance)
        self.set_pose(Pose2D(goal.x, goal.y, self.current.yaw))
        return handle


def test_the_robot_looks_again_from_a_stand_in_sight_of_each_doubtful_place() -> None:
    """Each doubtful place gets a goal 0.9-2.2 m away with a free line of sight, then a turn toward it."""
    robot = RoomRobot()
    robot.set_pose(Pose2D(1.0, 1.0, 0.0))
    scene = LiveScene()
    scene.doubtful = [("cup", 4.5, 3.2), ("laptop", 2.0, 3.5)]
    events = Events()
    leaf = LookAgain("look", LookAgain.Params())
    leaf.setup(context=MissionContext(robot=robot, events=events, scene=scene))
    turned = []
    for _ in range(600):
        leaf.tick_once()
        turned.append(robot.w)
        if leaf.status in (Status.SUCCESS, Status.FAILURE):
            break
        robot.advance(0.1)
    assert leaf.status is Status.SUCCESS
    assert "looked again at 2 places" in leaf.feedback_message
    assert len(robot.goals) == 2
    for goal, (_, x, y) in zip(robot.goals, [scene.doubtful[1], scene.doubtful[0]], strict=True):
        d = math.hypot(goal.goal.x - x, goal.goal.y - y)
        assert 0.9 <= d <= 2.2
        # the line of sight does not cross the wall at x = 3.0 except through the door
        if (goal.goal.x - 3.0) * (x - 3.0) < 0:
            t = (3.0 - goal.goal.x) / (x - goal.goal.x)
            assert 1.8 <= goal.goal.y + t * (y - goal.goal.y) <= 2.4
    assert any(w > 0 for w in turned) and any(w < 0 for w in turned)


def test_with_nothing_doubtful_the_leaf_ends_at_once() -> None:
    """With nothing doubtful the leaf ends at once, having sent no goal."""
    robot = RoomRobot()
    robot.set_pose(Pose2D(1.0, 1.0, 0.0))
    leaf = LookAgain("look", LookAgain.Params())
    leaf.setup(context=MissionContext(robot=robot, events=Events(), scene=LiveScene()))
    leaf.tick_once()
    assert leaf.status is Status.SUCCESS and not robot.goals
