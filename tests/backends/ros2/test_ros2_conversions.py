"""Round trips between ROS 2 messages and missiontree's value types (pure functions, no DDS)."""

from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip("rclpy", reason="ROS 2 extra not installed: pip install -e .[ros2]; setup-ros2.sh")
pytestmark = pytest.mark.ros2

from missiontree.backends.ros2 import conversions as conv  # noqa: E402
from missiontree.errors import BackendError  # noqa: E402
from missiontree.types import CameraIntrinsics, LaserScan, OccupancyGrid, Pose2D  # noqa: E402


def test_time_round_trip_keeps_nanoseconds() -> None:
    """Seconds → builtin_interfaces/Time → seconds keeps the value to the nanosecond."""
    t = 1_795_314_576.123456789
    msg = conv.sec_to_time(t)
    assert msg.nanosec < 1_000_000_000
    assert conv.time_to_sec(msg) == pytest.approx(t, abs=1e-6)


@pytest.mark.parametrize("yaw", [0.0, 0.5, -2.0, math.pi - 1e-6, -math.pi + 1e-6])
def test_pose_round_trip_keeps_position_and_yaw(yaw: float) -> None:
    """A Pose2D survives geometry_msgs/PoseStamped and back, yaw included."""
    pose = Pose2D(1.25, -3.5, yaw)
    back = conv.pose_stamped_from_msg(conv.pose_stamped_to_msg(pose, 12.5, "map"))
    assert back.stamp == pytest.approx(12.5)
    assert (back.pose.x, back.pose.y) == (1.25, -3.5)
    assert math.remainder(back.pose.yaw - yaw, 2 * math.pi) == pytest.approx(0.0, abs=1e-9)


def test_transform_round_trip_names_frames() -> None:
    """A TransformStamped gives back parent, child (leading slashes dropped), stamp and pose."""
    msg = conv.transform_to_msg(Pose2D(0.5, 0.25, 1.0), 3.0, "/odom", "base_link")
    parent, child, stamp, pose = conv.transform_from_msg(msg)
    assert (parent, child, stamp) == ("odom", "base_link", pytest.approx(3.0))
    assert pose.yaw == pytest.approx(1.0)


def test_twist_and_twist_stamped_carry_the_same_velocity() -> None:
    """Twist and TwistStamped both map to (forward speed, yaw rate)."""
    assert conv.twist_from_msg(conv.twist_to_msg(0.2, -0.7)) == pytest.approx((0.2, -0.7))
    stamped = conv.twist_stamped_to_msg(0.2, -0.7, 5.0, "base_link")
    assert stamped.header.frame_id == "base_link"
    assert conv.twist_from_msg(stamped) == pytest.approx((0.2, -0.7))


def test_scan_round_trip_keeps_layout_and_ranges() -> None:
    """A LaserScan survives sensor_msgs/LaserScan, inf and NaN readings included; mount yaw is supplied."""
    ranges = np.linspace(0.2, 5.0, 360, dtype=np.float32)
    ranges[10], ranges[20] = np.inf, np.nan
    scan = LaserScan(7.5, -math.pi, 2 * math.pi / 360, 0.15, 12.0, ranges, frame_id="rplidar_link")
    msg = conv.scan_to_msg(scan, scan_time=0.1)
    assert msg.angle_max == pytest.approx(-math.pi + 359 * 2 * math.pi / 360)
    back = conv.scan_from_msg(msg, mount_yaw=math.pi / 2)
    assert back.stamp == pytest.approx(7.5)
    assert back.frame_id == "rplidar_link" and back.mount_yaw == pytest.approx(math.pi / 2)
    np.testing.assert_array_equal(back.ranges, ranges)
    # TurtleBot 4 convention: a quarter of the array looks straight ahead.
    assert back.angles()[90] == pytest.approx(0.0, abs=1e-6)


@pytest.mark.parametrize("encoding", ["rgb8", "bgr8"])
def test_colour_image_round_trip_gives_rgb(encoding: str) -> None:
    """An RGB array sent as rgb8 or bgr8 comes back as the same RGB array."""
    rng = np.random.default_rng(0)
    rgb = rng.integers(0, 256, (24, 32, 3), dtype=np.uint8)
    pixels = rgb if encoding == "rgb8" else rgb[:, :, ::-1]
    back = conv.color_from_msg(conv.image_to_msg(pixels, encoding, 1.0, "cam"))
    np.testing.assert_array_equal(back, rgb)


def test_mono_image_becomes_three_equal_channels() -> None:
    """A mono8 image is widened to HxWx3 RGB."""
    mono = np.arange(12, dtype=np.uint8).reshape(3, 4)
    back = conv.color_from_msg(conv.image_to_msg(mono, "mono8", 1.0, "cam"))
    assert back.shape == (3, 4, 3)
    np.testing.assert_array_equal(back[:, :, 1], mono)


def test_image_with_padded_rows_drops_the_padding() -> None:
    """A row step larger than width × channels (driver padding) is cut away."""
    msg = conv.image_to_msg(np.zeros((2, 3, 3), np.uint8), "rgb8", 0.0, "cam")
    padded = np.zeros((2, 12), np.uint8)
    padded[:, :9] = np.arange(18).reshape(2, 9)
    msg.step, msg.data = 12, padded.tobytes()
    back = conv.image_from_msg(msg)
    np.testing.assert_array_equal(back.reshape(2, 9), np.arange(18).reshape(2, 9))


def test_depth_16uc1_is_millimetres_and_zero_is_unknown() -> None:
    """16UC1 depth is read as metres; 0 (no data) becomes NaN, and NaN is written back as 0."""
    depth = np.array([[1.0, 2.5], [np.nan, 0.75]], dtype=np.float32)
    msg = conv.depth_to_msg(depth, 2.0, "cam", "16UC1")
    assert msg.encoding == "16UC1"
    back = conv.depth_from_msg(msg)
    np.testing.assert_allclose(back, depth, atol=1e-3)


def test_depth_32fc1_round_trip_is_exact() -> None:
    """32FC1 depth (metres) round-trips exactly, NaN kept."""
    depth = np.array([[1.234567, np.nan]], dtype=np.float32)
    back = conv.depth_from_msg(conv.depth_to_msg(depth, 2.0, "cam"))
    np.testing.assert_array_equal(back, depth)


def test_unsupported_encoding_is_a_clear_error() -> None:
    """An encoding the backend cannot read names itself and the ones it can."""
    msg = conv.image_to_msg(np.zeros((2, 2, 3), np.uint8), "rgb8", 0.0, "cam")
    msg.encoding = "yuv422"
    with pytest.raises(BackendError, match=r"unsupported encoding 'yuv422'.*rgb8"):
        conv.image_from_msg(msg)


def test_truncated_image_is_a_clear_error() -> None:
    """An image whose data is shorter than its header says is refused, not misread."""
    msg = conv.image_to_msg(np.zeros((4, 4, 3), np.uint8), "rgb8", 0.0, "cam")
    msg.data = bytes(10)
    with pytest.raises(BackendError, match="truncated"):
        conv.image_from_msg(msg)


def test_camera_info_round_trip_keeps_intrinsics() -> None:
    """CameraIntrinsics survive sensor_msgs/CameraInfo's K matrix as plain floats."""
    intr = CameraIntrinsics(320, 240, 228.5, 228.5, 159.5, 119.5)
    back = conv.intrinsics_from_msg(conv.intrinsics_to_msg(intr, 1.0, "cam"))
    assert back == intr
    assert type(back.fx) is float


def test_occupancy_round_trip_keeps_rows_bottom_up() -> None:
    """An OccupancyGrid survives nav_msgs/OccupancyGrid with row 0 at the lowest y and its origin."""
    data = np.full((3, 5), -1, dtype=np.int8)
    data[0, 1], data[2, 4] = 100, 0
    grid = OccupancyGrid(4.0, 0.05, Pose2D(-1.0, -2.0, 0.0), data)
    back = conv.occupancy_from_msg(conv.occupancy_to_msg(grid, "map"))
    np.testing.assert_array_equal(back.data, data)
    assert back.resolution == pytest.approx(0.05)
    assert (back.origin.x, back.origin.y) == (-1.0, -2.0)
    assert back.world_to_cell(-1.0 + 0.06, -2.0 + 0.01) == (0, 1)


def test_odometry_message_gives_pose_and_velocity() -> None:
    """nav_msgs/Odometry carries the pose (in odom) and the body velocity."""
    msg = conv.odometry_to_msg(Pose2D(1.0, 2.0, 0.3), 0.25, 0.5, 9.0)
    assert (msg.header.frame_id, msg.child_frame_id) == ("odom", "base_link")
    stamped = conv.odometry_to_pose(msg)
    assert stamped.stamp == pytest.approx(9.0) and stamped.pose.yaw == pytest.approx(0.3)
    assert conv.twist_from_msg(msg.twist.twist) == pytest.approx((0.25, 0.5))
