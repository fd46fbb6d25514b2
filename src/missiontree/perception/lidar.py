"""Distance from a 2D lidar scan: the patrol-robot thesis's front cone, and a cone aimed at a detection.

Two methods, both pure functions of a :class:`~missiontree.types.LaserScan`:

- :func:`seed_front_distance` is the patrol-robot thesis's ``get_front_distance`` (Listing 3.6), reproduced
  exactly, including its assumptions: the array starts at the robot's right (index 0 = -90°) and
  the front sits at 25 % of the array whatever the scan's ``angle_min`` says; a ±15° cone taken
  by index arithmetic; centre ±5° drops readings under 0.75 m, the sides drop readings under
  0.40 m; the 10th percentile of what is left. It measures straight ahead, so a person 25° off
  the axis is missed and the wall behind is measured (the thesis §4.5.8).
- :func:`cone_distance` looks where the camera saw the target: a cone centred on the bearing of
  the detection's box, as wide as the box, using the scan's own angle layout. It returns the
  nearest compact cluster of returns inside the cone (the target in front of its background).

Bearings are radians in the robot base frame, positive to the left (counter-clockwise).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from missiontree.types import LaserScan, Pose2D, wrap_angle

#: The patrol-robot thesis's cone and masking constants (§3.9–3.11, Listing 3.6).
SEED_HALF_CONE_DEG = 15.0
SEED_CENTRE_HALF_DEG = 5.0
SEED_CENTRE_MIN_RANGE = 0.75
SEED_SIDE_MIN_RANGE = 0.40
SEED_PERCENTILE = 10.0


def seed_front_distance(scan: LaserScan) -> float:
    """The patrol-robot thesis's front distance (Listing 3.6), reproduced line by line.

    Args:
        scan: A full-circle scan in the TurtleBot 4 layout (index 0 = right, front at 25 %).

    Returns:
        The 10th percentile of the masked ±15° front cone in metres, ``inf`` when nothing is left.
    """
    ranges = np.array(scan.ranges, dtype=float)
    num_readings = len(ranges)
    if num_readings == 0:
        return float("inf")
    # 1. Geometric calibration: index 0 is the right side (-90°), the front is at 25 %.
    front_idx = int(num_readings * 0.25)
    deg_idx = num_readings / 360.0
    # 2. Cone of vision: ±15°, by index arithmetic (end exclusive, as np.arange in the seed).
    half_cone = int(SEED_HALF_CONE_DEG * deg_idx)
    indices = np.arange(front_idx - half_cone, front_idx + half_cone) % num_readings
    front_cone = ranges[indices]
    # 3. Dynamic masking: the centre ignores the chassis (< 0.75 m), the sides only < 0.40 m.
    cone_angles = np.linspace(-SEED_HALF_CONE_DEG, SEED_HALF_CONE_DEG, len(front_cone))
    mask_center = np.abs(cone_angles) < SEED_CENTRE_HALF_DEG
    mask_sides = np.abs(cone_angles) >= SEED_CENTRE_HALF_DEG
    front_cone[mask_center & (front_cone < SEED_CENTRE_MIN_RANGE)] = float("inf")
    front_cone[mask_sides & (front_cone < SEED_SIDE_MIN_RANGE)] = float("inf")
    front_cone[front_cone == 0.0] = float("inf")
    # 4. Floor horizon fix: the 10th percentile instead of the minimum.
    valid = front_cone[front_cone != float("inf")]
    if len(valid) == 0:
        return float("inf")
    return float(np.percentile(valid, SEED_PERCENTILE))


@dataclass(frozen=True)
class ConeReading:
    """What :func:`cone_distance` found.

    Attributes:
        distance: Range of the target's returns in metres (``inf`` when none).
        bearing: Mean bearing of the returns used, robot frame (rad).
        beams: How many returns were used.
    """

    distance: float
    bearing: float
    beams: int

    @property
    def found(self) -> bool:
        """True when the cone held a usable return."""
        return self.beams > 0 and math.isfinite(self.distance)


def valid_returns(scan: LaserScan, min_range: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Angles (robot frame, wrapped) and ranges of the finite returns inside the scan's limits."""
    ranges = np.asarray(scan.ranges, dtype=float)
    angles = (scan.angles() + np.pi) % (2.0 * np.pi) - np.pi
    low = scan.range_min if min_range is None else max(scan.range_min, min_range)
    ok = np.isfinite(ranges) & (ranges >= low) & (ranges <= scan.range_max) & (ranges > 0.0)
    return angles[ok], ranges[ok]


def cone_distance(
    scan: LaserScan,
    bearing: float,
    half_width: float = math.radians(4.0),
    *,
    min_range: float = 0.2,
    cluster_gap: float = 0.25,
    min_beams_for_stray: int = 8,
) -> ConeReading:
    """Distance to the nearest compact cluster of returns in a cone centred on ``bearing``.

    The cone is a detection's angular extent: a person seen by the camera at 25° is measured at
    25°, not straight ahead. Inside it the returns are sorted by range and the first cluster
    (consecutive ranges no more than ``cluster_gap`` apart) is the target; its median range is
    the distance. Background returns behind the target are ignored, and so is a single stray
    return in front of it when the cone is wide (a far person's leg may be a single beam).

    Args:
        scan: The scan taken at the moment the frame was (``robot.scan_at(frame.stamp)``).
        bearing: Centre of the cone, robot frame, rad (positive left).
        half_width: Half the cone's width, rad.
        min_range: Returns closer than this are the robot's own body.
        cluster_gap: Largest range step inside one cluster, metres.
        min_beams_for_stray: Returns in the cone from which a lone front return counts as a stray.

    Returns:
        A :class:`ConeReading`; ``distance`` is ``inf`` when the cone holds no return.
    """
    angles, ranges = valid_returns(scan, min_range)
    offset = np.abs((angles - bearing + np.pi) % (2.0 * np.pi) - np.pi)
    inside = offset <= half_width
    if not np.any(inside):
        return ConeReading(float("inf"), bearing, 0)
    cone_r, cone_a = ranges[inside], angles[inside]
    order = np.argsort(cone_r)
    cone_r, cone_a = cone_r[order], cone_a[order]
    breaks = np.flatnonzero(np.diff(cone_r) > cluster_gap)
    starts = np.concatenate(([0], breaks + 1))
    ends = np.concatenate((breaks + 1, [len(cone_r)]))
    chosen = 0
    if len(starts) > 1 and ends[0] - starts[0] == 1 and len(cone_r) >= min_beams_for_stray:
        chosen = 1  # in a wide cone a lone return in front of the rest is a stray, not the target
    lo, hi = starts[chosen], ends[chosen]
    members_r, members_a = cone_r[lo:hi], cone_a[lo:hi]
    mean_bearing = math.atan2(float(np.mean(np.sin(members_a))), float(np.mean(np.cos(members_a))))
    return ConeReading(float(np.median(members_r)), mean_bearing, int(hi - lo))


def box_bearings(
    camera_pose: Pose2D, robot_pose: Pose2D, u_left: float, u_right: float, fx: float, cx: float,
) -> tuple[float, float]:
    """Bearing of a box's centre and its half-width, in the robot frame (rad).

    Args:
        camera_pose: Camera pose in the map frame when the frame was taken.
        robot_pose: Robot pose at the same instant.
        u_left: Left column of the box.
        u_right: Right column of the box.
        fx: Focal length in pixels.
        cx: Principal point column.

    Returns:
        (bearing of the box centre, half the box's angular width).
    """
    left = math.atan2(cx - u_left, fx)
    right = math.atan2(cx - u_right, fx)
    mount = wrap_angle(camera_pose.yaw - robot_pose.yaw)
    return wrap_angle(mount + (left + right) / 2.0), abs(left - right) / 2.0


def position_from_range(robot_pose: Pose2D, bearing: float, distance: float) -> tuple[float, float]:
    """Map position of a point at ``distance`` along ``bearing`` from the robot (lidar at the base)."""
    return robot_pose.transform(distance * math.cos(bearing), distance * math.sin(bearing))


def legs_at(
    scan: LaserScan,
    bearing: float,
    distance: float,
    *,
    half_width: float = math.radians(6.0),
    tolerance: float = 0.4,
    max_width: float = 0.5,
    clearance: float = 0.4,
    step: float = 0.15,
) -> bool:
    """Whether the scan shows something leg-like near (``bearing``, ``distance``): the lidar's vote.

    A person cut by a 2D scan plane at shin height is one or two narrow segments (legs) standing
    clear of what is behind them; a wall, a door or a bench is a long continuous surface. This
    looks for a segment of consecutive returns (range steps under ``step``) that has a return
    within ``tolerance`` of ``distance`` inside ±``half_width`` of ``bearing``, is at most
    ``max_width`` metres wide and has, on at least one side, a return ``clearance`` farther away
    (the background seen past the leg). It lets surveillance drop detections that the camera made
    on a wall: independent evidence, not a second look by the same detector.

    Args:
        scan: The scan of the frame's instant.
        bearing: Expected direction, robot frame (rad).
        distance: Expected range of the person's near surface (m).
        half_width: Half-width of the search cone (rad).
        tolerance: Largest range difference from ``distance`` (m).
        max_width: Widest segment that still counts as legs (m).
        clearance: How much farther the neighbouring return must be (m).
        step: Largest range step between neighbouring beams of one segment (m).
    """
    r = np.asarray(scan.ranges, dtype=float)
    n = len(r)
    if n == 0:
        return False
    ok = np.isfinite(r) & (r >= scan.range_min) & (r <= scan.range_max)
    r = np.where(ok, r, np.inf)
    angles = (scan.angles() + np.pi) % (2.0 * np.pi) - np.pi
    offset = np.abs((angles - bearing + np.pi) % (2.0 * np.pi) - np.pi)
    seen: set[int] = set()
    for i in np.flatnonzero((offset <= half_width) & (np.abs(r - distance) <= tolerance)).tolist():
        if i in seen:
            continue
        lo = hi = i
        while (hi + 1) % n != lo and abs(r[(hi + 1) % n] - r[hi % n]) < step:
            hi += 1
        while (lo - 1) % n != hi % n and abs(r[(lo - 1) % n] - r[lo % n]) < step:
            lo -= 1
        members = [k % n for k in range(lo, hi + 1)]
        seen.update(members)
        mean = float(np.mean(r[members]))
        width = mean * len(members) * abs(scan.angle_increment)
        beyond = max(r[(lo - 1) % n], r[(hi + 1) % n]) - mean
        if width <= max_width and beyond >= clearance:
            return True
    return False
