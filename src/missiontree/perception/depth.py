"""Distance and map position of a detection from the depth image of its own frame.

Method (c) of issue 5: the median depth inside the box's centre region, made robust against the
background that shows between a person's legs and around their outline (the nearest cluster of
depths is kept, as NAIS takes the median depth around the box centre, seed 000). The position
is the box centre's ray from the camera, through the frame's intrinsics, scaled to that depth
and placed in the map with the frame's camera pose. Pure functions of
:class:`~missiontree.types.RGBDFrame` and :class:`~missiontree.types.Detection`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from missiontree.types import Detection, Pose2D, RGBDFrame


@dataclass(frozen=True)
class DepthReading:
    """What :func:`box_depth` measured.

    Attributes:
        depth: Depth along the optical axis in metres (``nan`` when the box held none).
        pixels: How many depth pixels were used.
    """

    depth: float
    pixels: int

    @property
    def found(self) -> bool:
        """True when the box held usable depth."""
        return self.pixels > 0 and math.isfinite(self.depth)


def centre_region(
    box: tuple[float, float, float, float], width: int, height: int, fraction: float = 0.5,
) -> tuple[int, int, int, int]:
    """Integer pixel bounds (x1, y1, x2, y2), end-exclusive, of the central ``fraction`` of a box.

    The box is clipped to the image first (a person entering at the edge is boxed up to the
    edge); the region always holds at least one pixel of a box that overlaps the image, and is
    empty (x1 == x2) for a box entirely outside it.
    """
    x1, x2 = (float(np.clip(v, 0, width)) for v in (box[0], box[2]))
    y1, y2 = (float(np.clip(v, 0, height)) for v in (box[1], box[3]))
    cx, cy = (x1 + x2) / 2.0, (y1 + y2) / 2.0
    hw, hh = (x2 - x1) * fraction / 2.0, (y2 - y1) * fraction / 2.0
    left = int(np.clip(math.floor(cx - hw), 0, width))
    right = int(np.clip(math.ceil(cx + hw), 0, width))
    top = int(np.clip(math.floor(cy - hh), 0, height))
    bottom = int(np.clip(math.ceil(cy + hh), 0, height))
    if right == left and 0 <= cx < width:
        left, right = int(cx), int(cx) + 1
    if bottom == top and 0 <= cy < height:
        top, bottom = int(cy), int(cy) + 1
    return left, top, right, bottom


def box_depth(
    frame: RGBDFrame,
    box: tuple[float, float, float, float],
    *,
    fraction: float = 0.5,
    max_depth: float = 12.0,
    cluster_gap: float = 0.3,
    mask: np.ndarray | None = None,
) -> DepthReading:
    """Robust depth of what a box shows: the median of the nearest depth cluster in its centre.

    Args:
        frame: The frame the box was found in.
        box: (x1, y1, x2, y2) in pixels.
        fraction: Share of the box's width and height that forms the centre region.
        max_depth: Depths beyond this are invalid.
        cluster_gap: Largest step between sorted depths inside one cluster, metres.
        mask: Optional instance mask (HxW bool); when given, only its pixels are used.

    Returns:
        A :class:`DepthReading`; ``depth`` is ``nan`` when the region held no valid depth.
    """
    depth = np.asarray(frame.depth)
    h, w = depth.shape[:2]
    x1, y1, x2, y2 = centre_region(box, w, h, fraction)
    patch = depth[y1:y2, x1:x2].astype(float)
    if mask is not None:
        patch = patch[np.asarray(mask)[y1:y2, x1:x2].astype(bool)]
    values = patch[np.isfinite(patch) & (patch > 0.0) & (patch <= max_depth)].ravel()
    if values.size == 0:
        return DepthReading(float("nan"), 0)
    values = np.sort(values)
    breaks = np.flatnonzero(np.diff(values) > cluster_gap)
    # The target stands in front of its background: keep the nearest cluster that holds at least
    # a tenth of the pixels (smaller ones are speckle or the floor's near edge).
    starts = np.concatenate(([0], breaks + 1))
    ends = np.concatenate((breaks + 1, [values.size]))
    floor_size = max(1, values.size // 10)
    for lo, hi in zip(starts, ends, strict=True):
        if hi - lo >= floor_size:
            return DepthReading(float(np.median(values[lo:hi])), int(hi - lo))
    return DepthReading(float(np.median(values)), int(values.size))


def pixel_to_map(frame: RGBDFrame, u: float, depth: float) -> tuple[float, float]:
    """Map position of the point at image column ``u`` and optical depth ``depth`` (pinhole model)."""
    k = frame.intrinsics
    lateral_left = (k.cx - u) * depth / k.fx
    return frame.camera_pose.transform(depth, lateral_left)


def detection_position(
    frame: RGBDFrame, detection: Detection, *, fraction: float = 0.5, surface_offset: float = 0.0,
) -> tuple[float, float, float] | None:
    """Map position of a detection and its range from the camera, from the frame's depth.

    Args:
        frame: The frame the detection was found in (its camera pose and intrinsics are used).
        detection: The detection.
        fraction: Share of the box forming the centre region.
        surface_offset: Added to the measured range along the ray: depth sees the target's near
            surface, the position wanted is its centre (about a body's half-depth for a person).

    Returns:
        (x, y, range from the camera in metres), or None when the box held no valid depth.
    """
    reading = box_depth(frame, detection.box, fraction=fraction, mask=detection.mask)
    if not reading.found:
        return None
    u = detection.center[0]
    k = frame.intrinsics
    ray = math.atan2(k.cx - u, k.fx)
    rng = reading.depth / math.cos(ray) + surface_offset
    z = rng * math.cos(ray)
    x, y = pixel_to_map(frame, u, z)
    return x, y, rng


def range_from(pose: Pose2D, x: float, y: float) -> float:
    """Planar distance from ``pose`` to the map point (x, y)."""
    return math.hypot(x - pose.x, y - pose.y)
