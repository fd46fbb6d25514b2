"""Plain value types shared by every layer: poses, scans, images, maps, detections, markers.

They are shaped after the ROS 2 messages they stand for (geometry_msgs/Pose2D,
sensor_msgs/LaserScan, sensor_msgs/Image + CameraInfo, nav_msgs/OccupancyGrid) so that
backends convert them with pure functions. Angles are radians, distances metres, times
seconds on the backend's clock (simulated time in the simulator, ROS time on ROS 2).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np


def wrap_angle(angle: float) -> float:
    """Return ``angle`` wrapped to [-pi, pi)."""
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


@dataclass(frozen=True, slots=True)
class Pose2D:
    """A planar pose in the map frame: position (m) and heading (rad, counter-clockwise from +x)."""

    x: float
    y: float
    yaw: float = 0.0

    def distance_to(self, other: Pose2D) -> float:
        """Euclidean distance between the two positions, ignoring heading."""
        return math.hypot(other.x - self.x, other.y - self.y)

    def bearing_to(self, x: float, y: float) -> float:
        """Bearing of the point (x, y) relative to this pose's heading, wrapped to [-pi, pi)."""
        return wrap_angle(math.atan2(y - self.y, x - self.x) - self.yaw)

    def transform(self, x: float, y: float) -> tuple[float, float]:
        """Map a point from this pose's body frame to the parent (map) frame."""
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        return self.x + c * x - s * y, self.y + s * x + c * y


@dataclass(frozen=True, slots=True)
class PoseStamped:
    """A pose with the time it was valid at."""

    stamp: float
    pose: Pose2D


@dataclass(frozen=True, slots=True)
class Tolerance:
    """Goal tolerances as in Nav2's goal checker.

    ``yaw=2*pi`` accepts any heading, as the patrol-robot thesis configured Nav2 (§3.6).
    """

    xy: float = 0.25
    yaw: float = 0.25


@dataclass(frozen=True)
class LaserScan:
    """A planar laser scan, like sensor_msgs/LaserScan.

    ``ranges[i]`` is measured at ``angle_min + i * angle_increment`` in the *sensor* frame,
    where angle 0 points along the sensor's x axis. A backend with the TurtleBot 4 index
    convention (index 0 = right, front at 25 %) sets ``angle_min = -pi/2`` and its mount
    yaw so that the robot's front lands at a quarter of the array. ``inf`` means no return
    within ``range_max``; NaN means an invalid reading.

    Attributes:
        stamp: Time the scan was taken.
        angle_min: Angle of the first beam in the sensor frame.
        angle_increment: Angle between consecutive beams (positive: counter-clockwise).
        range_min: Readings below this are invalid.
        range_max: Readings above this are invalid (no return).
        ranges: float32 array of ranges in metres.
        mount_yaw: Yaw of the sensor frame relative to the robot base frame.
        frame_id: Name of the sensor frame.
    """

    stamp: float
    angle_min: float
    angle_increment: float
    range_min: float
    range_max: float
    ranges: np.ndarray
    mount_yaw: float = 0.0
    frame_id: str = "rplidar_link"

    def angles(self) -> np.ndarray:
        """Angle of every beam in the robot base frame (0 = straight ahead)."""
        return self.mount_yaw + self.angle_min + self.angle_increment * np.arange(len(self.ranges))


@dataclass(frozen=True, slots=True)
class CameraIntrinsics:
    """Pinhole intrinsics, like sensor_msgs/CameraInfo's K matrix."""

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float

    @property
    def hfov(self) -> float:
        """Horizontal field of view in radians."""
        return 2.0 * math.atan2(self.width / 2.0, self.fx)

    def pixel_bearing(self, u: float) -> float:
        """Bearing (rad, positive to the left) of image column ``u`` relative to the optical axis."""
        return math.atan2(self.cx - u, self.fx)


@dataclass(frozen=True)
class RGBDFrame:
    """A colour image with its registered depth image.

    Attributes:
        stamp: Time the frame was taken (the time to fuse other sensors at).
        color: HxWx3 uint8 RGB image.
        depth: HxW float32 depth in metres along the optical axis; NaN or 0 where unknown.
        intrinsics: Pinhole intrinsics shared by colour and depth.
        camera_pose: Pose of the camera in the map frame at ``stamp`` as far as the robot knows
            it (its localisation estimate, never ground truth); x forward in the image centre.
        camera_height: Height of the optical centre above the floor in metres.
    """

    stamp: float
    color: np.ndarray
    depth: np.ndarray
    intrinsics: CameraIntrinsics
    camera_pose: Pose2D
    camera_height: float = 0.3


@dataclass(frozen=True)
class OccupancyGrid:
    """A 2D occupancy map, like nav_msgs/OccupancyGrid.

    ``data[row, col]`` is -1 (unknown), 0 (free) … 100 (occupied); row 0 is the map's
    lowest y (the image is stored bottom-up, as in ROS), cell (0, 0) has its corner at
    ``origin``.
    """

    stamp: float
    resolution: float
    origin: Pose2D
    data: np.ndarray

    def world_to_cell(self, x: float, y: float) -> tuple[int, int]:
        """Return (row, col) of the cell holding the map point (x, y); may be outside the grid."""
        return (int(math.floor((y - self.origin.y) / self.resolution)),
                int(math.floor((x - self.origin.x) / self.resolution)))

    def cell_to_world(self, row: int, col: int) -> tuple[float, float]:
        """Return the map coordinates of the centre of cell (row, col)."""
        return (self.origin.x + (col + 0.5) * self.resolution,
                self.origin.y + (row + 0.5) * self.resolution)


@dataclass(frozen=True)
class Detection:
    """One object found in an image.

    Attributes:
        label: Class name.
        score: Confidence in [0, 1].
        box: (x1, y1, x2, y2) in pixels of the image it was found in.
        mask: Optional HxW bool mask.
        attributes: Free-form extras (colour name, track id, ...).
    """

    label: str
    score: float
    box: tuple[float, float, float, float]
    mask: np.ndarray | None = None
    attributes: dict[str, Any] = field(default_factory=dict)

    @property
    def center(self) -> tuple[float, float]:
        """Centre of the box in pixels (u, v)."""
        return ((self.box[0] + self.box[2]) / 2.0, (self.box[1] + self.box[3]) / 2.0)


@dataclass(frozen=True, slots=True)
class Marker:
    """Something a run wants drawn on its top-down picture: a goal, a detection, an alarm."""

    kind: str
    x: float
    y: float
    stamp: float
    label: str = ""
