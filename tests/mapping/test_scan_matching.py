"""Scan matching (KISS-ICP) and the recorded-map figures: synthetic rooms, and MRPT's real faculty loop."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

from missiontree.errors import BackendUnavailableError
from missiontree.mapping.frontiers import find_frontiers
from missiontree.mapping.mrpt_datasets import find_dataset, missing_reason
from missiontree.mapping.rawlog import RecordedScan, read_rawlog, read_simplemap
from missiontree.mapping.recorded_map import (
    build_grid,
    endpoint_grid,
    loop_gap,
    loop_pairs,
    pass_agreement,
    wall_thickness,
)
from missiontree.mapping.scan_matching import (
    MatchSettings,
    correct_poses,
    refine_poses,
    relative,
    well_constrained,
)
from missiontree.semantics.rooms import segment_rooms
from missiontree.types import Pose2D

LOOP_NAME = "2006-01ENE-21-SENA_Telecom Faculty_one_loop_only.rawlog"
LOOP = find_dataset(LOOP_NAME) or Path("/nonexistent") / LOOP_NAME
MRPT_MAP = find_dataset("malaga-cs-fac-building.simplemap.gz") or Path("/nonexistent/map")


def room_scan(pose: Pose2D, half: float = 4.0, beams: int = 361) -> RecordedScan:
    """A 360° scan from ``pose`` in a square room of side 2 * half, a pillar breaking its symmetry."""
    angles = -math.pi + np.arange(beams) * 2 * math.pi / (beams - 1) + pose.yaw
    ranges = np.full(beams, np.inf)
    for i, a in enumerate(angles):
        c, s = math.cos(a), math.sin(a)
        best = math.inf
        for wall, d in ((0, half - pose.x), (0, -half - pose.x), (1, half - pose.y), (1, -half - pose.y)):
            comp = c if wall == 0 else s
            if abs(comp) > 1e-9 and d / comp > 0:
                best = min(best, d / comp)
        # pillar: a 1 m square at (2, 1.5) seen as a circle of 0.5 m
        px, py = 2.0 - pose.x, 1.5 - pose.y
        along = px * c + py * s
        miss = abs(-px * s + py * c)
        if along > 0 and miss < 0.5:
            best = min(best, along - math.sqrt(0.25 - miss**2))
        ranges[i] = best
    return RecordedScan(0.0, ranges.astype(np.float32), np.isfinite(ranges), 2 * math.pi, True, 30.0)


def test_missing_kiss_icp_names_the_extra(monkeypatch: pytest.MonkeyPatch) -> None:
    """Without KISS-ICP the matcher raises BackendUnavailableError naming the realdata extra."""
    for name in ("kiss_icp", "kiss_icp.mapping", "kiss_icp.registration"):
        monkeypatch.setitem(sys.modules, name, None)  # None in sys.modules: the import fails
    with pytest.raises(BackendUnavailableError, match=r"missiontree\[realdata\]"):
        correct_poses([], [])


def test_matching_removes_odometry_drift_in_a_room() -> None:
    """Scans of one room with odometry drifting 5 cm and 1° a step come back within 5 cm of the true path."""
    pytest.importorskip("kiss_icp", reason="KISS-ICP (the realdata extra) is not installed")
    truth = [Pose2D(-2.0 + 0.2 * i, -1.0 + 0.1 * i, 0.05 * i) for i in range(15)]
    odometry = [Pose2D(p.x + 0.05 * i, p.y - 0.03 * i, p.yaw + math.radians(1) * i)
                for i, p in enumerate(truth)]
    scans = [room_scan(p) for p in truth]
    corrected = correct_poses(scans, odometry).poses
    # the first scan anchors the frame (truth and odometry agree there)
    assert max(p.distance_to(q) for p, q in zip(corrected, truth, strict=True)) < 0.05
    assert max(p.distance_to(q) for p, q in zip(odometry, truth, strict=True)) > 0.6


def test_refinement_lays_a_displaced_scan_back_on_its_neighbours() -> None:
    """A scan 8 cm and 1.5° off among correctly placed ones of the same room is moved back within 2 cm."""
    pytest.importorskip("kiss_icp", reason="KISS-ICP (the realdata extra) is not installed")
    truth = [Pose2D(-2.0 + 0.2 * i, -1.0 + 0.1 * i, 0.05 * i) for i in range(15)]
    scans = [room_scan(p) for p in truth]
    start = list(truth)
    start[7] = Pose2D(truth[7].x + 0.06, truth[7].y - 0.05, truth[7].yaw + math.radians(1.5))
    refined = refine_poses(scans, start)
    assert refined[7].distance_to(truth[7]) < 0.02 < start[7].distance_to(truth[7])
    assert abs(refined[7].yaw - truth[7].yaw) < math.radians(0.3)
    assert max(p.distance_to(q) for p, q in zip(refined, truth, strict=True)) < 0.02


def test_a_corridor_match_is_not_well_constrained() -> None:
    """Two long parallel walls fix the pose across the corridor, not along it: the match is refused."""
    pytest.importorskip("kiss_icp", reason="KISS-ICP (the realdata extra) is not installed")
    xs = np.arange(-8.0, 8.0, 0.05)
    walls = np.concatenate([np.column_stack([xs, np.full_like(xs, y)]) for y in (1.0, -1.0)])
    near = walls[np.abs(walls[:, 0]) < 4.0]
    assert not well_constrained(walls, near, Pose2D(0.0, 0.0, 0.0), 0.3)


def test_a_room_match_is_well_constrained() -> None:
    """A room with a pillar fixes the whole pose: registrations started 0.3 m off all come back."""
    pytest.importorskip("kiss_icp", reason="KISS-ICP (the realdata extra) is not installed")
    anchor = room_scan(Pose2D(0.0, 0.0, 0.0)).points()
    seen = room_scan(Pose2D(0.5, -0.5, 0.3)).points()
    assert well_constrained(anchor, seen, Pose2D(0.5, -0.5, 0.3), 0.3)


def test_wall_thickness_reads_a_doubled_wall_as_two_cells() -> None:
    """A one-cell wall reads 1 cell thick, the same wall drawn twice side by side reads 2, a 3-cell band 3."""
    image = np.zeros((20, 40), bool)
    image[5, :] = True
    assert wall_thickness(image).median == 1
    image[6, :] = True
    assert wall_thickness(image).median == 2
    image[7, :] = True
    assert wall_thickness(image).median == 3 and wall_thickness(image).thin_share < 0.1  # only its ends


def test_wall_thickness_of_a_diagonal_wall_is_one_cell() -> None:
    """A one-cell diagonal wall is measured across the other diagonal: 1 cell, not its slanted length."""
    assert wall_thickness(np.eye(30, dtype=bool)).median == 1


def test_relative_is_the_inverse_of_compose() -> None:
    """relative(a, b) is b seen from a."""
    r = relative(Pose2D(1.0, 1.0, math.pi / 2), Pose2D(1.0, 3.0, math.pi))
    assert (r.x, r.y, r.yaw) == pytest.approx((2.0, 0.0, math.pi / 2))


@pytest.fixture(scope="module")
def real_loop():  # noqa: ANN201 - (ScanLog, Correction)
    pytest.importorskip("kiss_icp", reason="KISS-ICP (the realdata extra) is not installed")
    if not LOOP.is_file():
        pytest.skip(missing_reason(LOOP_NAME))
    log = read_rawlog(LOOP)
    return log, correct_poses(log.scans, log.poses)


@pytest.mark.realdata
def test_real_loop_closes_within_30_cm_after_loop_closure(real_loop) -> None:  # noqa: ANN001
    """On MRPT's faculty loop the pose graph closes each loop pair within 0.3 m; odometry is metres off."""
    log, corrected = real_loop
    assert corrected.closures, "no loop closure found"
    pairs = loop_pairs(log.scans, log.poses, corrected.poses)
    assert len(pairs) >= 10
    fixed = [loop_gap(log.scans, corrected.poses, s, e, (p, f)).translation for s, e, p, f in pairs]
    front = [loop_gap(log.scans, corrected.front_end, s, e, (p, f)).translation for s, e, p, f in pairs]
    raw = [loop_gap(log.scans, log.poses, s, e, (p, f)).translation for s, e, p, f in pairs]
    assert max(fixed) < 0.3
    assert max(fixed) < max(front)
    assert np.median(raw) > 2.0


@pytest.mark.realdata
def test_real_loop_closure_moves_the_path_towards_mrpts_own_map(real_loop) -> None:  # noqa: ANN001
    """The loop-closed path is nearer MRPT's own SLAM map of the loop than the scan-to-map path (median)."""
    if not MRPT_MAP.is_file():
        pytest.skip(missing_reason("malaga-cs-fac-building.simplemap.gz"))
    log, corrected = real_loop
    reference = read_simplemap(MRPT_MAP)
    index = {round(s.stamp, 4): i for i, s in enumerate(log.scans)}
    matched = [(index[round(s.stamp, 4)], p) for s, p in zip(reference.scans, reference.poses, strict=True)]
    first, origin = matched[0]

    def median_gap(poses: list[Pose2D]) -> float:
        gaps = []
        for i, ref in matched:
            ours, theirs = relative(poses[first], poses[i]), relative(origin, ref)
            gaps.append(math.hypot(ours.x - theirs.x, ours.y - theirs.y))
        return float(np.median(gaps))

    assert median_gap(corrected.poses) < 0.2 < median_gap(corrected.front_end)


@pytest.mark.realdata
def test_real_loop_walls_are_thin_after_matching(real_loop) -> None:  # noqa: ANN001
    """Returns laid at the scan-to-map poses draw walls at most 2 cells thick over 90 % of their cells."""
    log, corrected = real_loop
    assert wall_thickness(endpoint_grid(log.scans, corrected.front_end)).thin_share >= 0.9
    assert wall_thickness(endpoint_grid(log.scans, log.poses)).thin_share < 0.8


@pytest.mark.realdata
def test_real_loop_closure_lays_the_second_pass_on_the_first(real_loop) -> None:  # noqa: ANN001
    """After loop closure most returns of places seen twice lie within 10 cm of the first pass's."""
    log, corrected = real_loop
    closed, _ = pass_agreement(log.scans, corrected.poses)
    front, _ = pass_agreement(log.scans, corrected.front_end)
    raw, _ = pass_agreement(log.scans, log.poses)
    assert closed >= 0.75 and front < 0.5 and raw < 0.5


@pytest.mark.realdata
def test_real_loop_refinement_thins_the_walls_the_pose_graph_doubled(real_loop) -> None:  # noqa: ANN001
    """With each overlapping scan pair in the graph, walls are <= 2 cells over 90 % of their cells.

    The pose graph alone spreads the loop's correction evenly and blurs each pass's walls; the pair
    graph keeps scans that see the same wall consistent, so the two passes also lie within 10 cm of
    each other over 90 % of the returns seen twice (the raw odometry's figures stay far below).
    """
    log, corrected = real_loop
    assert corrected.graph and corrected.graph != corrected.poses
    refined = wall_thickness(endpoint_grid(log.scans, corrected.poses)).thin_share
    graph = wall_thickness(endpoint_grid(log.scans, corrected.graph)).thin_share
    raw = wall_thickness(endpoint_grid(log.scans, log.poses)).thin_share
    assert refined >= 0.9 > graph and raw < 0.8
    closed, _ = pass_agreement(log.scans, corrected.poses)
    graph_only, _ = pass_agreement(log.scans, corrected.graph)
    assert closed >= 0.9 > graph_only


@pytest.mark.realdata
def test_without_loop_closure_the_front_end_is_returned(real_loop) -> None:  # noqa: ANN001
    """loop_closure=False gives the scan-to-map poses alone (no closures)."""
    log, corrected = real_loop
    plain = correct_poses(log.scans[:40], log.poses[:40], MatchSettings(loop_closure=False))
    assert plain.closures == [] and plain.poses == plain.front_end
    assert max(p.distance_to(q) for p, q in zip(plain.poses, corrected.front_end[:40], strict=True)) < 1e-9


@pytest.mark.realdata
def test_real_loop_grid_has_no_walls_from_invalid_beams(real_loop) -> None:
    """The loop's log-odds map has no wall cell beyond 15 m of every pose (far, invalid beams draw none)."""
    log, corrected = real_loop
    grid = build_grid(log.scans, corrected.poses, max_range=15.0)
    occ = grid.to_occupancy()
    rows, cols = np.nonzero(occ.data == 100)
    xs = occ.origin.x + (cols + 0.5) * occ.resolution
    ys = occ.origin.y + (rows + 0.5) * occ.resolution
    sensors = np.array([p.transform(s.sensor_pose.x, s.sensor_pose.y)
                        for s, p in zip(log.scans, corrected.poses, strict=True)])
    nearest = np.min(np.hypot(xs[:, None] - sensors[None, :, 0], ys[:, None] - sensors[None, :, 1]), axis=1)
    assert len(xs) > 1000
    assert nearest.max() <= 15.0 + occ.resolution


@pytest.mark.realdata
def test_frontiers_and_rooms_run_on_the_real_map(real_loop) -> None:  # noqa: ANN001
    """Frontiers and room segmentation run on the loop's map: open edges found, at least one room."""
    log, corrected = real_loop
    occupancy = build_grid(log.scans, corrected.poses).to_occupancy()
    assert len(find_frontiers(occupancy)) > 10
    rooms = segment_rooms(occupancy, inside=(corrected.poses[0].x, corrected.poses[0].y))
    assert len(rooms.rooms) >= 1
