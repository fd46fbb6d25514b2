"""The recorded backend: a rawlog played through the robot interface at its timestamps, motion refused."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from missiontree.backends.recorded import RecordedRobot, create_robot
from missiontree.errors import BackendError, ConfigError
from missiontree.mapping import mrpt_datasets
from missiontree.mapping.grid import LogOddsGrid
from missiontree.mapping.mrpt_rgbd import read_rgbd_frames
from missiontree.mapping.rawlog import RecordedScan, ScanLog, read_rawlog
from missiontree.mapping.recorded_map import build_grid
from missiontree.robot.actions import INFRASTRUCTURE, ActionStatus
from missiontree.robot.interface import Robot
from missiontree.types import Pose2D

LOOP_FILE = "2006-01ENE-21-SENA_Telecom Faculty_one_loop_only.rawlog"
LOOP = mrpt_datasets.find_dataset(LOOP_FILE) or Path("missing")
RGBD = mrpt_datasets.find_dataset("tests_rgbd.rawlog") or Path("missing")
MISSING = mrpt_datasets.missing_reason(LOOP_FILE)


def small_log() -> ScanLog:
    """Three scans 1 s apart at x = 0, 1, 2 m."""
    log = ScanLog("small.rawlog")
    for i in range(3):
        ranges = np.full(5, 2.0 + i, np.float32)
        log.scans.append(RecordedScan(100.0 + i, ranges, np.ones(5, bool), np.pi, True, 30.0))
        log.poses.append(Pose2D(float(i), 0.0, 0.0))
    return log


def test_is_a_robot() -> None:
    """The recorded robot satisfies the Robot protocol."""
    assert isinstance(RecordedRobot(small_log()), Robot)


def test_plays_records_at_their_timestamps() -> None:
    """The clock starts at the first scan; each scan appears once the clock reaches its stamp."""
    robot = RecordedRobot(small_log())
    assert robot.now() == 100.0 and robot.scan().stamp == 100.0
    robot.spin_until(101.5)
    assert robot.scan().stamp == 101.0 and robot.pose().pose.x == 1.0
    robot.spin_until(150.0)
    assert robot.scan().stamp == 102.0 and robot.finished()  # the last stays, its stamp goes stale


def test_pose_at_interpolates_and_knows_only_the_past() -> None:
    """pose_at interpolates between scans already played and says nothing of the future."""
    robot = RecordedRobot(small_log())
    robot.spin_until(101.0)
    assert robot.pose_at(100.25).x == pytest.approx(0.25)
    assert robot.pose_at(101.5) is None
    assert robot.scan_at(100.9).stamp == 101.0


def test_navigation_is_refused_with_the_reason() -> None:
    """A goal comes back REJECTED at once, saying the robot cannot move, as an infrastructure fault."""
    handle = RecordedRobot(small_log()).navigate_to(Pose2D(1.0, 2.0, 0.0))
    assert handle.status() is ActionStatus.REJECTED
    result = handle.result()
    assert "recorded robot cannot navigate" in result.reason and result.kind == INFRASTRUCTURE


def test_driving_is_refused_and_stopping_works() -> None:
    """A drive with a velocity raises BackendError naming the recording; drive(0, 0) and stop() work."""
    robot = RecordedRobot(small_log())
    with pytest.raises(BackendError, match=r"cannot drive .*small\.rawlog"):
        robot.drive(0.2, 0.0)
    robot.drive(0.0, 0.0)
    robot.stop()
    robot.close()
    robot.close()


def test_create_robot_needs_a_rawlog() -> None:
    """create_robot without a .rawlog world, or with an unknown option, is bad input."""
    with pytest.raises(ConfigError, match="expected --world to name an MRPT .rawlog"):
        create_robot({"world": "office"})
    with pytest.raises(ConfigError, match="unknown options"):
        create_robot({"world": "x.rawlog", "speed": 2})


@pytest.mark.realdata
@pytest.mark.skipif(not LOOP.is_file(), reason=MISSING)
def test_mapping_on_the_played_loop_equals_the_offline_map() -> None:
    """Mapping each new scan at pose_at(its stamp), ticking at 10 Hz, builds the offline map cell for cell."""
    log = read_rawlog(LOOP)
    robot = create_robot({"world": str(LOOP)})
    grid = LogOddsGrid(0.05, 20.0, 20.0, max_range=15.0, sensor_offset=robot.lidar_offset)
    integrated = 0
    while not robot.finished():
        integrated += grid.update_from(robot.scan(), robot.pose_at)
        robot.spin_until(robot.now() + 0.1)
    integrated += grid.update_from(robot.scan(), robot.pose_at)
    assert integrated == len(log.scans)
    offline = build_grid(log.scans, log.poses, max_range=15.0)
    assert np.array_equal(grid.trinary(), offline.trinary())


@pytest.mark.realdata
@pytest.mark.skipif(not (LOOP.is_file() and RGBD.is_file()), reason=MISSING)
def test_rgbd_frames_play_at_their_stamp() -> None:
    """The Kinect frame appears once the clock reaches its stamp, with its depth."""
    robot = create_robot({"world": str(LOOP), "rgbd": str(RGBD)})
    frames_at = read_rgbd_frames(RGBD)[0].stamp
    robot.spin_until(frames_at - 1.0)
    assert robot.rgbd() is None
    robot.spin_until(frames_at)
    frame = robot.rgbd()
    assert frame is not None and frame.depth.shape == (480, 640)


def test_without_a_map_the_robot_maps_the_scans_played_so_far() -> None:
    """occupancy() is None before the first scan's map is asked, then grows with each scan played."""
    robot = RecordedRobot(small_log())
    first = robot.occupancy()
    assert first is not None and first.stamp == 100.0
    robot.spin_until(102.0)
    later = robot.occupancy()
    assert later is not None and later.stamp == 102.0
    assert (np.asarray(later.data) == 0).sum() > (np.asarray(first.data) == 0).sum(), "more free space"
    assert robot.occupancy() is later, "no new scan: the same map"


@pytest.mark.realdata
@pytest.mark.skipif(not LOOP.is_file(), reason=MISSING)
def test_the_live_map_of_the_whole_loop_is_the_offline_map() -> None:
    """Played to its end, the loop's live map equals the offline map of the same scans, cell for cell."""
    log = read_rawlog(LOOP)
    robot = create_robot({"world": str(LOOP)})
    while not robot.finished():
        robot.occupancy()
        robot.spin_until(robot.now() + 2.0)
    live = robot.occupancy()
    offline = build_grid(log.scans, log.poses, max_range=15.0).to_occupancy()
    assert live is not None
    assert np.array_equal(np.asarray(live.data), np.asarray(offline.data))
