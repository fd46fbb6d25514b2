"""Pose correction of recorded 2-D scans by scan-to-map matching (KISS-ICP's registration).

Wheel odometry drifts: on MRPT's faculty loop the same wall, seen before and after the loop, lands
about a metre apart when the scans are laid down at their odometry poses. :func:`correct_poses`
registers each scan against a map of all the scans before it (scan-to-map ICP), seeded with the
previous corrected pose composed with the odometry increment since then, so odometry is the motion
prior and the scans decide the rest. When the robot comes back to a place, its scan meets the
map's points from the first visit, which pulls the trajectory back (no pose graph, no explicit
loop closure: :func:`loop_gap` measures how far the loop still is from closed).

The ICP is KISS-ICP's (PRBonn, MIT; ``kiss-icp`` on PyPI, in the ``realdata`` extra): a voxel
hash map and a robust point-to-point ICP in C++, 0.5 MB with no heavy dependency (Open3D's ICP
would do the same job at about 400 MB). Its registration is 6-DoF; the 2-D points are given
z = 0 and the result is read back as (x, y, yaw).
"""

from __future__ import annotations

import importlib
import math
from collections.abc import Sequence
from dataclasses import dataclass
from types import ModuleType

import numpy as np
from scipy.spatial import cKDTree

from missiontree.errors import BackendUnavailableError
from missiontree.mapping.rawlog import RecordedScan, compose
from missiontree.types import Pose2D

#: The extra that installs KISS-ICP.
EXTRA = "realdata"


@dataclass(frozen=True)
class MatchSettings:
    """Settings of the scan-to-map matching.

    Attributes:
        voxel: Voxel size (m) of the map and of the scans' down-sampling.
        max_range: Beams longer than this (m) are left out of the matching (far returns at grazing
            angles are the least certain).
        kernel: Robust kernel scale (m) of the ICP (KISS-ICP's ``sigma``).
        max_correspondence: Farthest (m) a point may be from its map neighbour to count.
        max_correction: A match that moves the pose more than this (m) from its odometry prior is
            refused and the prior kept (a false match is worse than drift).
        iterations: ICP iteration cap.
    """

    voxel: float = 0.10
    max_range: float = 20.0
    kernel: float = 0.2
    max_correspondence: float = 0.6
    max_correction: float = 1.0
    iterations: int = 100


@dataclass
class Correction:
    """Corrected poses and how each match went.

    Attributes:
        poses: Corrected robot pose at each scan.
        fitness: Share of each scan's points within 0.2 m of the map after matching (NaN: first scan).
        refused: Indices of scans whose match was refused (the odometry prior was kept).
    """

    poses: list[Pose2D]
    fitness: list[float]
    refused: list[int]


def require_kiss_icp() -> ModuleType:
    """KISS-ICP's registration module; BackendUnavailableError naming the extra when it is missing."""
    try:
        importlib.import_module("kiss_icp.mapping")
        return importlib.import_module("kiss_icp.registration")
    except ImportError as exc:
        raise BackendUnavailableError(
            f"scan matching needs KISS-ICP, which is not installed ({exc}); install the extra: "
            f"pip install 'missiontree[{EXTRA}]'") from None


def relative(a: Pose2D, b: Pose2D) -> Pose2D:
    """Pose of ``b`` in ``a``'s frame (MRPT's ``b - a``)."""
    c, s = math.cos(a.yaw), math.sin(a.yaw)
    dx, dy = b.x - a.x, b.y - a.y
    yaw = math.atan2(math.sin(b.yaw - a.yaw), math.cos(b.yaw - a.yaw))
    return Pose2D(c * dx + s * dy, -s * dx + c * dy, yaw)


def pose_matrix(pose: Pose2D) -> np.ndarray:
    """4 x 4 homogeneous matrix of a planar pose."""
    m = np.eye(4)
    c, s = math.cos(pose.yaw), math.sin(pose.yaw)
    m[:2, :2] = [[c, -s], [s, c]]
    m[:2, 3] = (pose.x, pose.y)
    return m


def matrix_pose(matrix: np.ndarray) -> Pose2D:
    """Planar pose (x, y, yaw) of a 4 x 4 homogeneous matrix."""
    yaw = math.atan2(float(matrix[1, 0]), float(matrix[0, 0]))
    return Pose2D(float(matrix[0, 3]), float(matrix[1, 3]), yaw)


def _cloud(scan: RecordedScan, max_range: float) -> np.ndarray:
    """(n, 3) end points (robot frame, z = 0) of the usable beams within ``max_range``."""
    keep = scan.ranges[scan.usable()] <= max_range
    pts = scan.points()[keep]
    return np.column_stack([pts, np.zeros(len(pts))])


def _to_world(points: np.ndarray, pose: Pose2D) -> np.ndarray:
    """(n, 2) robot-frame points placed at robot ``pose``."""
    c, s = math.cos(pose.yaw), math.sin(pose.yaw)
    x, y = points[:, 0], points[:, 1]
    return np.column_stack([pose.x + c * x - s * y, pose.y + s * x + c * y])


def overlap(points: np.ndarray, pose: Pose2D, tree: cKDTree, within: float = 0.2) -> float:
    """Share of robot-frame ``points`` at ``pose`` within ``within`` m of a point of ``tree``."""
    if not len(points):
        return math.nan
    dist, _ = tree.query(_to_world(points, pose), distance_upper_bound=within)
    return float(np.mean(np.isfinite(dist)))


def correct_poses(scans: Sequence[RecordedScan], odometry: Sequence[Pose2D],
                  settings: MatchSettings | None = None) -> Correction:
    """Scan-to-map matching of ``scans`` seeded by their ``odometry`` poses; the corrected poses.

    The first scan keeps its odometry pose (it anchors the map's frame).

    Raises:
        BackendUnavailableError: KISS-ICP (the ``realdata`` extra) is not installed.
        ValueError: ``scans`` and ``odometry`` differ in length.
    """
    if len(scans) != len(odometry):
        raise ValueError(f"expected one odometry pose per scan, found {len(odometry)} for {len(scans)} scans")
    registration = require_kiss_icp()
    mapping = importlib.import_module("kiss_icp.mapping")
    cfg = settings or MatchSettings()
    icp = registration.Registration(max_num_iterations=cfg.iterations, convergence_criterion=1e-4,
                                    max_num_threads=1)
    local_map = mapping.VoxelHashMap(voxel_size=cfg.voxel, max_distance=1e4, max_points_per_voxel=20)
    poses: list[Pose2D] = []
    fitness: list[float] = []
    refused: list[int] = []
    map_points: list[np.ndarray] = []
    for i, (scan, odo) in enumerate(zip(scans, odometry, strict=True)):
        cloud = _cloud(scan, cfg.max_range)
        if i == 0 or not len(cloud):
            pose = odo if i == 0 else compose(poses[-1], relative(odometry[i - 1], odo))
            fit = math.nan
        else:
            prior = compose(poses[-1], relative(odometry[i - 1], odo))
            found = matrix_pose(icp.align_points_to_map(
                points=cloud, voxel_map=local_map, initial_guess=pose_matrix(prior),
                max_correspondance_distance=cfg.max_correspondence, kernel=cfg.kernel))
            moved = relative(prior, found)
            if math.hypot(moved.x, moved.y) > cfg.max_correction or abs(moved.yaw) > 0.35:
                refused.append(i)
                pose = prior
            else:
                pose = found
            fit = overlap(cloud[:, :2], pose, cKDTree(np.concatenate(map_points)))
        poses.append(pose)
        fitness.append(fit)
        if len(cloud):
            world = _to_world(cloud[:, :2], pose)
            local_map.add_points(np.column_stack([world, np.zeros(len(world))]))
            map_points.append(world)
    return Correction(poses, fitness, refused)
