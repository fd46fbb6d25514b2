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


def _frame_robot() -> RoomRobot:
    from missiontree.types import CameraIntrinsics, RGBDFrame

    robot = RoomRobot()
    robot.set_pose(Pose2D(1.0, 1.0, 0.0))
    k = CameraIntrinsics(width=320, height=240, fx=228.5, fy=228.5, cx=159.5, cy=119.5)
    colour = np.zeros((240, 320, 3), np.uint8)
    depth = np.ones((240, 320), np.float32)
    robot.frame = RGBDFrame(0.0, colour, depth, k, Pose2D(1.0, 1.0, 0.0), 0.4)
    return robot


def test_with_surfaces_the_robot_looks_at_a_table_top_from_where_its_top_is_in_view() -> None:
    """A 0.75 m table gets a stand far enough that 0.3 m above its top is in the vertical field of view."""
    robot = _frame_robot()
    scene = LiveScene()
    scene.map.add("table", (4.5, 2.0, 0.375), 0.0, size=(1.2, 1.2, 0.75))
    scene.map.add("cup", (1.5, 3.0, 0.05), 0.0, size=(0.09, 0.09, 0.11))  # below the camera: no look
    leaf = LookAgain("look", LookAgain.Params(surfaces=True))
    leaf.setup(context=MissionContext(robot=robot, events=Events(), scene=scene))
    for _ in range(600):
        leaf.tick_once()
        if leaf.status in (Status.SUCCESS, Status.FAILURE):
            break
        robot.advance(0.1)
    assert leaf.status is Status.SUCCESS and len(robot.goals) == 1
    goal = robot.goals[0].goal
    d = math.hypot(goal.x - 4.5, goal.y - 2.0)
    need = (0.75 + 0.3 - 0.4) / (120.0 / 228.5) + 0.6  # rise over tan(half vfov), plus half the table
    assert need - 1e-6 <= d <= need + 1.5


def test_without_surfaces_a_table_gets_no_look() -> None:
    """Without ``surfaces`` the leaf looks only at doubtful places: a table in the graph gets none."""
    robot = _frame_robot()
    scene = LiveScene()
    scene.map.add("table", (4.5, 2.0, 0.375), 0.0, size=(1.2, 1.2, 0.75))
    leaf = LookAgain("look", LookAgain.Params())
    leaf.setup(context=MissionContext(robot=robot, events=Events(), scene=scene))
    leaf.tick_once()
    assert leaf.status is Status.SUCCESS and not robot.goals
