"""Detections projected into the map frame from depth and the camera pose at the frame's instant.

The NAIS paper takes "the median value over a small neighbourhood around the box centre" of the
aligned depth image, back-projects that pixel through the camera intrinsics and transforms the
point into the map frame (TF2 at the image's stamp). :func:`project` does the same for a
:class:`~missiontree.types.Detection` in a :class:`~missiontree.types.RGBDFrame`:

- depth: ``method="centre"`` is the paper's median of a ``window`` x ``window`` pixel square at the
  box centre; ``method="robust"`` is :func:`missiontree.perception.depth.box_depth` (floor pixels
  dropped, the nearest cluster of the box's depths: what the box's object shows even when its
  centre falls on background, e.g. between a chair's legs; for an object lower than the floor
  clearance, the centre's median);
- pose: the camera pose of the frame's instant. A frame carries it (``frame.camera_pose``, the
  localisation estimate at ``frame.stamp``); :func:`camera_pose_at` can instead take the robot's
  pose history at the stamp (``robot.pose_at``) composed with the camera mount, which is what a
  backend without a per-frame pose needs, and never the latest pose (a frame is processed after
  the robot has moved on);
- the point: lateral offset ``(cx - u) * z / fx``, height ``h - (v - cy) * z / fy``; depth sees the
  near surface, so the centre is pushed along the ray by ``surface_offset`` (by default half the
  visible width, at most ``max_surface_offset``);
- size: the box's width and height at that depth (``(x2 - x1) * z / fx``, ``(y2 - y1) * z / fy``).

Pure functions; no robot state beyond the optional pose history.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal, Protocol

import numpy as np

from missiontree.perception.depth import box_depth
from missiontree.types import Detection, Pose2D, RGBDFrame

DepthMethod = Literal["centre", "robust"]

#: Side, in pixels, of the square around the box centre whose median depth NAIS takes.
DEFAULT_WINDOW = 7


class PoseHistory(Protocol):
    """The part of the Robot protocol projection may use: the pose at a past instant."""

    def pose_at(self, stamp: float) -> Pose2D | None:
        """Pose at ``stamp`` from the recent history, None if outside it."""
        ...


@dataclass(frozen=True)
class Projection:
    """A detection placed in the map.

    Attributes:
        label: Class label.
        score: Detector confidence.
        box: (x1, y1, x2, y2) in the frame's pixels.
        position: Centre (x, y, z) in the map frame, metres.
        range: Planar distance from the camera to the measured surface point, metres.
        depth: Depth (along the optical axis) that was used, metres.
        size: (width, depth, height) estimate, metres (depth = width: a camera sees one face).
        stamp: The frame's stamp.
        camera_pose: The camera pose used.
        detection: The detection itself.
    """

    label: str
    score: float
    box: tuple[float, float, float, float]
    position: tuple[float, float, float]
    range: float
    depth: float
    size: tuple[float, float, float]
    stamp: float
    camera_pose: Pose2D
    detection: Detection

    @property
    def xy(self) -> tuple[float, float]:
        """Planar position."""
        return self.position[0], self.position[1]


def camera_pose_at(frame: RGBDFrame, robot: PoseHistory | None = None, mount: Pose2D | None = None) -> Pose2D:
    """The camera pose at the frame's instant.

    With ``robot`` and ``mount`` (the camera's pose in the robot base frame), the robot's pose
    history at ``frame.stamp`` composed with the mount; else (or when the history no longer holds
    the stamp) the pose the frame carries, which backends stamp with the same instant.
    """
    if robot is not None and mount is not None:
        base = robot.pose_at(frame.stamp)
        if base is not None:
            x, y = base.transform(mount.x, mount.y)
            return Pose2D(x, y, math.remainder(base.yaw + mount.yaw, 2 * math.pi))
    return frame.camera_pose


def centre_depth(
    depth: np.ndarray,
    box: tuple[float, float, float, float],
    window: int = DEFAULT_WINDOW,
    max_depth: float = 12.0,
) -> float:
    """Median of the valid depths in a ``window`` x ``window`` square at the box centre (NAIS).

    Returns:
        Depth in metres, ``nan`` when the square holds no valid depth.
    """
    h, w = depth.shape[:2]
    u = (box[0] + box[2]) / 2.0
    v = (box[1] + box[3]) / 2.0
    half = max(0, window // 2)
    x1, x2 = int(np.clip(math.floor(u) - half, 0, w)), int(np.clip(math.floor(u) + half + 1, 0, w))
    y1, y2 = int(np.clip(math.floor(v) - half, 0, h)), int(np.clip(math.floor(v) + half + 1, 0, h))
    patch = np.asarray(depth[y1:y2, x1:x2], dtype=float)
    valid = patch[np.isfinite(patch) & (patch > 0.0) & (patch <= max_depth)]
    return float(np.median(valid)) if valid.size else float("nan")


def _box_depth(
    frame: RGBDFrame, detection: Detection, method: DepthMethod, window: int
) -> tuple[float, float]:
    """The image column the depth was read at and the depth there (``nan``: none) by ``method``."""
    u = (detection.box[0] + detection.box[2]) / 2.0
    if method == "robust":
        reading = box_depth(frame, detection.box, mask=detection.mask)
        if reading.found:
            return (reading.column if math.isfinite(reading.column) else u), reading.depth
        # an object lower than the floor clearance (a cup): the centre's depth
        return u, centre_depth(np.asarray(frame.depth), detection.box, window)
    if method == "centre":
        return u, centre_depth(np.asarray(frame.depth), detection.box, window)
    raise ValueError(f"unknown depth method {method!r}; expected 'centre' or 'robust'")


def project(
    frame: RGBDFrame,
    detection: Detection,
    *,
    pose: Pose2D | None = None,
    method: DepthMethod = "centre",
    window: int = DEFAULT_WINDOW,
    surface_offset: float | None = None,
    max_surface_offset: float = 0.45,
) -> Projection | None:
    """Place ``detection`` in the map frame (see module docstring).

    Args:
        frame: The frame the detection was found in.
        detection: The detection.
        pose: Camera pose to use; default :func:`camera_pose_at` without a robot (the frame's own).
        method: ``centre`` (the NAIS paper) or ``robust``.
        window: Side of the centre square, pixels (``centre``).
        surface_offset: Metres added along the ray from the seen surface to the centre; default half
            the measured width, at most ``max_surface_offset``. 0 reproduces the paper.
        max_surface_offset: Cap of the default surface offset.

    Returns:
        The projection, or None when the box shows no valid depth.
    """
    k = frame.intrinsics
    camera = pose if pose is not None else frame.camera_pose
    u, z = _box_depth(frame, detection, method, window)
    if not math.isfinite(z) or z <= 0.0:
        return None
    width = max(0.0, detection.box[2] - detection.box[0]) * z / k.fx
    height = max(0.0, detection.box[3] - detection.box[1]) * z / k.fy
    offset = surface_offset if surface_offset is not None else min(width / 2.0, max_surface_offset)
    lateral = (k.cx - u) * z / k.fx
    ray = math.hypot(z, lateral)
    scale = (ray + offset) / ray if ray > 0 else 1.0
    x, y = camera.transform(z * scale, lateral * scale)
    v = (detection.box[1] + detection.box[3]) / 2.0
    elevation = frame.camera_height - (v - k.cy) * z / k.fy
    return Projection(
        label=detection.label,
        score=float(detection.score),
        box=tuple(float(b) for b in detection.box),  # type: ignore[arg-type]
        position=(x, y, max(0.0, elevation)),
        range=ray,
        depth=z,
        size=(width, width, height),
        stamp=frame.stamp,
        camera_pose=camera,
        detection=detection,
    )


def to_camera(pose: Pose2D, x: float, y: float) -> tuple[float, float]:
    """A map point in the camera frame: (forward, left) metres."""
    dx, dy = x - pose.x, y - pose.y
    c, s = math.cos(pose.yaw), math.sin(pose.yaw)
    return c * dx + s * dy, -s * dx + c * dy
