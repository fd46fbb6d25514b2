"""SimRobot: determinism, sensor rates, estimate versus truth, ground truth off the protocol, pictures."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from missiontree.backends.sim import create_robot
from missiontree.backends.sim import robot as robot_module
from missiontree.backends.sim.render import PEOPLE_BGR, ROBOT_BGR, Scene, ScenePerson, draw_topdown
from missiontree.backends.sim.timing import TimingLog
from missiontree.robot.interface import Drawable, Robot
from missiontree.types import Marker, Pose2D, Tolerance

NOISY = {"lidar": {"noise": 0.02}, "camera": {"depth_noise": 0.01, "color_noise": 3.0},
         "odometry": {"noise_v": 0.03, "noise_w": 0.03}}


def _patrol(seed: int, seconds: float = 12.0):
    robot = create_robot({"world": "combined", "seed": seed, "config": NOISY})
    handle = robot.navigate_to(Pose2D(4.75, 0.15), Tolerance(0.25, 2 * math.pi))
    scans, frames = [], []
    while robot.now() < seconds:
        robot.spin_until(robot.now() + 0.5)
        scans.append(robot.scan().ranges.copy())
        frames.append((robot.rgbd().color.copy(), robot.rgbd().depth.copy()))
    return robot, handle, scans, frames


def test_same_seed_gives_the_same_sensors_and_trajectory():
    """Two runs with one seed produce identical scans, images, poses and goal outcome."""
    a, ha, scans_a, frames_a = _patrol(7)
    b, hb, scans_b, frames_b = _patrol(7)
    assert all(np.array_equal(x, y, equal_nan=True) for x, y in zip(scans_a, scans_b, strict=True))
    assert all(np.array_equal(c1, c2) and np.array_equal(d1, d2, equal_nan=True)
               for (c1, d1), (c2, d2) in zip(frames_a, frames_b, strict=True))
    assert a.trajectory == b.trajectory and a.pose() == b.pose()
    assert ha.status() == hb.status()


def test_another_seed_gives_other_noise():
    """A different seed changes the noisy readings."""
    robot_a = create_robot({"world": "conformance", "seed": 1, "config": NOISY})
    robot_b = create_robot({"world": "conformance", "seed": 2, "config": NOISY})
    assert not np.array_equal(robot_a.scan().ranges, robot_b.scan().ranges)


def test_sensor_rates_are_configurable():
    """Lidar and camera publish at their configured rates on the simulated clock."""
    rates = {"lidar": {"rate": 20.0}, "camera": {"rate": 2.0}}
    robot = create_robot({"world": "conformance", "config": rates})
    scan_stamps, frame_stamps = set(), set()
    while robot.now() < 5.0 - 1e-9:
        robot.spin_until(robot.now() + 0.05)
        scan_stamps.add(robot.scan().stamp)
        frame_stamps.add(robot.rgbd().stamp)
    scan_stamps.discard(0.0)
    frame_stamps.discard(0.0)   # the first readings come at t = 0
    assert len(scan_stamps) == 100 and len(frame_stamps) == 10
    assert min(np.diff(sorted(scan_stamps))) > 0.049


def test_pose_is_the_estimate_not_the_truth():
    """With odometry noise, pose() drifts from the true pose that only ground truth knows."""
    robot = create_robot({"world": "conformance", "seed": 4,
                          "config": {"odometry": {"noise_v": 0.1, "noise_w": 0.1}}})
    robot.drive(0.25, 0.4)
    robot.spin_until(10.0)
    estimate, truth = robot.pose().pose, robot.truth.robot_pose()
    assert estimate.distance_to(truth) > 0.01
    assert robot.rgbd().camera_pose.distance_to(estimate) < 0.1


def test_ground_truth_is_not_part_of_the_robot_protocol():
    """The Robot protocol exposes no ground truth; the simulator keeps it on the side."""
    robot = create_robot({"world": "conformance"})
    assert isinstance(robot, Robot) and isinstance(robot, Drawable)
    assert not hasattr(Robot, "truth") and not hasattr(Robot, "true_pose")
    assert robot.truth.object("chair_red").label == "chair"


def test_collisions_stop_the_robot_at_the_wall():
    """Driving into a wall stops the robot next to it, its body short of the wall line."""
    robot = create_robot({"world": "conformance"})
    robot.drive(0.31, 0.0)
    robot.spin_until(20.0)
    assert robot.bumps > 0
    gap = 5.0 - robot.true_pose.x   # the east wall's line is x = 5
    assert 0.17 <= gap < 0.17 + 0.1



def test_a_push_against_a_wall_is_one_contact_with_its_place():
    """Many refused steps against one wall are one contact, reported with where and when it began."""
    robot = create_robot({"world": "conformance"})
    robot.drive(0.31, 0.0)
    robot.spin_until(20.0)
    report = robot.bump_report()
    assert report["refused_moves"] > 1 and report["contacts"] == 1
    (place,) = report["where"]
    assert abs(place["x"] - robot.true_pose.x) < 0.05 and 0.0 < place["t"] < 20.0
    assert "touched" in report["meaning"]

def test_history_forgets_beyond_its_horizon():
    """pose_at and scan_at answer within the history horizon and None beyond it."""
    robot = create_robot({"world": "conformance", "config": {"history_horizon": 2.0}})
    robot.spin_until(5.0)
    assert robot.pose_at(4.0) is not None and robot.scan_at(4.0) is not None
    assert robot.pose_at(1.0) is None and robot.scan_at(1.0) is None


def test_draw_writes_a_topdown_png(tmp_path):
    """draw() writes a PNG with the map, the trajectory and the markers."""
    robot = create_robot({"world": "office"})
    robot.drive(0.2, 0.2)
    robot.spin_until(5.0)
    markers = [Marker("alarm", 3.0, 3.0, 2.0, "ALARM"), Marker("detection", 2, 2, 1, "cup")]
    (path,) = robot.draw(tmp_path, markers)
    image = cv2.imread(str(path))
    assert image is not None and image.shape[0] > 300 and image.shape[1] > 400
    assert (np.abs(image.astype(int) - (30, 30, 220)).sum(axis=2) < 60).any()   # the red alarm marker


def test_close_stops_everything():
    """After close() the clock no longer advances and the robot does not move."""
    robot = create_robot({"world": "conformance"})
    robot.drive(0.2, 0.0)
    robot.close()
    robot.spin_until(3.0)
    assert robot.now() == 0.0


def test_camera_thread_gives_the_same_frames():
    """Rendering on the worker thread changes nothing: same frames, noise and sightings."""
    runs = []
    for thread in (True, False):
        robot = create_robot({"world": "combined", "seed": 3, "config": {**NOISY, "camera_thread": thread}})
        robot.drive(0.2, 0.3)
        frames = []
        while robot.now() < 3.0:
            robot.spin_until(robot.now() + 0.5)   # several frames per read: the thread runs ahead
            frames.append(robot.rgbd().color.copy())
        runs.append((frames, [sorted(seen) for _, seen in robot.truth.visibility]))
    assert all(np.array_equal(a, b) for a, b in zip(runs[0][0], runs[1][0], strict=True))
    assert runs[0][1] == runs[1][1]


# -- memory stays flat on long runs ------------------------------------------------------------------


def test_timing_log_keeps_recent_samples_and_counts_every_call():
    """A TimingLog holds at most ``keep`` samples but counts and sums all of them."""
    log = TimingLog(keep=10)
    for i in range(25):
        log.append(float(i))
    assert len(log) == 10 and list(log) == [float(i) for i in range(15, 25)]
    assert log.count == 25 and log.total_ms == sum(range(25)) and log.max_ms == 24.0
    assert log.median() == 19.5


def test_trajectory_is_thinned_to_a_bound_and_keeps_its_ends(monkeypatch: pytest.MonkeyPatch):
    """Driving for a long time keeps at most the bound of points; the first and the latest stay."""
    monkeypatch.setattr(robot_module, "_TRAJECTORY_MAX", 40)
    robot = create_robot({"world": "conformance"})
    start = robot.trajectory[0]
    robot.drive(0.2, 0.4)   # circles
    robot.spin_until(300.0)
    assert len(robot.trajectory) <= 41
    assert robot.trajectory[0] == start
    last = robot.trajectory[-1]
    assert math.hypot(last[1] - robot.true_pose.x, last[2] - robot.true_pose.y) < 0.5
    times = [t for t, _, _ in robot.trajectory]
    assert times == sorted(times) and times[-1] > 250.0
    assert robot.timings["lidar"].count == 3001 and len(robot.timings["lidar"]) <= 4096


def test_standing_still_adds_no_trajectory_points():
    """A robot that does not move does not grow its trajectory."""
    robot = create_robot({"world": "conformance"})
    robot.spin_until(120.0)
    assert len(robot.trajectory) == 1


def test_visibility_log_is_compact_and_reads_as_frames():
    """The ground truth's visibility log reads as (stamp, {name: Sighting}) and costs bytes, not objects."""
    robot = create_robot({"world": "combined"})
    robot.drive(0.0, 0.5)
    robot.spin_until(20.0)
    log = robot.truth.visibility
    assert len(log) == 101   # 5 Hz for 20 s, and the first frame
    stamp, seen = log[-1]
    assert seen and all(s.pixels > 0 and s.kind in ("object", "person") for s in seen.values())
    assert robot.truth.visible_at(stamp) == seen
    assert [st for st, _ in log][:3] == [0.0, 0.2, 0.4]
    assert log.nbytes < 200 * len(log)


# -- the top-down picture ----------------------------------------------------------------------------


def test_picture_draws_a_plain_scene_people_apart_from_the_robot(tmp_path):
    """A Scene (no robot, no world) draws; people are not in the robot's blue; labels never overlap."""
    robot = create_robot({"world": "combined"})
    scene = robot.scene()
    person = ScenePerson("p1", np.array([[3.0, 3.0], [3.5, 3.0]]), (3.5, 3.0))
    scene = Scene(**{**scene.__dict__, "people": [person]})
    markers = [Marker("alarm", 3.5, 3.0, 1.0, label="person"),
               Marker("alarm", 3.52, 3.0, 2.0, label="person"),
               Marker("detection", 3.6, 3.1, 1.0, label="person 0.9"), Marker("goal", 3.4, 2.9, 0.0, "wp1")]
    path = tmp_path / "top.png"
    boxes = draw_topdown(scene, markers, path)
    img = cv2.imread(str(path))
    for i, a in enumerate(boxes):
        for b in boxes[i + 1:]:
            assert a[2] <= b[0] or b[2] <= a[0] or a[3] <= b[1] or b[3] <= a[1], (a, b)
    assert PEOPLE_BGR != ROBOT_BGR
    assert (np.abs(img.astype(int) - PEOPLE_BGR).sum(axis=2) == 0).any()


def test_picture_legend_shows_only_what_is_drawn(tmp_path):
    """No alarm, no alarm entry in the legend: the legend band holds no alarm red until an alarm is drawn."""
    robot = create_robot({"world": "conformance"})
    plain, alarmed = tmp_path / "plain.png", tmp_path / "alarm.png"
    draw_topdown(robot.scene(), [], plain)
    draw_topdown(robot.scene(), [Marker("alarm", 1.0, 1.0, 0.0, label="person")], alarmed)
    red = np.array((30, 30, 220))

    def legend_has_red(path) -> bool:
        img = cv2.imread(str(path)).astype(int)
        band = img[-40:]
        return bool((np.abs(band - red).sum(axis=2) < 30).any())

    assert not legend_has_red(plain) and legend_has_red(alarmed)


def _frames_read(every: int, ask_truth: bool = False):
    """A noisy drive reading the camera after every ``every``-th frame; (robot, {stamp: (colour, depth)})."""
    robot = create_robot({"world": "combined", "seed": 5, "config": NOISY})
    robot.drive(0.2, 0.4)
    frames, step = {}, 0
    while robot.now() < 4.0:
        robot.spin_until(robot.now() + 0.2)   # one frame a step at 5 Hz
        step += 1
        if ask_truth:
            robot.truth.visible_at(robot.now())   # the ground truth asks before the camera is read
        if step % every == 0:
            frame = robot.rgbd()
            frames[frame.stamp] = (frame.color.copy(), frame.depth.copy())
    return robot, frames


def test_frames_nobody_reads_are_not_rendered_and_change_nothing():
    """Unread frames are not drawn, yet the frames read and the ground truth's sightings are the same."""
    every, every_other = _frames_read(1), _frames_read(2)
    asked = _frames_read(2, ask_truth=True)
    for robot, frames in (every_other, asked):
        assert frames and robot.timings["camera"].count == len(frames) < len(every[1])
        for stamp, (color, depth) in frames.items():
            assert np.array_equal(color, every[1][stamp][0])
            assert np.array_equal(depth, every[1][stamp][1], equal_nan=True)
        assert [(s, sorted(seen)) for s, seen in robot.truth.visibility] == \
            [(s, sorted(seen)) for s, seen in every[0].truth.visibility]
