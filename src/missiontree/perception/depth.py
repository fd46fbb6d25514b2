"""Distance and map position of a detection from the depth image of its own frame.

The ``depth`` distance method: the median depth inside the box, made robust against what a box holds
besides its target — the floor at its feet, the background between the legs and around the
outline (floor pixels are dropped by their height, the nearest cluster of depths is kept, as NAIS
takes the median depth around the box centre). The position is the ray through the
target's pixels (their median column) from the camera, through the frame's intrinsics, scaled to
that depth and placed in the map with the frame's camera pose. Pure functions of
:class:`~missiontree.types.RGBDFrame` and :class:`~missiontree.types.Detection`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from missiontree.types import Detection, RGBDFrame


@dataclass(frozen=True)
class DepthReading:
    """What :func:`box_depth` measured.

    Attributes:
        depth: Depth along the optical axis in metres (``nan`` when the box held none).
        pixels: How many depth pixels were used.
        column: Median image column of those pixels: where in a loose box the target really is.
    """

    depth: float
    pixels: int
    column: float = float("nan")

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
    fraction: float = 0.9,
    max_depth: float = 12.0,
    cluster_gap: float = 0.3,
    min_share: float = 0.1,
    floor_clearance: float = 0.15,
    mask: np.ndarray | None = None,
) -> DepthReading:
    """Robust depth of what a box shows: the median of the nearest depth cluster standing off the floor.

    A detector's box holds the target and whatever is around it: the floor at its feet (nearer
    than the target at the bottom of the box), the wall behind, a door frame beside. The pixels
    that lie on the floor (less than ``floor_clearance`` above it, from their depth, row, the
    intrinsics and the camera height) are dropped; of the rest, sorted by depth, the nearest
    cluster (steps no larger than ``cluster_gap``) holding at least ``min_share`` of them is the
    target: it stands in front of its background.

    Args:
        frame: The frame the box was found in.
        box: (x1, y1, x2, y2) in pixels.
        fraction: Share of the box's width and height used, around its centre.
        max_depth: Depths beyond this are invalid.
        cluster_gap: Largest step between sorted depths inside one cluster, metres.
        min_share: Least share of the box's off-floor pixels the target's cluster must hold.
        floor_clearance: Pixels lower than this above the floor are floor (m).
        mask: Optional instance mask (HxW bool); when given, only its pixels are used.

    Returns:
        A :class:`DepthReading`; ``depth`` is ``nan`` when the region held no valid depth.
    """
    values, columns = _target_pixels(frame, box, fraction, 1, max_depth, cluster_gap, min_share,
                                     floor_clearance, mask)
    if values.size == 0:
        return DepthReading(float("nan"), 0)
    return DepthReading(float(np.median(values)), int(values.size), float(np.median(columns)))


def _target_pixels(
    frame: RGBDFrame,
    box: tuple[float, float, float, float],
    fraction: float,
    stride: int,
    max_depth: float,
    cluster_gap: float,
    min_share: float,
    floor_clearance: float,
    mask: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Depths and image columns of the pixels a box shows its target with (see :func:`box_depth`).

    Every ``stride``-th pixel of the box's centre region; floor pixels dropped; of the rest, sorted
    by depth, the nearest cluster holding at least ``min_share`` of them. Both arrays are empty
    when the region holds no valid depth.
    """
    depth = np.asarray(frame.depth)
    h, w = depth.shape[:2]
    x1, y1, x2, y2 = centre_region(box, w, h, fraction)
    step = max(1, int(stride))
    patch = depth[y1:y2:step, x1:x2:step].astype(float)
    rows, cols = np.mgrid[y1:y2:step, x1:x2:step]
    k = frame.intrinsics
    height = frame.camera_height - (rows - k.cy) * patch / k.fy
    keep = np.isfinite(patch) & (patch > 0.0) & (patch <= max_depth) & (height > floor_clearance)
    if mask is not None:
        keep &= np.asarray(mask)[y1:y2:step, x1:x2:step].astype(bool)
    values, columns = patch[keep], cols[keep].astype(float)
    if values.size == 0:
        return values, columns
    order = np.argsort(values, kind="stable")
    values, columns = values[order], columns[order]
    breaks = np.flatnonzero(np.diff(values) > cluster_gap)
    starts = np.concatenate(([0], breaks + 1))
    ends = np.concatenate((breaks + 1, [values.size]))
    need = max(1, int(min_share * values.size))
    lo, hi = 0, values.size
    for a, b in zip(starts, ends, strict=True):
        if b - a >= need:
            lo, hi = a, b
            break
    return values[lo:hi], columns[lo:hi]


def surface_points(
    frame: RGBDFrame,
    box: tuple[float, float, float, float],
    *,
    fraction: float = 0.9,
    stride: int = 3,
    max_depth: float = 12.0,
    cluster_gap: float = 0.3,
    min_share: float = 0.1,
    floor_clearance: float = 0.15,
) -> np.ndarray:
    """Map-frame (x, y) of the pixels :func:`box_depth` takes for the target: the surface the box shows.

    Same selection as :func:`box_depth` (floor dropped, the nearest depth cluster holding at least
    ``min_share`` of the rest), on every ``stride``-th pixel, each back-projected through the
    intrinsics and placed with the frame's camera pose. Views from several sides together outline
    an object's footprint, which a single view's centre cannot (depth sees only the near face).

    Returns:
        An (N, 2) float array, empty when the box holds no usable depth.
    """
    z, u = _target_pixels(frame, box, fraction, stride, max_depth, cluster_gap, min_share, floor_clearance)
    if z.size == 0:
        return np.empty((0, 2))
    k = frame.intrinsics
    lateral = (k.cx - u) * z / k.fx
    pose = frame.camera_pose
    c, s = math.cos(pose.yaw), math.sin(pose.yaw)
    return np.stack([pose.x + c * z - s * lateral, pose.y + s * z + c * lateral], axis=1)


def pixel_to_map(frame: RGBDFrame, u: float, depth: float) -> tuple[float, float]:
    """Map position of the point at image column ``u`` and optical depth ``depth`` (pinhole model)."""
    k = frame.intrinsics
    lateral_left = (k.cx - u) * depth / k.fx
    return frame.camera_pose.transform(depth, lateral_left)


def detection_position(
    frame: RGBDFrame, detection: Detection, *, fraction: float = 0.9, surface_offset: float = 0.0,
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
    u = reading.column if math.isfinite(reading.column) else detection.center[0]
    k = frame.intrinsics
    ray = math.atan2(k.cx - u, k.fx)
    rng = reading.depth / math.cos(ray) + surface_offset
    z = rng * math.cos(ray)
    x, y = pixel_to_map(frame, u, z)
    return x, y, rng
