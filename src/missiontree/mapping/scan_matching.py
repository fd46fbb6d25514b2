"""Pose correction of recorded 2-D scans by scan-to-map matching (KISS-ICP's registration).

Wheel odometry drifts: on MRPT's faculty loop the same wall, seen before and after the loop, lands
about a metre apart when the scans are laid down at their odometry poses. :func:`correct_poses`
registers each scan against a map of all the scans before it (scan-to-map ICP), seeded with the
previous corrected pose composed with the odometry increment since then, so odometry is the motion
prior and the scans decide the rest. When the robot comes back to a place, its scan meets the
map's points from the first visit, which pulls the trajectory back only part of the way; loop
closures (:func:`find_closures`) and a pose graph (:mod:`missiontree.mapping.pose_graph`) close
it, and :func:`refine_poses` solves the graph again with every overlapping pair of scans
registered directly, so scans that see the same wall agree with each other.

The ICP is KISS-ICP's (PRBonn, MIT; ``kiss-icp`` on PyPI, in the ``realdata`` extra): a voxel
hash map and a robust point-to-point ICP in C++, 0.5 MB with no heavy dependency (Open3D's ICP
would do the same job at about 400 MB). Its registration is 6-DoF; the 2-D points are given
z = 0 and the result is read back as (x, y, yaw).
"""

from __future__ import annotations

import importlib
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from types import ModuleType

import numpy as np
from scipy.spatial import cKDTree

from missiontree.errors import BackendUnavailableError
from missiontree.mapping.pose_graph import Edge, optimise
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
        loop_closure: After the scan-to-map pass, look for loop closures and solve the pose graph.
        closure_travel: A closure ties two scans at least this far apart along the path (m).
        closure_radius: ... and at most this far apart on the scan-to-map trajectory (m).
        closure_step: Every this many scans is tried as a closure's late end.
        closure_window: The early end is registered on the scans this many either side of it.
        closure_overlap: A closure is kept when this share of the late scan's points agrees
            within 0.2 m after registration.
        closure_max_shift: ... and the registration moved it at most this far from where the
            trajectory had it (m): a larger jump is more likely a false match than drift.
        closure_spread: ... and registrations started this far (m) to either side of the match
            all return to it (see :func:`well_constrained`).
        refine_rounds: After the pose graph, rounds of :func:`refine_poses` (0: none).
        refine_radius: Scans whose poses lie within this (m) of each other are registered as a pair.
        refine_max_shift: A pair whose registration moved it further than this (m) or 2° is dropped.
        refine_overlap: A pair is kept when this share of one scan's points lies within 0.1 m of
            the other's after registration.
    """

    voxel: float = 0.10
    max_range: float = 20.0
    kernel: float = 0.2
    max_correspondence: float = 0.6
    max_correction: float = 1.0
    iterations: int = 100
    loop_closure: bool = True
    closure_travel: float = 10.0
    closure_radius: float = 3.0
    closure_step: int = 2
    closure_window: int = 5
    closure_overlap: float = 0.5
    closure_max_shift: float = 1.0
    closure_spread: float = 0.3
    refine_rounds: int = 2
    refine_radius: float = 4.0
    refine_max_shift: float = 0.15
    refine_overlap: float = 0.5


@dataclass
class Correction:
    """Corrected poses and how each match went.

    Attributes:
        poses: Corrected robot pose at each scan.
        fitness: Share of each scan's points within 0.2 m of the map after matching (NaN: first scan).
        refused: Indices of scans whose match was refused (the odometry prior was kept).
        closures: Loop closures used by the pose graph (empty when none was found or asked for).
        front_end: The scan-to-map poses before the pose graph (equal to ``poses`` without closures).
        graph: The pose graph's poses (the scan-to-map ones when no closure was found) before
            :func:`refine_poses` (empty with ``loop_closure`` off).
    """

    poses: list[Pose2D]
    fitness: list[float]
    refused: list[int]
    closures: list[Edge] = field(default_factory=list)
    front_end: list[Pose2D] = field(default_factory=list)
    graph: list[Pose2D] = field(default_factory=list)


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
    """Scan-to-map matching of ``scans`` seeded by their ``odometry`` poses, then loop closure; the poses.

    The first scan keeps its odometry pose (it anchors the map's frame). With
    ``settings.loop_closure`` the scan-to-map trajectory is the first estimate of a pose graph whose
    edges are its consecutive steps and the loop closures :func:`find_closures` measures, and the
    result is polished by :func:`refine_poses` (``refine_rounds``).

    Raises:
        BackendUnavailableError: KISS-ICP (the ``realdata`` extra) is not installed.
        ValueError: ``scans`` and ``odometry`` differ in length.
    """
    if len(scans) != len(odometry):
        raise ValueError(f"expected one odometry pose per scan, found {len(odometry)} for {len(scans)} scans")
    cfg = settings or MatchSettings()
    front = _scan_to_map(scans, odometry, cfg)
    front.front_end = list(front.poses)
    if not cfg.loop_closure or len(scans) < 3:
        return front
    closures = find_closures(scans, front.poses, cfg)
    steps = [Edge(k, k + 1, relative(front.poses[k], front.poses[k + 1]), STEP_SIGMA_XY, STEP_SIGMA_YAW)
             for k in range(len(scans) - 1)]
    if closures:
        front.poses = optimise(front.poses, steps + closures)
        front.closures = closures
    front.graph = list(front.poses)
    if cfg.refine_rounds > 0:
        front.poses = refine_poses(scans, front.poses, cfg, steps + closures)
    return front


#: Standard deviations of a scan-to-map step (m, rad) and of a loop closure in the pose graph.
STEP_SIGMA_XY, STEP_SIGMA_YAW = 0.05, 0.02
CLOSURE_SIGMA_XY, CLOSURE_SIGMA_YAW = 0.10, 0.03


def _scan_to_map(scans: Sequence[RecordedScan], odometry: Sequence[Pose2D], cfg: MatchSettings) -> Correction:
    """The front end: each scan registered on the map of the scans before it."""
    registration = require_kiss_icp()
    mapping = importlib.import_module("kiss_icp.mapping")
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
            fit = overlap(cloud[:, :2], pose, cKDTree(np.concatenate(map_points))) if map_points else math.nan
        poses.append(pose)
        fitness.append(fit)
        if len(cloud):
            world = _to_world(cloud[:, :2], pose)
            local_map.add_points(np.column_stack([world, np.zeros(len(world))]))
            map_points.append(world)
    return Correction(poses, fitness, refused)



def register(anchor: np.ndarray, points: np.ndarray, guess: Pose2D) -> tuple[Pose2D, float]:
    """Pose at which robot-frame ``points`` best lie on the (n, 2) ``anchor`` points, coarse to fine.

    Returns the pose and the share of ``points`` within 0.2 m of the anchor's there.
    """
    registration = require_kiss_icp()
    mapping = importlib.import_module("kiss_icp.mapping")
    icp = registration.Registration(max_num_iterations=200, convergence_criterion=1e-5, max_num_threads=1)
    pose = guess
    cloud = np.column_stack([points, np.zeros(len(points))])
    anchor3 = np.column_stack([anchor, np.zeros(len(anchor))])
    # KISS-ICP looks for a point's neighbour only in the voxels next to its own, so the coarse stages
    # need coarse voxels: with 0.1 m voxels a start 0.3 m off finds wrong neighbours and stays put
    for distance, kernel, voxel in ((1.0, 0.3, 0.5), (0.5, 0.15, 0.25), (0.3, 0.1, 0.1)):
        voxel_map = mapping.VoxelHashMap(voxel_size=voxel, max_distance=1e4, max_points_per_voxel=20)
        voxel_map.add_points(anchor3)
        out = icp.align_points_to_map(points=cloud, voxel_map=voxel_map, initial_guess=pose_matrix(pose),
                                      max_correspondance_distance=distance, kernel=kernel)
        pose = matrix_pose(out)
    return pose, overlap(points, pose, cKDTree(anchor))


def find_closures(scans: Sequence[RecordedScan], poses: Sequence[Pose2D],
                  settings: MatchSettings | None = None) -> list[Edge]:
    """Loop closures: late scans registered directly on the early scans beside them.

    Every ``closure_step``-th scan is compared with the nearest earlier pose at least
    ``closure_travel`` m back along the path and within ``closure_radius`` m; it is registered on
    that scan and its ``closure_window`` neighbours either side, laid at their ``poses`` in the early
    scan's frame, and kept when ``closure_overlap`` of its points agree and the registration moved it
    at most ``closure_max_shift`` m.
    """
    cfg = settings or MatchSettings()
    xy = np.array([(p.x, p.y) for p in poses])
    travel = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(xy, axis=0).T))])
    found: list[Edge] = []
    for late in range(0, len(scans), max(1, cfg.closure_step)):
        early_ok = np.nonzero(travel <= travel[late] - cfg.closure_travel)[0]
        if not len(early_ok):
            continue
        dist = np.hypot(*(xy[early_ok] - xy[late]).T)
        if dist.min() > cfg.closure_radius:
            continue
        early = int(early_ok[int(np.argmin(dist))])
        window = range(max(0, early - cfg.closure_window), min(len(scans), early + cfg.closure_window + 1))
        anchor = [scans[k].points(relative(poses[early], poses[k]))[scans[k].ranges[scans[k].usable()]
                                                                    <= cfg.max_range] for k in window]
        around = range(max(0, late - cfg.closure_window), min(len(scans), late + cfg.closure_window + 1))
        points = np.concatenate([_to_world(_cloud(scans[k], cfg.max_range)[:, :2],
                                           relative(poses[late], poses[k])) for k in around])
        if not len(points) or not sum(len(a) for a in anchor):
            continue
        guess = relative(poses[early], poses[late])
        measured, agree = register(np.concatenate(anchor), points, guess)
        shift = relative(guess, measured)
        if agree < cfg.closure_overlap or math.hypot(shift.x, shift.y) > cfg.closure_max_shift:
            continue
        if well_constrained(np.concatenate(anchor), points, measured, cfg.closure_spread):
            found.append(Edge(early, late, measured, CLOSURE_SIGMA_XY, CLOSURE_SIGMA_YAW))
    return found


def well_constrained(anchor: np.ndarray, points: np.ndarray, found: Pose2D, spread: float) -> bool:
    """Whether registrations started ``spread`` m off ``found`` on each side all come back to it.

    In a corridor the scans fix the pose across the corridor but not along it: a registration started
    further along stays there, so the match is ambiguous (a false loop closure bends the whole
    trajectory). A match that every start returns to, within 0.1 m and 2°, is kept.
    """
    for dx, dy in ((spread, 0.0), (-spread, 0.0), (0.0, spread), (0.0, -spread)):
        again, _ = register(anchor, points, compose(found, Pose2D(dx, dy, 0.0)))
        moved = relative(found, again)
        if math.hypot(moved.x, moved.y) > 0.1 or abs(moved.yaw) > math.radians(2):
            return False
    return True


def refine_poses(scans: Sequence[RecordedScan], poses: Sequence[Pose2D],
                 settings: MatchSettings | None = None, kept: Sequence[Edge] = ()) -> list[Pose2D]:
    """The pose graph solved again with every pair of overlapping scans registered directly.

    The pose graph's step edges only tie consecutive scans, so it spreads the loop's correction
    evenly along the path: scans far apart in time that see the same wall then disagree by the
    correction accumulated between them (on the faculty loop each pass's returns scatter 2 cm across
    their walls instead of the scan-to-map poses' 1 cm, and the two passes meet a few centimetres
    apart). Here each scan is registered on each scan whose pose lies within ``refine_radius`` of its
    own (:func:`scan_pairs`), and the graph of those pairs plus the ``kept`` edges (steps and loop
    closures) is solved; ``refine_rounds`` times, the pairs measured again from the new poses. The
    correction then goes where the scans do not overlap (turns, doorways) and the poses of scans that
    see the same walls stay consistent with each other.
    """
    cfg = settings or MatchSettings()
    clouds = [_cloud(scan, cfg.max_range) for scan in scans]
    current = list(poses)
    for _ in range(cfg.refine_rounds):
        pairs = scan_pairs(clouds, current, cfg)
        if not pairs:
            break
        current = optimise(current, [*kept, *pairs])
    return current


#: Standard deviations (m, rad) of a scan-to-scan pair's relative pose in the refinement's graph.
PAIR_SIGMA_XY, PAIR_SIGMA_YAW = 0.02, 0.005


def scan_pairs(clouds: Sequence[np.ndarray], poses: Sequence[Pose2D], cfg: MatchSettings) -> list[Edge]:
    """Relative poses of the scan pairs within ``refine_radius`` of each other, measured by registration.

    Fine ICP (0.2 m correspondences, 5 cm kernel and voxels) seeded by ``poses``; a pair is kept when
    the registration moved it at most ``refine_max_shift`` m and 2° (this only polishes) and
    ``refine_overlap`` of the later scan's points then lie within 0.1 m of the earlier scan's.
    """
    registration = require_kiss_icp()
    mapping = importlib.import_module("kiss_icp.mapping")
    icp = registration.Registration(max_num_iterations=100, convergence_criterion=1e-5, max_num_threads=1)
    xy = np.array([(p.x, p.y) for p in poses])
    pairs: list[Edge] = []
    for i, anchor in enumerate(clouds):
        if not len(anchor):
            continue
        voxel_map = mapping.VoxelHashMap(voxel_size=0.05, max_distance=1e4, max_points_per_voxel=20)
        voxel_map.add_points(anchor)
        tree = cKDTree(anchor[:, :2])
        for j in (np.nonzero(np.hypot(*(xy[i + 1:] - xy[i]).T) <= cfg.refine_radius)[0] + i + 1).tolist():
            if not len(clouds[j]):
                continue
            guess = relative(poses[i], poses[j])
            found = matrix_pose(icp.align_points_to_map(
                points=clouds[j], voxel_map=voxel_map, initial_guess=pose_matrix(guess),
                max_correspondance_distance=0.2, kernel=0.05))
            shift = relative(guess, found)
            if math.hypot(shift.x, shift.y) > cfg.refine_max_shift or abs(shift.yaw) > math.radians(2):
                continue
            if overlap(clouds[j][:, :2], found, tree, 0.1) >= cfg.refine_overlap:
                pairs.append(Edge(i, j, found, PAIR_SIGMA_XY, PAIR_SIGMA_YAW))
    return pairs
