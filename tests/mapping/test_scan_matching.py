"""Scan matching (KISS-ICP) and the recorded-map figures: synthetic rooms, and MRPT's real faculty loop."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

from missiontree.errors import BackendUnavailableError
from missiontree.mapping.frontiers import find_frontiers
from missiontree.mapping.rawlog import RecordedScan, read_rawlog
from missiontree.mapping.recorded_map import build_grid, endpoint_grid, loop_gap, loop_pairs, wall_thickness
from missiontree.mapping.scan_matching import correct_poses, relative
from missiontree.semantics.rooms import segment_rooms
from missiontree.types import Pose2D

LOOP = Path("/usr/share/mrpt/datasets/2006-01ENE-21-SENA_Telecom Faculty_one_loop_only.rawlog")


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
        pytest.skip("MRPT's datasets are not installed: apt-get install -y mrpt-common (or make setup-mrpt)")
    log = read_rawlog(LOOP)
    return log, correct_poses(log.scans, log.poses)


@pytest.mark.realdata
def test_real_loop_closes_within_30_cm_after_matching(real_loop) -> None:  # noqa: ANN001
    """On MRPT's faculty loop the corrected path closes within 0.3 m (median); raw odometry is metres off."""
    log, corrected = real_loop
    pairs = loop_pairs(log.scans, log.poses, corrected.poses)
    assert len(pairs) >= 10
    fixed = [loop_gap(log.scans, corrected.poses, s, e, (p, f)).translation for s, e, p, f in pairs]
    raw = [loop_gap(log.scans, log.poses, s, e, (p, f)).translation for s, e, p, f in pairs]
    assert np.median(fixed) < 0.3
    assert np.median(raw) > 2.0


@pytest.mark.realdata
def test_real_loop_walls_are_thin_after_matching(real_loop) -> None:  # noqa: ANN001
    """Every return laid at the corrected poses draws walls at most 2 cells thick over 90 % of their cells."""
    log, corrected = real_loop
    assert wall_thickness(endpoint_grid(log.scans, corrected.poses)).thin_share >= 0.9
    assert wall_thickness(endpoint_grid(log.scans, log.poses)).thin_share < 0.8


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
