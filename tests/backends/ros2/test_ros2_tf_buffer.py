"""The planar transform buffer over /tf and /tf_static (pure Python: runs without ROS installed)."""

from __future__ import annotations

import math

import pytest

from missiontree.backends.ros2.tf_buffer import TransformBuffer, compose, interpolate, invert
from missiontree.types import Pose2D


def _close(a: Pose2D, b: Pose2D) -> bool:
    return (a.x, a.y) == pytest.approx((b.x, b.y), abs=1e-9) and math.remainder(a.yaw - b.yaw, 2 * math.pi) \
        == pytest.approx(0.0, abs=1e-9)


def test_compose_then_invert_is_identity() -> None:
    """A transform composed with its inverse gives the identity."""
    a = Pose2D(1.0, -2.0, 0.7)
    assert _close(compose(a, invert(a)), Pose2D(0.0, 0.0, 0.0))


def test_interpolate_takes_the_short_way_round() -> None:
    """Halfway between yaw 3.0 and -3.0 is pi, not 0."""
    mid = interpolate(Pose2D(0, 0, 3.0), Pose2D(2, 0, -3.0), 0.5)
    assert mid.x == pytest.approx(1.0)
    assert abs(mid.yaw) == pytest.approx(math.pi, abs=1e-9)


def test_lookup_chains_map_odom_base() -> None:
    """The chain map → odom → base_link composes into the base's pose in the map."""
    tf = TransformBuffer()
    tf.set_transform("map", "odom", 1.0, Pose2D(1.0, 0.0, math.pi / 2))
    tf.set_transform("odom", "base_link", 1.0, Pose2D(2.0, 0.0, 0.0))
    stamp, pose = tf.lookup("map", "base_link")
    assert stamp == 1.0
    assert _close(pose, Pose2D(1.0, 2.0, math.pi / 2))


def test_lookup_between_siblings_uses_the_common_parent() -> None:
    """The lidar's pose in the camera frame goes up to base_link and back down."""
    tf = TransformBuffer()
    tf.set_transform("base_link", "rplidar_link", 0.0, Pose2D(-0.04, 0.0, math.pi / 2), static=True)
    tf.set_transform("base_link", "camera", 0.0, Pose2D(0.06, 0.0, 0.0), static=True)
    _, pose = tf.lookup("camera", "rplidar_link")
    assert _close(pose, Pose2D(-0.10, 0.0, math.pi / 2))


def test_lookup_at_a_time_interpolates_dynamic_and_holds_static() -> None:
    """Between two odometry stamps the pose is interpolated; static mounts hold at every time."""
    tf = TransformBuffer()
    tf.set_transform("odom", "base_link", 1.0, Pose2D(0.0, 0.0, 0.0))
    tf.set_transform("odom", "base_link", 2.0, Pose2D(1.0, 0.0, 0.0))
    tf.set_transform("base_link", "laser", 0.0, Pose2D(0.5, 0.0, 0.0), static=True)
    _, pose = tf.lookup("odom", "laser", stamp=1.5)
    assert _close(pose, Pose2D(1.0, 0.0, 0.0))


def test_latest_lookup_uses_the_oldest_latest_stamp_on_the_path() -> None:
    """Like tf2's time 0: the newest time every dynamic transform on the path is known at."""
    tf = TransformBuffer()
    tf.set_transform("map", "odom", 1.0, Pose2D(0.0, 0.0, 0.0))
    tf.set_transform("odom", "base_link", 1.0, Pose2D(0.0, 0.0, 0.0))
    tf.set_transform("odom", "base_link", 3.0, Pose2D(2.0, 0.0, 0.0))
    tf.set_transform("map", "odom", 2.0, Pose2D(0.0, 1.0, 0.0))
    stamp, pose = tf.lookup("map", "base_link")
    assert stamp == 2.0
    assert _close(pose, Pose2D(1.0, 1.0, 0.0))


def test_unconnected_frames_and_times_outside_history_give_none() -> None:
    """No path between frames, or a time outside the history, is None rather than a guess."""
    tf = TransformBuffer()
    tf.set_transform("odom", "base_link", 1.0, Pose2D(0.0, 0.0, 0.0))
    tf.set_transform("odom", "base_link", 2.0, Pose2D(1.0, 0.0, 0.0))
    assert tf.lookup("map", "base_link") is None
    assert tf.lookup("odom", "base_link", stamp=5.0) is None
    assert tf.frames() == {"odom", "base_link"}
