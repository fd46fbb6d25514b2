"""Where is the person in this frame? Bearing, distance and map position by a chosen method.

The three distance methods, all fed with the sensor data *of the instant the frame was taken*
(``robot.pose_at(frame.stamp)``, ``robot.scan_at(frame.stamp)``) unless told to use the latest
data, which is what the patrol-robot thesis did and why its distances drifted by Δd = v·T:

- ``seed``: the thesis's ±15° front cone (:func:`~missiontree.perception.lidar.seed_front_distance`);
  it assumes the person is straight ahead.
- ``cone``: a lidar cone on the bearing and width of the person's box, reaching past an image
  border that cuts the box (:func:`~missiontree.perception.lidar.cone_distance`).
- ``depth``: the robust median depth inside the box, projected through the frame's intrinsics
  and camera pose (:func:`~missiontree.perception.depth.detection_position`); when the box holds
  no depth (a person beyond the depth range), the cone is used instead. When the nearest thing
  the box shows is low (nothing of it higher than UPPER_BODY above the floor) and not cut by the
  image's top edge, it is furniture in front of the person (a sofa, a table, a plant hiding their
  legs), not the person: the box is then read from its pixels higher than UPPER_BODY (the chest
  and head). A person too near for the camera to see their chest reaches the image's top edge
  and is read from the whole box, as is everyone the box shows unhidden. (A person sitting lower
  than UPPER_BODY behind furniture is read from what stands behind them.)
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np

from missiontree.perception.depth import box_depth, centre_region, pixel_to_map
from missiontree.perception.lidar import box_bearings, cone_distance, position_from_range, seed_front_distance
from missiontree.robot.interface import Robot
from missiontree.types import Detection, LaserScan, Pose2D, RGBDFrame

Method = Literal["seed", "cone", "depth"]
FuseAt = Literal["frame", "answer"]

#: Narrowest cone used around a box, rad (a person far away is a few beams wide).
MIN_CONE_HALF_WIDTH = math.radians(1.5)
#: How far past the image border the lidar cone looks when a box is cut by the border, rad.
EDGE_EXTENSION = math.radians(20.0)
#: The depth method reads a box from what shows higher than this above the floor (m): an adult's
#: chest and head, above most furniture.
UPPER_BODY = 1.0
#: Least depth pixels above UPPER_BODY for the upper body to be read (else the whole box is).
MIN_UPPER_PIXELS = 12


@dataclass(frozen=True)
class Measurement:
    """A person located from one frame.

    Attributes:
        stamp: Time of the sensor data used.
        robot_pose: Robot pose at that time.
        bearing: Bearing of the person, robot frame (rad, positive left).
        distance: Distance from the robot (m), ``inf`` when nothing was measured.
        position: Map position, None when the distance is unknown.
        method: The method that produced the distance (``depth`` may fall back to ``cone``).
    """

    stamp: float
    robot_pose: Pose2D
    bearing: float
    distance: float
    position: tuple[float, float] | None
    method: str


def measure(
    robot: Robot,
    frame: RGBDFrame,
    detection: Detection | None,
    method: Method,
    *,
    fuse_at: FuseAt = "frame",
    surface_offset: float = 0.0,
) -> Measurement | None:
    """Locate the person of ``detection`` (or, with no box, straight ahead) in ``frame``.

    Args:
        robot: Source of the pose and scan (history lookups by the frame's stamp).
        frame: The frame the person was seen in.
        detection: The person's box; None means "somewhere in the image" (the thesis's case).
        method: ``seed``, ``cone`` or ``depth``.
        fuse_at: ``frame`` uses the data of the frame's instant; ``answer`` the latest (the thesis's).
        surface_offset: Added to lidar and depth ranges: sensors see the near surface of the
            person, the position wanted is their centre (ignored by ``seed``, reproduced as is).

    Returns:
        The measurement, or None when the pose or scan it needs is not available.
    """
    stamp, pose, scan = _pose_and_scan(robot, frame, fuse_at, with_scan=method != "depth")
    if pose is None:
        return None
    k = frame.intrinsics
    if detection is not None:
        bearing, half = box_bearings(frame.camera_pose, pose, detection.box[0], detection.box[2], k.fx, k.cx)
        cone_bearing, cone_half = _cone_of(bearing, half, detection, k.width)
    else:
        bearing, half = 0.0, math.radians(15.0)
        cone_bearing, cone_half = bearing, half
    if method == "seed":
        if scan is None:
            return None
        distance = seed_front_distance(scan)
        position = position_from_range(pose, 0.0, distance) if math.isfinite(distance) else None
        return Measurement(stamp, pose, 0.0, distance, position, "seed")
    if method == "depth" and detection is not None:
        located = person_position(frame, detection, surface_offset)
        if located is not None:
            x, y, _ = located
            distance = math.hypot(x - pose.x, y - pose.y)
            return Measurement(stamp, pose, pose.bearing_to(x, y), distance, (x, y), "depth")
        scan = robot.scan_at(stamp) if fuse_at == "frame" else robot.scan()
    if scan is None:
        return None
    reading = cone_distance(scan, cone_bearing, max(cone_half, MIN_CONE_HALF_WIDTH))
    if not reading.found:
        return Measurement(stamp, pose, bearing, math.inf, None, "cone")
    distance = reading.distance + surface_offset
    return Measurement(stamp, pose, reading.bearing, distance,
                       position_from_range(pose, reading.bearing, distance), "cone")


def _pose_and_scan(robot: Robot, frame: RGBDFrame, fuse_at: FuseAt, with_scan: bool
                   ) -> tuple[float, Pose2D | None, LaserScan | None]:
    """(stamp, pose, scan) of the frame's instant (``fuse_at="frame"``) or the latest (``"answer"``)."""
    if fuse_at == "frame":
        return frame.stamp, robot.pose_at(frame.stamp), robot.scan_at(frame.stamp) if with_scan else None
    stamped = robot.pose()
    return robot.now(), stamped.pose if stamped is not None else None, robot.scan() if with_scan else None


def person_position(frame: RGBDFrame, detection: Detection,
                    surface_offset: float = 0.0) -> tuple[float, float, float] | None:
    """Map position and range of a person's box from the frame's depth (None: the box held none).

    As :func:`~missiontree.perception.depth.detection_position`, except that a box whose nearest
    thing is low furniture (see the module docstring) is read from its pixels above UPPER_BODY.
    """
    reading = box_depth(frame, detection.box, mask=detection.mask)
    if not reading.found:
        return None
    if _hidden_by_something_low(frame, detection, reading.depth):
        upper = box_depth(frame, detection.box, floor_clearance=UPPER_BODY, mask=detection.mask)
        if upper.found and upper.pixels >= MIN_UPPER_PIXELS and upper.depth > reading.depth:
            reading = upper
    k = frame.intrinsics
    u = reading.column if math.isfinite(reading.column) else detection.center[0]
    ray = math.atan2(k.cx - u, k.fx)
    rng = reading.depth / math.cos(ray) + surface_offset
    x, y = pixel_to_map(frame, u, rng * math.cos(ray))
    return x, y, rng


def _hidden_by_something_low(frame: RGBDFrame, detection: Detection, depth: float) -> bool:
    """Whether the nearest thing in the box, at ``depth`` (along the optical axis), is lower than a chest.

    Its pixels (within 0.3 m of that depth, in the box's central 90 %) all lie below UPPER_BODY
    and below the top of the camera's view at that depth (less 0.1 m), and the box is not cut by
    the image's top edge: a person too near for the camera to see their chest fills the view to
    its top, whatever box the detector drew.
    """
    if detection.box[1] <= 1.0:
        return False
    image = np.asarray(frame.depth, dtype=float)
    h, w = image.shape[:2]
    x1, y1, x2, y2 = centre_region(detection.box, w, h, 0.9)
    patch = image[y1:y2, x1:x2]
    near = np.isfinite(patch) & (np.abs(patch - depth) <= 0.3)
    if not near.any():
        return False
    rows = np.arange(y1, y2, dtype=float)[:, None]
    k = frame.intrinsics
    heights = frame.camera_height - (rows - k.cy) * patch / k.fy
    top, view_top = float(np.max(heights[near])), frame.camera_height + (k.cy + 0.5) * depth / k.fy
    return top < UPPER_BODY and top < view_top - 0.1


def _cone_of(bearing: float, half: float, detection: Detection, width: int) -> tuple[float, float]:
    """The lidar cone for a box: the box's extent, reaching past an image border that cuts the box.

    A person standing at the edge of the camera's view is boxed only up to the border; the rest
    of them, often the part nearest the robot, lies beyond it where only the lidar sees.
    """
    left, right = bearing + half, bearing - half
    if detection.box[0] <= 1.0:
        left += EDGE_EXTENSION
    if detection.box[2] >= width - 1.0:
        right -= EDGE_EXTENSION
    return (left + right) / 2.0, (left - right) / 2.0
