"""What a run records for its viewer: runview.json from the mission hooks, poses.jsonl from run --view."""

from __future__ import annotations

import json
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from missiontree.runlog.record import (
    PoseTrail,
    missiontree_mission_finished,
    missiontree_mission_started,
    robot_map,
    robot_trajectory,
)
from missiontree.runlog.replay import read_pose_trail
from missiontree.types import OccupancyGrid, Pose2D, PoseStamped


class MaplessRobot:
    """A robot whose map is not there yet (a ROS robot before map_server answers)."""

    def occupancy(self):
        raise TimeoutError("no map yet")


class MappedRobot:
    def __init__(self) -> None:
        self.t = 0.0

    def occupancy(self) -> OccupancyGrid:
        data = np.zeros((4, 6), dtype=np.int8)
        data[0, :] = 100
        data[3, 5] = -1
        return OccupancyGrid(0.0, 0.5, Pose2D(-1.0, -2.0, 0.0), data)

    def pose(self) -> PoseStamped:
        return PoseStamped(self.t, Pose2D(self.t, 2 * self.t, 0.0))


def test_a_robot_without_a_map_records_none_and_no_trajectory():
    """A missing map or trajectory is left out, never an error."""
    assert robot_map(MaplessRobot()) is None
    assert robot_trajectory(MaplessRobot()) == []


def test_the_map_is_recorded_with_its_geometry():
    """Size, resolution and origin go with the picture."""
    found = robot_map(MappedRobot())
    assert (found["width"], found["height"], found["resolution"], found["origin"]) == (
        6,
        4,
        0.5,
        [-1.0, -2.0],
    )


def test_hooks_write_runview_only_with_a_run_directory(tmp_path: Path):
    """No run directory, no file; with one, the start writes the map and the end adds the trajectory."""
    robot = MappedRobot()
    robot.trajectory = [(0.0, 1.0, 2.0), (0.25, 1.5, 2.0)]
    missiontree_mission_started(context=SimpleNamespace(robot=robot, run_dir=None), mission=None)
    assert not list(tmp_path.iterdir())
    context = SimpleNamespace(robot=robot, run_dir=tmp_path)
    missiontree_mission_started(context=context, mission=None)
    assert "poses" not in json.loads((tmp_path / "runview.json").read_text())
    missiontree_mission_finished(context=context, summary={})
    runview = json.loads((tmp_path / "runview.json").read_text())
    assert runview["poses"] == [[0.0, 1.0, 2.0], [0.25, 1.5, 2.0]] and runview["map"]["width"] == 6


def test_pose_trail_samples_on_a_grid_of_its_period(tmp_path: Path):
    """At 10 Hz ticks and a 0.25 s period: four samples a second, on the grid."""
    robot = MappedRobot()
    trail = PoseTrail(tmp_path, period=0.25)
    for n in range(21):
        robot.t = round(n * 0.1, 6)
        trail(SimpleNamespace(robot=robot))
    trail.close()
    times = [t for t, _, _ in read_pose_trail(tmp_path)]
    assert times == [0.0, 0.3, 0.5, 0.8, 1.0, 1.3, 1.5, 1.8, 2.0]


def test_pose_trail_never_raises(tmp_path: Path):
    """A robot whose pose fails leaves a gap, not a crashed run."""
    trail = PoseTrail(tmp_path)
    trail(SimpleNamespace(robot=MaplessRobot()))  # has no pose() at all
    trail.close()
    assert read_pose_trail(tmp_path) == []
