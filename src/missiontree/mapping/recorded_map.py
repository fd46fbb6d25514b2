"""A log-odds map from recorded scans, and the figures that say how good it is.

:func:`build_grid` lays recorded 2-D scans (:class:`~missiontree.mapping.rawlog.RecordedScan`) into
the project's :class:`~missiontree.mapping.grid.LogOddsGrid` at given robot poses, with what a real
lidar needs:

- *invalid beams and dropouts* (MRPT's validity flag off, NaN, zero, or at the device's maximum
  range, which is how a SICK reports "no return" and how glass often reads) are skipped: they
  neither free space nor make walls, so a window or a missed return leaves the cells behind it as
  they were instead of clearing a wall or drawing one;
- *far returns* beyond ``max_range`` free space up to it and draw no wall (their angular error
  at 0.25° is over 4 cm a beam at 10 m, which smears walls seen at grazing angles).

:func:`wall_thickness` measures how thick the map's walls are (a blurred, drifted map draws one wall
two or three times side by side) and :func:`loop_gap` how far a trajectory's loop is from closing,
against a relative pose measured by registering the loop's two scans directly.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import ndimage
from scipy.spatial import cKDTree

from missiontree.mapping.grid import OCCUPIED, LogOddsGrid
from missiontree.mapping.rawlog import RecordedScan
from missiontree.mapping.scan_matching import register, relative
from missiontree.types import OccupancyGrid, Pose2D

#: The four directions a wall's thickness is measured along (row step, column step).
_DIRECTIONS = ((0, 1), (1, 0), (1, 1), (1, -1))


def build_grid(scans: Sequence[RecordedScan], poses: Sequence[Pose2D], *, resolution: float = 0.05,
               max_range: float = 15.0) -> LogOddsGrid:
    """A log-odds grid of ``scans`` laid at robot ``poses`` (invalid and max-range beams skipped).

    Args:
        scans: The recorded scans.
        poses: The robot's pose at each scan (odometry or corrected).
        resolution: Cell size (m).
        max_range: Returns beyond this free space up to it and draw no wall.
    """
    if len(scans) != len(poses):
        raise ValueError(f"expected one pose per scan, found {len(poses)} for {len(scans)} scans")
    offset = (scans[0].sensor_pose.x, scans[0].sensor_pose.y) if scans else (0.0, 0.0)
    grid = LogOddsGrid(resolution, 20.0, 20.0, max_range=max_range, sensor_offset=offset)
    for scan, pose in zip(scans, poses, strict=True):
        grid.sensor_offset = (scan.sensor_pose.x, scan.sensor_pose.y)
        grid.integrate(scan.to_laser_scan(), pose)
    return grid


@dataclass(frozen=True)
class WallThickness:
    """How thick a map's walls are, in cells.

    Attributes:
        cells: Occupied cells measured.
        thin_share: Share of occupied cells whose wall is at most ``limit`` cells thick.
        median: Median thickness (cells).
        p90: 90th percentile of the thickness (cells).
        limit: The thickness counted as thin.
    """

    cells: int
    thin_share: float
    median: float
    p90: float
    limit: int


def wall_thickness(grid: OccupancyGrid | np.ndarray, limit: int = 2) -> WallThickness:
    """Wall thickness at each occupied cell: its shortest run of occupied cells across four directions.

    A wall along x is as thick as its vertical run; a diagonal one as its run across the other
    diagonal. Counted per occupied cell, so thick stretches weigh more than by length (the share
    of thin wall is, if anything, understated).
    """
    data = grid.data if isinstance(grid, OccupancyGrid) else grid
    occupied = np.asarray(data) >= OCCUPIED if isinstance(grid, OccupancyGrid) else np.asarray(data, bool)
    if not occupied.any():
        return WallThickness(0, math.nan, math.nan, math.nan, limit)
    runs = np.full(occupied.shape, np.iinfo(np.int32).max, np.int32)
    for dr, dc in _DIRECTIONS:
        structure = np.zeros((3, 3), bool)
        structure[1, 1] = structure[1 + dr, 1 + dc] = structure[1 - dr, 1 - dc] = True
        labels, _ = ndimage.label(occupied, structure)
        lengths = np.bincount(labels.ravel())
        runs = np.minimum(runs, lengths[labels])
    values = runs[occupied]
    return WallThickness(int(occupied.sum()), float(np.mean(values <= limit)), float(np.median(values)),
                         float(np.percentile(values, 90)), limit)


@dataclass(frozen=True)
class LoopGap:
    """How far a trajectory's loop is from closed.

    Attributes:
        start: Index of the loop's first scan.
        end: Index of the scan where the robot is back beside it.
        measured: Pose of ``end`` relative to ``start`` from registering the two scans directly.
        fitness: Share of ``end``'s points within 0.2 m of ``start``'s after that registration.
        trajectory: Pose of ``end`` relative to ``start`` along the trajectory.
        translation: Distance (m) between the two relative poses' positions.
        rotation: Difference (rad) of their headings.
    """

    start: int
    end: int
    measured: Pose2D
    fitness: float
    trajectory: Pose2D
    translation: float
    rotation: float


def loop_pairs(scans: Sequence[RecordedScan], odometry: Sequence[Pose2D], guide: Sequence[Pose2D], *,
               starts: Sequence[int] = (0, 5, 10, 15, 20), anchor: int = 10, within: float = 3.5,
               min_overlap: float = 0.4) -> list[tuple[int, int, Pose2D, float]]:
    """The loop's closing pairs: (start, end, measured relative pose, overlap) for every usable pair.

    ``end`` runs over the scans of the run's second half whose ``guide`` pose (e.g. the corrected
    trajectory, used only to pick candidates and seed the registration) is within ``within`` m of
    ``start``'s; each is registered on the ``anchor`` scans from ``start`` laid at their odometry
    poses, and kept when at least ``min_overlap`` of its points agree.
    """
    pairs = []
    xy = np.array([(p.x, p.y) for p in guide])
    for start in starts:
        near = np.hypot(xy[:, 0] - xy[start, 0], xy[:, 1] - xy[start, 1]) < within
        for end in range(max(start + 1, len(guide) // 2), len(guide)):
            if not near[end]:
                continue
            pose, agree = measure_relative(scans[start:start + anchor], odometry[start:start + anchor],
                                           scans[end], relative(guide[start], guide[end]))
            if agree >= min_overlap:
                pairs.append((start, end, pose, agree))
    return pairs


def measure_relative(anchor: Sequence[RecordedScan], anchor_poses: Sequence[Pose2D], scan: RecordedScan,
                     guess: Pose2D, *, max_range: float = 20.0) -> tuple[Pose2D, float]:
    """Pose of ``scan``'s robot in ``anchor_poses[0]``'s frame, registering it on the anchor scans alone.

    The anchor is a few consecutive scans laid at their (short-range, so barely drifted) odometry
    poses: more of the place than one scan sees, so a scan taken there later from another heading
    still overlaps it. Returns the pose and the share of ``scan``'s points within 0.2 m of the
    anchor's after registration (how much the two agree).
    """
    origin = anchor_poses[0]
    pts_a = np.concatenate([s.points(relative(origin, p))[s.ranges[s.usable()] <= max_range]
                            for s, p in zip(anchor, anchor_poses, strict=True)])
    pts_b = scan.points()[scan.ranges[scan.usable()] <= max_range]
    return register(pts_a, pts_b, guess)


def endpoint_grid(scans: Sequence[RecordedScan], poses: Sequence[Pose2D], *, resolution: float = 0.05,
                  max_range: float = 15.0) -> np.ndarray:
    """Bool image of every cell some return within ``max_range`` ends in (no clearing by later beams).

    Unlike the log-odds grid, where beams through a doubled wall erase one copy, this keeps every
    copy: a drifted trajectory draws one wall several cells thick here.
    """
    pts = np.concatenate([s.points(p)[s.ranges[s.usable()] <= max_range]
                          for s, p in zip(scans, poses, strict=True)])
    cells = np.floor((pts - pts.min(axis=0)) / resolution).astype(int)
    image = np.zeros((cells[:, 1].max() + 1, cells[:, 0].max() + 1), bool)
    image[cells[:, 1], cells[:, 0]] = True
    return image


def loop_gap(scans: Sequence[RecordedScan], poses: Sequence[Pose2D], start: int, end: int,
             measured: tuple[Pose2D, float]) -> LoopGap:
    """The gap between the trajectory's relative pose of ``end`` to ``start`` and the ``measured`` one."""
    along = relative(poses[start], poses[end])
    truth, fit = measured
    yaw = math.atan2(math.sin(along.yaw - truth.yaw), math.cos(along.yaw - truth.yaw))
    return LoopGap(start, end, truth, fit, along, math.hypot(along.x - truth.x, along.y - truth.y), abs(yaw))


def pass_agreement(scans: Sequence[RecordedScan], poses: Sequence[Pose2D], *, within: float = 0.1,
                   seen: float = 1.0, max_range: float = 15.0) -> tuple[float, int]:
    """How well a run's second half lies on its first: the share of its returns within ``within`` m of one.

    Only second-half returns with a first-half return within ``seen`` m count (the places seen
    twice). Drift draws the second pass of a wall beside the first (a doubled wall, which the
    thickness figure reads as two thin walls); closing the loop lays it on top. Returns the share
    and the number of returns counted.
    """
    half = len(scans) // 2

    def cloud(part: range) -> np.ndarray:
        return np.concatenate([scans[k].points(poses[k])[scans[k].ranges[scans[k].usable()] <= max_range]
                               for k in part])

    early, late = cloud(range(half)), cloud(range(half, len(scans)))
    dist, _ = cKDTree(early).query(late, distance_upper_bound=seen)
    counted = dist[np.isfinite(dist)]
    return (float(np.mean(counted <= within)) if len(counted) else math.nan), int(len(counted))
