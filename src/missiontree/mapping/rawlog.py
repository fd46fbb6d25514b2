"""MRPT rawlog files read into timestamped 2-D laser scans and odometry.

A rawlog (``.rawlog``, usually gzipped) is a sequence of MRPT serialized objects (see
:mod:`missiontree.mapping.mrpt_archive` for the encoding) in one of two layouts:

- *actions-observations*: ``CActionCollection`` (what the robot did: ``CActionRobotMovement2D``, an
  odometry increment) and ``CSensoryFrame`` (what it saw meanwhile: a list of ``CObservation*``)
  alternate, as in MRPT's ``2006-01ENE-21-SENA_Telecom Faculty_one_loop_only.rawlog``;
- *observations only*: the observations one after another, odometry as ``CObservationOdometry``
  (absolute poses).

:func:`read_rawlog` reads both into a :class:`ScanLog`: every ``CObservation2DRangeScan`` as a
:class:`RecordedScan` (ranges, MRPT's per-beam validity, the aperture and scan direction, the
sensor's mount pose, the stamp) and the robot's odometry pose at each scan, composed from the
increments (or read from the absolute odometry). Objects of any other class stop the reader with
an :class:`~missiontree.mapping.mrpt_archive.ArchiveError` naming the class, since MRPT's format
gives no length to skip them by. Field layouts follow MRPT's ``serializeFrom`` methods
(``libs/obs``: ``CObservation2DRangeScan`` versions 0 to 8, ``CActionRobotMovement2D`` 0 to 7,
``CSensoryFrame`` 0 to 2, ``CActionCollection`` 0).
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from missiontree.mapping.mrpt_archive import (
    ArchiveError,
    ArchiveReader,
    load_archive_bytes,
    mrpt_time_to_unix,
    yaw_of,
)
from missiontree.types import LaserScan, Pose2D

#: Most beams one scan may have (a 0.25° 360° lidar has 1,440).
MAX_BEAMS = 100_000
#: Classes of observation other than 2-D scans that are read and left out (their layouts are known).
_ODOMETRY_OBSERVATION = "CObservationOdometry"

__all__ = ["ArchiveError", "OdometryStep", "RecordedScan", "ScanLog", "iter_rawlog", "read_rawlog",
           "read_simplemap"]


@dataclass(frozen=True)
class RecordedScan:
    """One ``CObservation2DRangeScan`` as recorded.

    Attributes:
        stamp: Time the scan was taken (seconds since 1970; NaN when the file has none).
        ranges: float32 ranges in metres, beam 0 first.
        valid: MRPT's per-beam validity (False: no return, or out of range).
        aperture: Field of view in radians (beams spread evenly over it, ends included).
        right_to_left: Beams run counter-clockwise (MRPT's ``rightToLeft``).
        max_range: The device's maximum range (m).
        sensor_pose: The sensor's (x, y, yaw) on the robot.
        sensor_z: The sensor's height on the robot (m).
        std_error: The device's range noise (m).
        label: MRPT's sensor label.
    """

    stamp: float
    ranges: np.ndarray
    valid: np.ndarray
    aperture: float
    right_to_left: bool
    max_range: float
    sensor_pose: Pose2D = Pose2D(0.0, 0.0, 0.0)
    sensor_z: float = 0.0
    std_error: float = 0.01
    label: str = ""

    def angles(self) -> np.ndarray:
        """Angle of each beam in the sensor frame (MRPT's ``getScanAngle``)."""
        n = len(self.ranges)
        if n < 2:
            return np.zeros(n)
        step = self.aperture / (n - 1)
        start = -0.5 * self.aperture
        if not self.right_to_left:
            start, step = -start, -step
        return start + step * np.arange(n)

    def usable(self) -> np.ndarray:
        """Beams worth using: valid, finite, positive and within the device's range."""
        r = self.ranges
        return self.valid & np.isfinite(r) & (r > 0.0) & (r < self.max_range)

    def points(self, pose: Pose2D | None = None) -> np.ndarray:
        """(n, 2) end points of the usable beams, in the robot frame or in the map at robot ``pose``."""
        keep = self.usable()
        a = self.angles()[keep] + self.sensor_pose.yaw
        r = self.ranges[keep].astype(np.float64)
        x = self.sensor_pose.x + r * np.cos(a)
        y = self.sensor_pose.y + r * np.sin(a)
        if pose is not None:
            c, s = math.cos(pose.yaw), math.sin(pose.yaw)
            x, y = pose.x + c * x - s * y, pose.y + s * x + c * y
        return np.column_stack([x, y])

    def to_laser_scan(self, stamp: float | None = None) -> LaserScan:
        """The scan as a :class:`LaserScan` for the log-odds grid: invalid beams NaN (skipped, never walls).

        The sensor's x/y offset on the robot is not in LaserScan (pass it to the grid as
        ``sensor_offset``); its yaw is the mount yaw.
        """
        n = len(self.ranges)
        ranges = np.where(self.usable(), self.ranges, np.nan).astype(np.float32)
        step = self.aperture / (n - 1) if n > 1 else 0.0
        angle_min = -0.5 * self.aperture
        if not self.right_to_left:  # LaserScan runs counter-clockwise: reverse the beams
            ranges = ranges[::-1].copy()
        return LaserScan(stamp=self.stamp if stamp is None else stamp, angle_min=angle_min,
                         angle_increment=step, range_min=0.0, range_max=float(self.max_range),
                         ranges=ranges, mount_yaw=self.sensor_pose.yaw, frame_id=self.label or "laser")


@dataclass(frozen=True)
class OdometryStep:
    """An odometry reading: the increment since the previous one, or an absolute pose.

    Attributes:
        stamp: Time of the reading (seconds since 1970; NaN when the file has none).
        increment: Motion since the previous reading in the robot's frame (None for absolute readings).
        absolute: The odometry pose (None for increments).
    """

    stamp: float
    increment: Pose2D | None = None
    absolute: Pose2D | None = None


@dataclass
class ScanLog:
    """The 2-D scans of a rawlog with the robot's raw odometry pose at each.

    Attributes:
        source: The file read.
        scans: Scans in file order.
        poses: Odometry pose of the robot at each scan (the first reading at the origin).
        odometry: Every odometry reading in file order.
        skipped: Count of observations of other classes that were read and left out.
    """

    source: str
    scans: list[RecordedScan] = field(default_factory=list)
    poses: list[Pose2D] = field(default_factory=list)
    odometry: list[OdometryStep] = field(default_factory=list)
    skipped: int = 0

    def path_length(self) -> float:
        """Length (m) of the odometry path through the scans' poses."""
        xy = np.array([(p.x, p.y) for p in self.poses])
        return float(np.linalg.norm(np.diff(xy, axis=0), axis=1).sum()) if len(xy) > 1 else 0.0


def compose(a: Pose2D, b: Pose2D) -> Pose2D:
    """Pose ``b`` (in ``a``'s frame) composed onto ``a`` (MRPT's ``a + b``)."""
    c, s = math.cos(a.yaw), math.sin(a.yaw)
    yaw = math.atan2(math.sin(a.yaw + b.yaw), math.cos(a.yaw + b.yaw))
    return Pose2D(a.x + c * b.x - s * b.y, a.y + s * b.x + c * b.y, yaw)


def read_rawlog(path: str | Path) -> ScanLog:
    """Read the 2-D scans and odometry of an MRPT rawlog (gzipped or not).

    Raises:
        ArchiveError: The file cannot be read, or holds an object this reader does not know
            (the message names the class and its byte offset).
    """
    log = ScanLog(str(path))
    pose = Pose2D(0.0, 0.0, 0.0)
    for item in iter_rawlog(path):
        if isinstance(item, OdometryStep):
            log.odometry.append(item)
            if item.increment is not None:
                pose = compose(pose, item.increment)
            elif item.absolute is not None:
                pose = item.absolute
        elif isinstance(item, RecordedScan):
            log.scans.append(item)
            log.poses.append(pose)
        else:
            log.skipped += 1
    return log


def read_simplemap(path: str | Path) -> ScanLog:
    """Read an MRPT simple map (``.simplemap``, usually gzipped): its 2-D scans at the map's own poses.

    A ``CSimpleMap`` (``CSensFrameProbSequence`` before MRPT 1.0) is what MRPT's SLAM leaves: key
    frames, each a pose (the mean of a Gaussian: ``CPose3DPDFGaussian``, or ``CPosePDFGaussian`` in
    version 0) and a ``CSensoryFrame``. The poses are already corrected, so ``poses`` holds them
    (projected to the plane) and ``odometry`` stays empty.

    Raises:
        ArchiveError: The file cannot be read, is no simple map, or holds an object this reader
            does not know.
    """
    reader = ArchiveReader(load_archive_bytes(path), str(path))
    name, version, old = reader.expect_header("CSimpleMap", "CSensFrameProbSequence")
    if version not in (0, 1):
        raise reader.unknown_version(name, version, "0, 1")
    log = ScanLog(str(path))
    count = reader.u32("the key frame count")
    if count > reader.remaining:
        raise reader.error(f"expected at most {reader.remaining:,} key frames, found a count of {count:,}")
    for _ in range(count):
        pose = _pose_pdf_mean(reader) if version == 0 else _pose3d_pdf_mean(reader)
        frame, frame_version, frame_old = reader.expect_header("CSensoryFrame", "CSensorialFrame")
        for item in _sensory_frame(reader, frame_version, frame_old):
            if isinstance(item, RecordedScan):
                log.scans.append(item)
                log.poses.append(pose)
            else:
                log.skipped += 1
    reader.end(name, old)
    return log


def iter_rawlog(path: str | Path) -> Iterator[RecordedScan | OdometryStep | str]:
    """Scans and odometry readings of a rawlog in file order (other observations: their class name)."""
    reader = ArchiveReader(load_archive_bytes(path), str(path))
    while not reader.at_end():
        name, version, old = reader.header()
        if name == "CSensoryFrame":
            yield from _sensory_frame(reader, version, old)
        elif name == "CActionCollection":
            yield from _action_collection(reader, version, old)
        else:
            yield _observation(reader, name, version, old)


def _sensory_frame(reader: ArchiveReader, version: int,
                   old: bool) -> Iterator[RecordedScan | OdometryStep | str]:
    if version not in (0, 1, 2):
        raise reader.unknown_version("CSensoryFrame", version, "0 to 2")
    if version < 2:
        reader.u32("the frame's id")
    frame_stamp = mrpt_time_to_unix(reader.u64("the frame's stamp")) if version == 0 else math.nan
    count = reader.u32("the observation count")
    if count > reader.remaining:
        raise reader.error(f"expected at most {reader.remaining:,} observations, found a count of {count:,}")
    for _ in range(count):
        name, obs_version, obs_old = reader.header()
        item = _observation(reader, name, obs_version, obs_old)
        if isinstance(item, RecordedScan) and version == 0:
            item = RecordedScan(**{**item.__dict__, "stamp": frame_stamp})
        yield item
    reader.end("CSensoryFrame", old)


def _action_collection(reader: ArchiveReader, version: int, old: bool) -> Iterator[OdometryStep]:
    if version != 0:
        raise reader.unknown_version("CActionCollection", version, "0")
    count = reader.u32("the action count")
    if count > reader.remaining:
        raise reader.error(f"expected at most {reader.remaining:,} actions, found a count of {count:,}")
    for _ in range(count):
        name, act_version, act_old = reader.header()
        if name != "CActionRobotMovement2D":
            raise reader.error(f"an action of class {name!r} is not read (known: CActionRobotMovement2D)")
        step = _robot_movement_2d(reader, act_version)
        reader.end(name, act_old)
        if step is not None:
            yield step
    reader.end("CActionCollection", old)


def _observation(reader: ArchiveReader, name: str, version: int,
                 old: bool) -> RecordedScan | OdometryStep | str:
    if name == "CObservation2DRangeScan":
        scan = _range_scan_2d(reader, version)
        reader.end(name, old)
        return scan
    if name == _ODOMETRY_OBSERVATION:
        step = _odometry_observation(reader, version)
        reader.end(name, old)
        return step
    raise reader.error(f"an object of class {name!r} is not read by this reader (known: "
                       "CSensoryFrame, CActionCollection, CObservation2DRangeScan, CObservationOdometry)")


def _range_scan_2d(reader: ArchiveReader, version: int) -> RecordedScan:
    """A ``CObservation2DRangeScan`` after its header (MRPT's serializeFrom, versions 0 to 8)."""
    if not 0 <= version <= 8:
        raise reader.unknown_version("CObservation2DRangeScan", version, "0 to 8")
    aperture = reader.f32("the aperture")
    right_to_left = reader.boolean("the scan direction")
    max_range = reader.f32("the maximum range")
    sensor = reader.pose3d()
    if version < 6:
        reader.matrix()  # the sensor pose's covariance, dropped by MRPT in version 6
    n = reader.u32("the beam count")
    if n > MAX_BEAMS:
        raise reader.error(f"expected at most {MAX_BEAMS:,} beams, found {n:,}")
    ranges = reader.array("f4", n, "the ranges")
    valid = (reader.array("u1", n, "the beam validity") != 0) if version >= 1 else ranges < max_range
    std_error = reader.f32("the range noise") if version >= 2 else 0.01
    stamp = mrpt_time_to_unix(reader.u64("the stamp")) if version >= 3 else math.nan
    label = ""
    if version >= 4:
        reader.f32("the beam aperture")
    if version >= 5:
        label = reader.string("the sensor label")
        reader.f64("the pitch step")
    if version >= 7 and reader.boolean("the intensity flag"):
        reader.array("i4", n, "the intensities")
    if version >= 8:
        reader.f32("the sweep duration")
    if not (math.isfinite(aperture) and 0 < aperture <= 2 * math.pi + 1e-3 and max_range > 0):
        raise reader.error(f"expected an aperture in (0, 2 pi] and a positive range, found {aperture:g} rad "
                           f"and {max_range:g} m")
    return RecordedScan(stamp=stamp, ranges=ranges.astype(np.float32), valid=valid, aperture=aperture,
                        right_to_left=right_to_left, max_range=max_range,
                        sensor_pose=Pose2D(float(sensor[0, 3]), float(sensor[1, 3]), yaw_of(sensor)),
                        sensor_z=float(sensor[2, 3]), std_error=std_error, label=label)


def _robot_movement_2d(reader: ArchiveReader, version: int) -> OdometryStep | None:
    """A ``CActionRobotMovement2D`` after its header: the odometry increment (None if not odometry)."""
    if version in (0, 1):
        increment = _pose_pdf_mean(reader)
        method = reader.i32("the estimation method")
        if version == 1:
            reader.take(1 + 8 + 1 + 8, "the velocities and encoders")
        return OdometryStep(math.nan, increment) if method == 0 else None
    if not 2 <= version <= 7:
        raise reader.unknown_version("CActionRobotMovement2D", version, "0 to 7")
    method = reader.i32("the estimation method")
    if method == 0:  # emOdometry: the raw increment and the motion model's settings
        increment = Pose2D(*reader.pose2d())
        if version == 2:
            reader.take(44, "the motion model's settings")
        else:
            # model, a1..a4 (v >= 4; v3 has 3 dummies), min std xy/phi, particles, 4 alphas, 2 more (v >= 5)
            floats = (6 if version >= 4 else 5) + 4 + (2 if version >= 5 else 0)
            reader.take(4 + 4 * floats + 4, "the motion model's settings")
    else:
        increment = _pose_pdf_mean(reader)
    has_velocities = reader.boolean("the velocity flag")
    if version >= 7:
        if has_velocities:
            reader.take(24, "the velocities")  # TTwist2D: vx, vy, omega as doubles
    else:
        reader.take(8, "the velocities")
    has_encoders = reader.boolean("the encoder flag")
    if version < 7 or has_encoders:
        reader.take(8, "the encoder ticks")
    stamp = mrpt_time_to_unix(reader.u64("the stamp")) if version >= 6 else math.nan
    return OdometryStep(stamp, increment)


def _pose_pdf_mean(reader: ArchiveReader) -> Pose2D:
    """The mean of a ``CPosePDFGaussian`` object (the only pose PDF read)."""
    name, version, old = reader.expect_header("CPosePDFGaussian")
    mean = Pose2D(*reader.pose2d())
    if version == 0:
        reader.matrix()
    elif version in (1, 2):
        reader.take(6 * (4 if version == 1 else 8), "the covariance")
    else:
        raise reader.unknown_version(name, version, "0 to 2")
    reader.end(name, old)
    return mean


def _pose3d_pdf_mean(reader: ArchiveReader) -> Pose2D:
    """The mean of a ``CPose3DPDFGaussian`` object, projected to the plane."""
    name, version, old = reader.expect_header("CPose3DPDFGaussian")
    if version != 1:
        raise reader.unknown_version(name, version, "1")
    mean = reader.pose3d()
    reader.take(21 * 8, "the covariance")  # the 6 x 6 symmetric matrix's upper triangle
    reader.end(name, old)
    return Pose2D(float(mean[0, 3]), float(mean[1, 3]), yaw_of(mean))


def _odometry_observation(reader: ArchiveReader, version: int) -> OdometryStep:
    """A ``CObservationOdometry`` after its header: an absolute odometry pose."""
    if version not in (0, 1, 2):
        raise reader.unknown_version(_ODOMETRY_OBSERVATION, version, "0 to 2")
    pose = Pose2D(*reader.pose2d())
    reader.string("the sensor label")
    stamp = mrpt_time_to_unix(reader.u64("the stamp"))
    if version >= 1:
        has_encoders = reader.boolean("the encoder flag")
        if has_encoders or version < 2:
            reader.take(8, "the encoder ticks")
        has_velocities = reader.boolean("the velocity flag")
        if version < 2:
            reader.take(8, "the velocities")
        elif has_velocities:
            reader.take(24, "the velocities")
    return OdometryStep(stamp, absolute=pose)
