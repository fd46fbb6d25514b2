"""LogOddsGrid against hand-made scans: free along a beam, occupied at its end, unknown behind."""

from __future__ import annotations

import math

import numpy as np
import pytest

from missiontree.mapping import grid as grid_module
from missiontree.mapping.grid import FREE, OCCUPIED, UNKNOWN, LogOddsGrid
from missiontree.types import LaserScan, Pose2D

ACCEL = [pytest.param(True, id="numba"), pytest.param(False, id="numpy")]


def one_beam(rng: float, angle: float = 0.0, stamp: float = 0.0, range_max: float = 10.0) -> LaserScan:
    """A scan with a single beam at ``angle`` (robot frame)."""
    return LaserScan(stamp, angle, 0.1, 0.05, range_max, np.array([rng], np.float32))


def ring(ranges: np.ndarray, stamp: float = 0.0) -> LaserScan:
    n = len(ranges)
    return LaserScan(stamp, -math.pi, 2 * math.pi / n, 0.15, 12.0, np.asarray(ranges, np.float32))


def cell(grid: LogOddsGrid, x: float, y: float) -> int:
    r, c = grid.world_to_cell(x, y)
    return int(grid.trinary()[r, c])


@pytest.mark.parametrize("accelerate", ACCEL)
def test_beam_frees_its_path_marks_its_end_and_leaves_behind_unknown(accelerate: bool) -> None:
    """A beam along +x ending at 2 m: free before, occupied at 2 m, unknown beyond."""
    g = LogOddsGrid(0.1, 6.0, 6.0, Pose2D(-3.0, -3.0), accelerate=accelerate)
    for k in range(3):
        g.integrate(one_beam(2.0, stamp=k), Pose2D(0.05, 0.05, 0.0))
    for x in (0.15, 0.55, 1.05, 1.85):
        assert cell(g, x, 0.05) == FREE, x
    assert cell(g, 2.05, 0.05) == OCCUPIED
    assert cell(g, 2.25, 0.05) == UNKNOWN
    assert cell(g, 0.55, 0.35) == UNKNOWN  # beside the beam


@pytest.mark.parametrize("accelerate", ACCEL)
def test_one_pass_is_not_yet_free_but_one_hit_is_occupied(accelerate: bool) -> None:
    """map_server's thresholds: one free pass (p 0.35) stays unknown; one hit (p 0.7) reads occupied."""
    g = LogOddsGrid(0.1, 6.0, 6.0, Pose2D(-3.0, -3.0), accelerate=accelerate)
    g.integrate(one_beam(2.0), Pose2D(0.05, 0.05, 0.0))
    assert cell(g, 1.05, 0.05) == UNKNOWN
    assert cell(g, 2.05, 0.05) == OCCUPIED
    g.integrate(one_beam(2.0, stamp=1.0), Pose2D(0.05, 0.05, 0.0))
    assert cell(g, 1.05, 0.05) == FREE


@pytest.mark.parametrize("accelerate", ACCEL)
def test_beam_uses_pose_heading_and_mount_yaw(accelerate: bool) -> None:
    """A beam at 0 in a sensor mounted at +90 deg on a robot facing +90 deg points along -x."""
    g = LogOddsGrid(0.1, 6.0, 6.0, Pose2D(-3.0, -3.0), accelerate=accelerate)
    scan = LaserScan(0.0, 0.0, 0.1, 0.05, 10.0, np.array([1.5], np.float32), mount_yaw=math.pi / 2)
    g.integrate(scan, Pose2D(0.05, 0.05, math.pi / 2))
    assert cell(g, -1.45, 0.05) == OCCUPIED
    assert cell(g, 1.55, 0.05) == UNKNOWN


@pytest.mark.parametrize("accelerate", ACCEL)
def test_no_return_frees_to_range_max_and_marks_nothing(accelerate: bool) -> None:
    """An inf reading frees up to range_max without an obstacle; NaN is ignored."""
    g = LogOddsGrid(0.1, 10.0, 10.0, Pose2D(-5.0, -5.0), accelerate=accelerate)
    scan = LaserScan(0.0, 0.0, math.pi, 0.05, 3.0, np.array([np.inf, np.nan], np.float32))
    for k in range(2):
        g.integrate(LaserScan(k, scan.angle_min, scan.angle_increment, 0.05, 3.0, scan.ranges),
                    Pose2D(0.05, 0.05, 0.0))
    assert cell(g, 2.95, 0.05) == FREE
    assert cell(g, 3.25, 0.05) == UNKNOWN
    assert not (g.trinary() == OCCUPIED).any()
    assert cell(g, -1.0, 0.05) == UNKNOWN  # the NaN beam pointed there


def test_a_cell_hit_in_a_scan_is_not_freed_by_another_beam_of_it() -> None:
    """A wall seen at a grazing angle stays a wall: within one scan, hits win over passes."""
    g = LogOddsGrid(0.1, 6.0, 6.0, Pose2D(-3.0, -3.0))
    # beam 0 ends in cell (x 1.0-1.1); beam 1 passes through that cell and ends further on
    scan = LaserScan(0.0, 0.0, 0.0, 0.05, 10.0, np.array([1.05, 2.0], np.float32))
    g.integrate(scan, Pose2D(0.0, 0.05, 0.0))
    r, c = g.world_to_cell(1.05, 0.05)
    assert g.logodds[r, c] == pytest.approx(g.l_occ)


def test_pose_is_taken_from_the_history_at_the_scan_stamp() -> None:
    """update_from looks the pose up at the scan's own stamp, skips old scans and uncovered stamps."""
    poses = {1.0: Pose2D(0.05, 0.05, 0.0), 2.0: Pose2D(0.05, 1.05, 0.0)}
    g = LogOddsGrid(0.1, 6.0, 6.0, Pose2D(-3.0, -3.0))
    assert g.update_from(one_beam(1.0, stamp=1.0), poses.get)
    assert cell(g, 1.05, 0.05) == OCCUPIED
    assert not g.update_from(one_beam(1.0, stamp=1.0), poses.get)   # not newer
    assert not g.update_from(one_beam(1.0, stamp=5.0), poses.get)   # no pose then
    assert g.update_from(one_beam(1.0, stamp=2.0), poses.get)
    assert cell(g, 1.05, 1.05) == OCCUPIED
    assert not g.update_from(None, poses.get)


@pytest.mark.parametrize("accelerate", ACCEL)
def test_grid_grows_to_fit_a_scan_and_keeps_what_it_knew(accelerate: bool) -> None:
    """A beam reaching outside pads the grid in whole steps; old cells keep their place in the map."""
    g = LogOddsGrid(0.1, 2.0, 2.0, Pose2D(-1.0, -1.0), grow_step=1.0, accelerate=accelerate)
    g.integrate(one_beam(0.5), Pose2D(0.05, 0.05, 0.0))
    assert cell(g, 0.55, 0.05) == OCCUPIED
    backwards = LaserScan(1.0, math.pi, 0.1, 0.05, 10.0, np.array([3.0], np.float32))
    g.integrate(backwards, Pose2D(0.05, 0.05, 0.0))
    # the end at x -2.95 needs 20 more columns on the left (two whole 1 m steps), none elsewhere
    assert g.origin.x == pytest.approx(-3.0) and g.origin.y == pytest.approx(-1.0)
    assert g.shape == (20, 40)
    assert cell(g, 0.55, 0.05) == OCCUPIED
    assert cell(g, -2.95, 0.05) == OCCUPIED
    occ = g.to_occupancy(3.0)
    assert occ.stamp == 3.0 and occ.origin == g.origin and occ.data.dtype == np.int8


@pytest.mark.parametrize("accelerate", ACCEL)
def test_without_growth_beams_are_clipped_at_the_border(accelerate: bool) -> None:
    """grow=False: a beam leaving the grid frees up to the border and marks no obstacle there."""
    g = LogOddsGrid(0.1, 2.0, 2.0, Pose2D(-1.0, -1.0), grow=False, accelerate=accelerate)
    for k in range(2):
        g.integrate(one_beam(3.0, stamp=k), Pose2D(0.05, 0.05, 0.0))
    assert g.shape == (20, 20)
    assert cell(g, 0.95, 0.05) == FREE
    assert not (g.trinary() == OCCUPIED).any()


@pytest.mark.skipif(not grid_module.HAVE_NUMBA, reason="numba is not installed (extra `accel`)")
def test_numba_and_numpy_give_the_same_grid() -> None:
    """The two ray traversals update exactly the same cells by the same amounts."""
    rng = np.random.default_rng(3)
    grids = [LogOddsGrid(0.05, 20.0, 20.0, Pose2D(-10.0, -10.0), accelerate=a) for a in (True, False)]
    for k in range(5):
        ranges = rng.uniform(0.3, 11.0, 360)
        ranges[rng.random(360) < 0.1] = np.inf
        ranges[rng.random(360) < 0.05] = np.nan
        pose = Pose2D(*rng.uniform(-3.0, 3.0, 2), rng.uniform(-math.pi, math.pi))
        for g in grids:
            g.integrate(ring(ranges, stamp=k), pose)
    assert grids[0].shape == grids[1].shape and grids[0].origin == grids[1].origin
    np.testing.assert_array_equal(grids[0].logodds, grids[1].logodds)


def test_bad_settings_are_refused() -> None:
    """Impossible settings raise a ValueError saying what was expected."""
    with pytest.raises(ValueError, match="resolution"):
        LogOddsGrid(0.0)
    with pytest.raises(ValueError, match="free_thresh"):
        LogOddsGrid(free_thresh=0.7, occupied_thresh=0.65)
    with pytest.raises(ValueError, match="rotated"):
        LogOddsGrid(origin=Pose2D(0.0, 0.0, 0.3))


@pytest.mark.parametrize("accelerate", ACCEL)
@pytest.mark.parametrize("direction", [1.0, -1.0])
def test_noisy_returns_from_a_wall_on_a_cell_edge_leave_the_cell_before_it_free(accelerate: bool,
                                                                                 direction: float) -> None:
    """Noisy returns from a surface on a cell edge mark the wall's cell, not the free one before it."""
    rng = np.random.default_rng(5)
    g = LogOddsGrid(0.05, 6.0, 6.0, Pose2D(-3.0, -3.0), accelerate=accelerate)
    wall_x = 1.0  # the surface; the wall lies beyond it, seen from the robot 1 m away
    robot = Pose2D(wall_x - direction * 1.0, 0.0, 0.0 if direction > 0 else math.pi)
    angles = np.linspace(-0.3, 0.3, 61)
    for k in range(30):
        ranges = 1.0 / np.cos(angles) + rng.normal(0.0, 0.01, len(angles))
        g.integrate(LaserScan(float(k), -0.3, 0.01, 0.05, 10.0, ranges.astype(np.float32)), robot)
    for y in np.arange(-0.2, 0.2, 0.05) + 0.025:
        assert cell(g, wall_x - direction * 0.025, y) == FREE, y
        assert cell(g, wall_x + direction * 0.025, y) == OCCUPIED, y


def test_a_negative_hit_depth_is_refused() -> None:
    """hit_depth below zero raises a ValueError naming it."""
    with pytest.raises(ValueError, match="hit_depth"):
        LogOddsGrid(hit_depth=-0.01)
