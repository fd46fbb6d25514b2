"""MRPT rawlog reader: synthetic streams written here, and MRPT's real faculty loop (mrpt-common)."""

from __future__ import annotations

import gzip
import math
import struct
from pathlib import Path

import numpy as np
import pytest

from missiontree.mapping.mrpt_archive import ArchiveError, mrpt_time_to_unix
from missiontree.mapping.mrpt_datasets import find_dataset, missing_reason
from missiontree.mapping.rawlog import compose, read_rawlog, read_simplemap
from missiontree.types import Pose2D

LOOP_NAME = "2006-01ENE-21-SENA_Telecom Faculty_one_loop_only.rawlog"
LOOP = find_dataset(LOOP_NAME) or Path("/nonexistent") / LOOP_NAME
NEEDS_LOOP = pytest.mark.skipif(not LOOP.is_file(), reason=missing_reason(LOOP_NAME))
STAMP = 127_823_078_257_133_865  # 2006-01-21 09:03:45 UTC in MRPT's 100 ns ticks since 1601


def header(name: str, version: int) -> bytes:
    return bytes([0x80 | len(name)]) + name.encode() + bytes([version])


def pose3d(x: float = 0.78, z: float = 0.3) -> bytes:
    m = np.eye(4)
    m[0, 3], m[2, 3] = x, z
    matrix = header("CMatrixD", 0) + struct.pack("<II", 4, 4) + m.astype("<f8").tobytes()
    return header("CPose3D", 1) + matrix + b"\x88\x88"


def scan2d(ranges: list[float], valid: list[bool], *, right_to_left: bool = True,
           stamp: int = STAMP) -> bytes:
    out = header("CObservation2DRangeScan", 6) + struct.pack("<f?f", math.pi, right_to_left, 80.0) + pose3d()
    out += struct.pack("<I", len(ranges)) + np.asarray(ranges, "<f4").tobytes() + bytes(int(v) for v in valid)
    out += struct.pack("<fQf", 0.01, stamp, math.radians(0.25))
    out += struct.pack("<I", 0) + struct.pack("<d", 0.0)  # no label, no pitch step
    return out + b"\x88"


def frame(*observations: bytes) -> bytes:
    body = struct.pack("<I", len(observations)) + b"".join(observations)
    return header("CSensoryFrame", 2) + body + b"\x88"


def odometry(dx: float, dy: float, dphi: float, stamp: int = STAMP) -> bytes:
    move = header("CActionRobotMovement2D", 6) + struct.pack("<i", 0)
    move += header("CPose2D", 1) + struct.pack("<ddd", dx, dy, dphi) + b"\x88"
    move += struct.pack("<i", 0) + b"\0" * (4 * 12) + struct.pack("<i", 300)  # motion model settings
    move += b"\0" + b"\0" * 8 + b"\0" + b"\0" * 8 + struct.pack("<Q", stamp) + b"\x88"
    return header("CActionCollection", 0) + struct.pack("<I", 1) + move + b"\x88"


def write(tmp_path: Path, data: bytes, zipped: bool = True) -> Path:
    path = tmp_path / "log.rawlog"
    path.write_bytes(gzip.compress(data) if zipped else data)
    return path


def test_reads_scans_with_their_fields(tmp_path: Path) -> None:
    """A scan's ranges, validity, aperture, mount pose and stamp come through as MRPT wrote them."""
    log = read_rawlog(write(tmp_path, frame(scan2d([1.0, 2.0, 81.9], [True, True, False]))))
    scan = log.scans[0]
    assert scan.ranges.tolist() == pytest.approx([1.0, 2.0, 81.9], rel=1e-6)
    assert scan.valid.tolist() == [True, True, False]
    assert scan.aperture == pytest.approx(math.pi)
    assert scan.sensor_pose.x == pytest.approx(0.78) and scan.sensor_z == pytest.approx(0.3)
    assert scan.stamp == pytest.approx(1137834225.713, abs=1e-3)


def test_beam_angles_follow_the_scan_direction(tmp_path: Path) -> None:
    """Beams run from -aperture/2 counter-clockwise, or from +aperture/2 when MRPT's rightToLeft is off."""
    log = read_rawlog(write(tmp_path, frame(scan2d([1, 1, 1], [True] * 3), scan2d([1, 1, 1], [True] * 3,
                                                                                   right_to_left=False))))
    assert log.scans[0].angles() == pytest.approx([-math.pi / 2, 0, math.pi / 2])
    assert log.scans[1].angles() == pytest.approx([math.pi / 2, 0, -math.pi / 2])


def test_invalid_beams_become_nan_in_the_laser_scan(tmp_path: Path) -> None:
    """Beams MRPT marks invalid (or at max range) reach the grid as NaN: no wall, no free space."""
    log = read_rawlog(write(tmp_path, frame(scan2d([1.0, 0.0, 81.9], [True, True, False]))))
    assert np.isnan(log.scans[0].to_laser_scan().ranges).tolist() == [False, True, True]


def test_odometry_increments_compose_into_poses(tmp_path: Path) -> None:
    """Each scan gets the pose composed from the odometry increments before it."""
    data = frame(scan2d([1.0], [True])) + odometry(1.0, 0.0, math.pi / 2) + frame(scan2d([1.0], [True]))
    data += odometry(1.0, 0.0, 0.0) + frame(scan2d([1.0], [True]))
    log = read_rawlog(write(tmp_path, data, zipped=False))
    assert [(round(p.x, 6), round(p.y, 6)) for p in log.poses] == [(0, 0), (1, 0), (1, 1)]
    assert len(log.odometry) == 2


def test_an_unknown_class_is_named_with_its_offset(tmp_path: Path) -> None:
    """An object this reader cannot parse stops it with the class name and byte offset (no length to skip)."""
    data = frame(scan2d([1.0], [True])) + header("CObservationBearingRange", 3) + b"\0" * 20
    with pytest.raises(ArchiveError, match=r"at byte [\d,]+: .*'CObservationBearingRange'"):
        read_rawlog(write(tmp_path, data))


def test_a_cut_short_file_says_where(tmp_path: Path) -> None:
    """A file that ends inside a scan says what it was reading."""
    with pytest.raises(ArchiveError, match="ends inside the ranges"):
        read_rawlog(write(tmp_path, frame(scan2d([1.0, 2.0], [True, True]))[:218]))


def test_a_missing_file_is_an_archive_error(tmp_path: Path) -> None:
    """A missing file raises ArchiveError naming it."""
    with pytest.raises(ArchiveError, match="missing.rawlog"):
        read_rawlog(tmp_path / "missing.rawlog")


def test_mrpt_time_zero_is_no_time() -> None:
    """MRPT's invalid timestamp (0) reads as NaN, not 1601."""
    assert math.isnan(mrpt_time_to_unix(0))


def test_compose_turns_the_increment_into_the_frame() -> None:
    """An increment along x after a quarter turn moves along y."""
    p = compose(Pose2D(1.0, 0.0, math.pi / 2), Pose2D(2.0, 0.0, 0.0))
    assert (p.x, p.y) == pytest.approx((1.0, 2.0))


@pytest.mark.realdata
@NEEDS_LOOP
def test_real_loop_has_225_scans_of_361_beams_over_180_degrees() -> None:
    """MRPT's faculty loop reads as 225 SICK scans of 361 beams over 180°, 80 m max range, one minute long."""
    log = read_rawlog(LOOP)
    assert len(log.scans) == 225 and len(log.odometry) == 224
    assert {len(s.ranges) for s in log.scans} == {361}
    assert log.scans[0].aperture == pytest.approx(math.pi) and log.scans[0].max_range == 80.0
    assert 55 < log.scans[-1].stamp - log.scans[0].stamp < 65
    assert all(b.stamp > a.stamp for a, b in zip(log.scans, log.scans[1:], strict=False))


@pytest.mark.realdata
@NEEDS_LOOP
def test_real_loop_invalid_beams_are_past_max_range() -> None:
    """Every beam MRPT flags invalid reads past the 80 m max range; valid ones lie within 60 m."""
    log = read_rawlog(LOOP)
    ranges = np.concatenate([s.ranges for s in log.scans])
    valid = np.concatenate([s.valid for s in log.scans])
    assert 0.8 < valid.mean() < 0.95
    assert ranges[~valid].min() > 80.0 and ranges[valid].max() < 60.0


@pytest.mark.realdata
@NEEDS_LOOP
def test_real_loop_odometry_is_a_76_m_path() -> None:
    """The odometry path is about 76 m long, the robot's laser 0.78 m ahead of its centre."""
    log = read_rawlog(LOOP)
    assert 70 < log.path_length() < 80
    assert log.scans[0].sensor_pose.x == pytest.approx(0.78, abs=1e-6)


@pytest.mark.realdata
@NEEDS_LOOP
def test_mrpt_simplemap_of_the_loop_holds_99_of_its_scans() -> None:
    """MRPT's map of the faculty (a CSimpleMap) holds 99 of the loop's scans, identical, at its own poses."""
    simple = read_simplemap(LOOP.parent / "malaga-cs-fac-building.simplemap.gz")
    log = read_rawlog(LOOP)
    by_stamp = {round(s.stamp, 4): s for s in log.scans}
    assert len(simple.scans) == 99 == len(simple.poses)
    assert all(np.array_equal(s.ranges, by_stamp[round(s.stamp, 4)].ranges) for s in simple.scans)
    assert 70 < simple.path_length() < 80


@pytest.mark.realdata
@NEEDS_LOOP
def test_old_format_simplemap_reads() -> None:
    """A simple map from before MRPT 1.0 (CSensFrameProbSequence, old headers) reads its 72 scans."""
    simple = read_simplemap(LOOP.parent / "localization_demo.simplemap.gz")
    assert len(simple.scans) == 72 and simple.scans[0].aperture == pytest.approx(math.pi)


def test_a_rawlog_is_no_simplemap(tmp_path: Path) -> None:
    """read_simplemap on a rawlog names the classes it expected and what it found."""
    with pytest.raises(ArchiveError, match="CSimpleMap or CSensFrameProbSequence, found .CSensoryFrame"):
        read_simplemap(write(tmp_path, frame(scan2d([1.0], [True]))))
