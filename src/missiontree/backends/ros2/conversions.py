"""Pure conversions between ROS 2 messages and missiontree's value types.

No node, no I/O, no global state: every function takes a message or a value and returns the
other, so each is tested by a round trip. Images are converted with numpy (cv_bridge on PyPI is
ROS 1 code). Times are float seconds; headers carry ``builtin_interfaces/Time``.
"""

from __future__ import annotations

import array
import math

import numpy as np
from builtin_interfaces.msg import Duration as DurationMsg
from builtin_interfaces.msg import Time as TimeMsg
from geometry_msgs.msg import Pose as PoseMsg
from geometry_msgs.msg import PoseStamped as PoseStampedMsg
from geometry_msgs.msg import PoseWithCovarianceStamped, Quaternion, TransformStamped, Twist, TwistStamped
from nav_msgs.msg import OccupancyGrid as OccupancyGridMsg
from nav_msgs.msg import Odometry
from sensor_msgs.msg import CameraInfo, Image
from sensor_msgs.msg import LaserScan as LaserScanMsg

from missiontree.errors import BackendError
from missiontree.mapping.ros2bag import IMAGE_ENCODINGS, color_from_image, depth_from_image, image_pixels
from missiontree.types import CameraIntrinsics, LaserScan, OccupancyGrid, Pose2D, PoseStamped

# ------------------------------------------------------------------------------------------ arrays


def _packed(values: np.ndarray, typecode: str) -> array.array:
    """An ``array.array`` of the values (the fast path of generated message setters)."""
    dtype = {"f": np.float32, "b": np.int8, "B": np.uint8}[typecode]
    return array.array(typecode, np.ascontiguousarray(values, dtype=dtype).tobytes())


# --------------------------------------------------------------------------------------------- time


def time_to_sec(stamp: TimeMsg) -> float:
    """Seconds of a ``builtin_interfaces/Time`` (or Duration)."""
    return stamp.sec + stamp.nanosec * 1e-9


def sec_to_time(t: float) -> TimeMsg:
    """A ``builtin_interfaces/Time`` for ``t`` seconds (non-negative)."""
    ns = max(0, round(t * 1e9))
    return TimeMsg(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def sec_to_duration(t: float) -> DurationMsg:
    """A ``builtin_interfaces/Duration`` for ``t`` seconds (clamped at zero)."""
    ns = max(0, round(t * 1e9))
    return DurationMsg(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


# ---------------------------------------------------------------------------------------- rotations


def yaw_to_quaternion(yaw: float) -> Quaternion:
    """The quaternion of a rotation by ``yaw`` about z."""
    return Quaternion(x=0.0, y=0.0, z=math.sin(yaw / 2.0), w=math.cos(yaw / 2.0))


def quaternion_to_yaw(q: Quaternion) -> float:
    """The yaw (rotation about z) of a quaternion; roll and pitch are ignored."""
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


# -------------------------------------------------------------------------------------------- poses


def pose_to_msg(pose: Pose2D) -> PoseMsg:
    """A ``geometry_msgs/Pose`` on the floor plane (z = 0)."""
    msg = PoseMsg()
    msg.position.x, msg.position.y = float(pose.x), float(pose.y)
    msg.orientation = yaw_to_quaternion(pose.yaw)
    return msg


def pose_from_msg(msg: PoseMsg) -> Pose2D:
    """The planar part of a ``geometry_msgs/Pose``."""
    return Pose2D(msg.position.x, msg.position.y, quaternion_to_yaw(msg.orientation))


def pose_stamped_to_msg(pose: Pose2D, stamp: float, frame_id: str = "map") -> PoseStampedMsg:
    """A ``geometry_msgs/PoseStamped`` in ``frame_id``."""
    msg = PoseStampedMsg()
    msg.header.stamp = sec_to_time(stamp)
    msg.header.frame_id = frame_id
    msg.pose = pose_to_msg(pose)
    return msg


def pose_stamped_from_msg(msg: PoseStampedMsg | PoseWithCovarianceStamped) -> PoseStamped:
    """A stamped planar pose from ``PoseStamped`` or ``PoseWithCovarianceStamped`` (/amcl_pose)."""
    pose = msg.pose.pose if isinstance(msg, PoseWithCovarianceStamped) else msg.pose
    return PoseStamped(time_to_sec(msg.header.stamp), pose_from_msg(pose))


def odometry_to_pose(msg: Odometry) -> PoseStamped:
    """The stamped pose of an ``nav_msgs/Odometry`` (in its own frame, usually ``odom``)."""
    return PoseStamped(time_to_sec(msg.header.stamp), pose_from_msg(msg.pose.pose))


def odometry_to_msg(pose: Pose2D, v: float, w: float, stamp: float,
                    frame_id: str = "odom", child_frame_id: str = "base_link") -> Odometry:
    """A ``nav_msgs/Odometry`` with the pose and body velocity."""
    msg = Odometry()
    msg.header.stamp = sec_to_time(stamp)
    msg.header.frame_id = frame_id
    msg.child_frame_id = child_frame_id
    msg.pose.pose = pose_to_msg(pose)
    msg.twist.twist = twist_to_msg(v, w)
    return msg


def transform_to_msg(pose: Pose2D, stamp: float, parent: str, child: str) -> TransformStamped:
    """A ``geometry_msgs/TransformStamped`` placing ``child`` at ``pose`` in ``parent``."""
    msg = TransformStamped()
    msg.header.stamp = sec_to_time(stamp)
    msg.header.frame_id = parent
    msg.child_frame_id = child
    msg.transform.translation.x, msg.transform.translation.y = float(pose.x), float(pose.y)
    msg.transform.rotation = yaw_to_quaternion(pose.yaw)
    return msg


def transform_from_msg(msg: TransformStamped) -> tuple[str, str, float, Pose2D]:
    """(parent, child, stamp, planar pose of child in parent) of a ``TransformStamped``."""
    t = msg.transform
    pose = Pose2D(t.translation.x, t.translation.y, quaternion_to_yaw(t.rotation))
    parent, child = msg.header.frame_id.lstrip("/"), msg.child_frame_id.lstrip("/")
    return parent, child, time_to_sec(msg.header.stamp), pose


# ---------------------------------------------------------------------------------------- velocity


def twist_to_msg(v: float, w: float) -> Twist:
    """A ``geometry_msgs/Twist`` with forward speed ``v`` and yaw rate ``w``."""
    msg = Twist()
    msg.linear.x, msg.angular.z = float(v), float(w)
    return msg


def twist_stamped_to_msg(v: float, w: float, stamp: float, frame_id: str = "base_link") -> TwistStamped:
    """A ``geometry_msgs/TwistStamped`` with forward speed ``v`` and yaw rate ``w``."""
    msg = TwistStamped()
    msg.header.stamp = sec_to_time(stamp)
    msg.header.frame_id = frame_id
    msg.twist = twist_to_msg(v, w)
    return msg


def twist_from_msg(msg: Twist | TwistStamped) -> tuple[float, float]:
    """(forward speed, yaw rate) of a ``Twist`` or ``TwistStamped``."""
    twist = msg.twist if isinstance(msg, TwistStamped) else msg
    return twist.linear.x, twist.angular.z


# ------------------------------------------------------------------------------------------- lidar


def scan_from_msg(msg: LaserScanMsg, mount_yaw: float = 0.0) -> LaserScan:
    """A :class:`LaserScan` from ``sensor_msgs/LaserScan``; ``mount_yaw`` comes from TF or config."""
    return LaserScan(
        stamp=time_to_sec(msg.header.stamp),
        angle_min=msg.angle_min,
        angle_increment=msg.angle_increment,
        range_min=msg.range_min,
        range_max=msg.range_max,
        ranges=np.asarray(msg.ranges, dtype=np.float32),
        mount_yaw=mount_yaw,
        frame_id=msg.header.frame_id,
    )


def scan_to_msg(scan: LaserScan, scan_time: float = 0.0) -> LaserScanMsg:
    """A ``sensor_msgs/LaserScan`` from a :class:`LaserScan` (its mount yaw belongs in TF)."""
    msg = LaserScanMsg()
    msg.header.stamp = sec_to_time(scan.stamp)
    msg.header.frame_id = scan.frame_id
    n = len(scan.ranges)
    msg.angle_min = float(scan.angle_min)
    msg.angle_increment = float(scan.angle_increment)
    msg.angle_max = float(scan.angle_min + scan.angle_increment * max(n - 1, 0))
    msg.range_min, msg.range_max = float(scan.range_min), float(scan.range_max)
    msg.scan_time = float(scan_time)
    msg.time_increment = float(scan_time / n) if n else 0.0
    msg.ranges = _packed(scan.ranges, "f")
    return msg


# ------------------------------------------------------------------------------------------ images



def image_from_msg(msg: Image) -> np.ndarray:
    """The pixels of a ``sensor_msgs/Image`` as an HxW or HxWxC array (the bag reader's decoder).

    Raises:
        BackendError: An encoding it does not read, a size out of range, or data shorter than the
            header says.
    """
    return image_pixels(msg, BackendError)


def color_from_msg(msg: Image) -> np.ndarray:
    """An HxWx3 uint8 RGB image from any 8-bit colour or mono ``sensor_msgs/Image``."""
    return color_from_image(msg, BackendError)


def depth_from_msg(msg: Image) -> np.ndarray:
    """An HxW float32 depth image in metres; 16-bit encodings are millimetres, 0 (no data) becomes NaN."""
    return depth_from_image(msg, BackendError)


def image_to_msg(pixels: np.ndarray, encoding: str, stamp: float, frame_id: str) -> Image:
    """A ``sensor_msgs/Image`` from an array (rgb8/bgr8/mono8 uint8, 16UC1 uint16, 32FC1 float32)."""
    if encoding not in IMAGE_ENCODINGS:
        raise BackendError(f"cannot encode an image as {encoding!r}; "
                           f"expected one of {', '.join(IMAGE_ENCODINGS)}")
    kind, channels = IMAGE_ENCODINGS[encoding]
    dtype = np.dtype(kind)
    data = np.ascontiguousarray(pixels, dtype=dtype)
    msg = Image()
    msg.header.stamp = sec_to_time(stamp)
    msg.header.frame_id = frame_id
    msg.height, msg.width = int(data.shape[0]), int(data.shape[1])
    msg.encoding = encoding
    msg.is_bigendian = 0
    msg.step = int(data.shape[1] * channels * dtype.itemsize)
    msg.data = _packed(data.view(np.uint8).ravel(), "B")
    return msg


def depth_to_msg(depth: np.ndarray, stamp: float, frame_id: str, encoding: str = "32FC1") -> Image:
    """A depth ``sensor_msgs/Image``: 32FC1 metres (NaN kept) or 16UC1 millimetres (unknown = 0)."""
    if encoding == "16UC1":
        mm = np.nan_to_num(np.asarray(depth, dtype=np.float64) * 1000.0, nan=0.0, posinf=0.0, neginf=0.0)
        return image_to_msg(np.clip(np.rint(mm), 0, 65535).astype(np.uint16), "16UC1", stamp, frame_id)
    return image_to_msg(np.asarray(depth, dtype=np.float32), "32FC1", stamp, frame_id)


def intrinsics_from_msg(msg: CameraInfo) -> CameraIntrinsics:
    """Pinhole intrinsics from ``sensor_msgs/CameraInfo``'s K matrix."""
    k = msg.k
    return CameraIntrinsics(width=int(msg.width), height=int(msg.height), fx=float(k[0]), fy=float(k[4]),
                            cx=float(k[2]), cy=float(k[5]))


def intrinsics_to_msg(intr: CameraIntrinsics, stamp: float, frame_id: str) -> CameraInfo:
    """A ``sensor_msgs/CameraInfo`` for an undistorted pinhole camera."""
    msg = CameraInfo()
    msg.header.stamp = sec_to_time(stamp)
    msg.header.frame_id = frame_id
    msg.width, msg.height = int(intr.width), int(intr.height)
    msg.distortion_model = "plumb_bob"
    msg.d = [0.0] * 5
    msg.k = [intr.fx, 0.0, intr.cx, 0.0, intr.fy, intr.cy, 0.0, 0.0, 1.0]
    msg.r = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]
    msg.p = [intr.fx, 0.0, intr.cx, 0.0, 0.0, intr.fy, intr.cy, 0.0, 0.0, 0.0, 1.0, 0.0]
    return msg


# -------------------------------------------------------------------------------------------- maps


def occupancy_from_msg(msg: OccupancyGridMsg) -> OccupancyGrid:
    """An :class:`OccupancyGrid` (row 0 = lowest y, as in ROS) from ``nav_msgs/OccupancyGrid``."""
    info = msg.info
    data = np.asarray(msg.data, dtype=np.int8)
    if data.size != info.width * info.height:
        raise BackendError(f"map on frame {msg.header.frame_id!r}: {data.size} cells for "
                           f"{info.width}x{info.height}; the message is inconsistent")
    return OccupancyGrid(
        stamp=time_to_sec(msg.header.stamp),
        resolution=float(info.resolution),
        origin=pose_from_msg(info.origin),
        data=data.reshape(info.height, info.width).copy(),
    )


def occupancy_to_msg(grid: OccupancyGrid, frame_id: str = "map") -> OccupancyGridMsg:
    """A ``nav_msgs/OccupancyGrid`` from an :class:`OccupancyGrid`."""
    msg = OccupancyGridMsg()
    msg.header.stamp = sec_to_time(grid.stamp)
    msg.header.frame_id = frame_id
    msg.info.map_load_time = msg.header.stamp
    msg.info.resolution = float(grid.resolution)
    msg.info.height, msg.info.width = int(grid.data.shape[0]), int(grid.data.shape[1])
    msg.info.origin = pose_to_msg(grid.origin)
    msg.data = _packed(grid.data.ravel(), "b")
    return msg
