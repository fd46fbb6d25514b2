"""A recorded run as a robot: scans, poses, RGB-D frames (and maps) played at their timestamps.

The recording is an MRPT rawlog (the constructor) or a ROS 2 bag (:meth:`RecordedRobot.from_bag`).

:class:`RecordedRobot` implements the :class:`~missiontree.robot.interface.Robot` protocol over a
recording, so a mission's perception and mapping leaves run on real data without a robot:

- the clock starts at the recording's first stamp and moves only when the runner calls
  :meth:`~RecordedRobot.spin_until` (as fast as the machine allows, like the simulator: the
  recording's time is the run's time, so ``simulated`` is True);
- ``scan()``, ``rgbd()`` and ``pose()`` give the latest record whose stamp the clock has reached,
  with that stamp; after the recording's end they keep their last stamp (a sensor gone quiet);
  ``pose_at`` interpolates between the poses of the scans around a stamp and ``scan_at`` gives the
  scan nearest to it;
- the poses are the recording's odometry, or the odometry corrected by scan matching
  (``correct=True``, the ``realdata`` extra), or a bag's /tf (or /odom) track at each scan's
  stamp; ``occupancy()`` is a map given with the recording, else a bag's latest /map played, or
  else the map of the scans played so far (a log-odds grid each new scan is laid into when the map
  is asked for, as the simulator maps an unknown world), so that a mission's mapping and
  scene-graph leaves work on the recording;
- the robot cannot move: ``navigate_to`` returns a handle already REJECTED saying so, ``drive``
  with any non-zero velocity raises :class:`~missiontree.errors.BackendError` with the reason
  (a leaf that drives fails with it), ``stop`` always works and does nothing.

The lidar's mount offset on the robot (MRPT's sensor pose; 0.78 m ahead on the faculty loop's
robot) is not part of a LaserScan: it is :attr:`RecordedRobot.lidar_offset`, for a grid's
``sensor_offset``.
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Protocol

from missiontree.errors import BackendError
from missiontree.mapping.grid import LogOddsGrid
from missiontree.mapping.rawlog import ScanLog
from missiontree.mapping.ros2bag import BagRecording
from missiontree.robot.actions import RefusedAction
from missiontree.robot.sensors import SensorKind, SensorReading, UnknownSensorError, unknown_sensor_message
from missiontree.types import LaserScan, OccupancyGrid, Pose2D, PoseStamped, RGBDFrame, Tolerance


class PlayedFrame(Protocol):
    """A recorded RGB-D frame: its stamp, and the frame seen from a robot pose (MRPT's or a bag's)."""

    @property
    def stamp(self) -> float:
        """The frame's stamp."""
        ...

    def to_frame(self, camera_pose: Pose2D | None = None) -> RGBDFrame:
        """The frame as an RGBDFrame, the robot at ``camera_pose``."""
        ...


#: How far (s) from a stamp the nearest scan may be for ``scan_at``.
SCAN_GAP = 0.5
#: Cell size (m) and the farthest return that draws a wall (m) of the map built as the scans play
#: (as :func:`~missiontree.mapping.recorded_map.build_grid` builds it offline).
LIVE_MAP_RESOLUTION = 0.05
LIVE_MAP_RANGE = 15.0


class RecordedRobot:
    """A robot that plays back a recording (see the module docstring).

    Args:
        log: The recording's scans and odometry (:func:`~missiontree.mapping.rawlog.read_rawlog`).
        poses: The robot's pose at each scan (default: the log's odometry poses).
        frames: RGB-D frames to play (their own stamps; they may come from another recording).
        occupancy: A map to serve, e.g. one built from this recording (default: the map of the
            scans played so far, built as they play).
        name: The robot's name.
    """

    simulated = True

    def __init__(self, log: ScanLog, poses: Sequence[Pose2D] | None = None,
                 frames: Sequence[PlayedFrame] = (), occupancy: OccupancyGrid | None = None,
                 name: str = "recorded") -> None:
        poses = list(poses if poses is not None else log.poses)
        if len(poses) != len(log.scans):
            raise ValueError(f"expected one pose per scan, found {len(poses)} for {len(log.scans)} scans")
        stamped = [(s.stamp, s.to_laser_scan(), p, (s.sensor_pose.x, s.sensor_pose.y))
                   for s, p in zip(log.scans, poses, strict=True) if math.isfinite(s.stamp)]
        self._setup(log.source, stamped, frames, occupancy, (), name)

    @classmethod
    def from_bag(cls, bag: BagRecording, occupancy: OccupancyGrid | None = None, live_map: bool = False,
                 name: str = "recorded") -> RecordedRobot:
        """A robot playing a ROS 2 bag (:func:`~missiontree.mapping.ros2bag.read_bag`).

        Each scan gets the pose of the bag's pose track at its stamp (scans outside the track are
        left out, and so are frames outside the scans' time, where no pose is known).
        ``occupancy()`` serves ``occupancy`` when given; else the bag's /map messages as they play
        (unless ``live_map``); else the map of the scans played so far.

        Raises:
            ValueError: No scan falls within the pose track.
        """
        stamped = []
        for scan in bag.scans:
            pose = bag.pose_at(scan.stamp)
            if pose is not None:
                stamped.append((scan.stamp, scan, pose, bag.lidar_offset))
        # a frame outside the scans' poses would be placed at no known pose: left out
        first, last = (min(r[0] for r in stamped), max(r[0] for r in stamped)) if stamped else (0.0, -1.0)
        frames = [f for f in bag.frames if first <= f.stamp <= last]
        robot = cls.__new__(cls)
        robot._setup(bag.source, stamped, frames, occupancy, () if live_map else bag.maps, name)
        return robot

    def _setup(self, source: str, stamped: Sequence[tuple[float, LaserScan, Pose2D, tuple[float, float]]],
               frames: Sequence[PlayedFrame], occupancy: OccupancyGrid | None, maps: Sequence[OccupancyGrid],
               name: str) -> None:
        """Index the records: (stamp, scan, pose, lidar x/y offset) per scan, frames, maps."""
        stamped = sorted(stamped, key=lambda r: r[0])
        if not stamped:
            raise ValueError(f"{source}: expected timestamped scans to play, found none")
        self.name = name
        self.source = source
        self._stamps = [r[0] for r in stamped]
        self._scans = [r[1] for r in stamped]
        self._poses = [r[2] for r in stamped]
        self._offsets = [r[3] for r in stamped]
        self.lidar_offset = self._offsets[0]
        ordered = sorted((f for f in frames if math.isfinite(f.stamp)), key=lambda f: f.stamp)
        self._frame_stamps = [f.stamp for f in ordered]
        self._frames = ordered
        self._map = occupancy
        self._maps = sorted(maps, key=lambda g: g.stamp)
        self._map_stamps = [g.stamp for g in self._maps]
        self._grid: LogOddsGrid | None = None
        self._mapped = 0  # scans laid into the live map
        self._live: OccupancyGrid | None = None
        starts = [self._stamps[0]] + self._frame_stamps[:1]
        ends = [self._stamps[-1]] + self._frame_stamps[-1:]
        self._now = min(starts)
        self.end = max(ends)
        self.closed = False

    # -- time ----------------------------------------------------------------------------------

    def now(self) -> float:
        """The playback clock (the recording's time)."""
        return self._now

    def spin_until(self, t: float) -> None:
        """Move the clock to ``t`` (never back); records up to ``t`` become the latest."""
        self._now = max(self._now, float(t))

    def finished(self) -> bool:
        """Whether the clock has passed the recording's last record."""
        return self._now >= self.end

    # -- sensors -------------------------------------------------------------------------------

    def _last(self, stamps: list[float]) -> int:
        """Index of the last record at or before the clock, -1 before the first."""
        return bisect.bisect_right(stamps, self._now) - 1

    def pose(self) -> PoseStamped | None:
        """The pose of the latest scan played, with its stamp."""
        i = self._last(self._stamps)
        return PoseStamped(self._stamps[i], self._poses[i]) if i >= 0 else None

    def scan(self) -> LaserScan | None:
        """The latest scan played."""
        i = self._last(self._stamps)
        return self._scans[i] if i >= 0 else None

    def rgbd(self) -> RGBDFrame | None:
        """The latest RGB-D frame played (camera pose: the robot's pose at its stamp, when known)."""
        i = self._last(self._frame_stamps)
        if i < 0:
            return None
        frame = self._frames[i]
        return frame.to_frame(camera_pose=self._pose_at(frame.stamp))

    def occupancy(self) -> OccupancyGrid | None:
        """The map given with the recording, else the map of every scan played so far (None before one)."""
        if self._map is not None:
            return self._map
        if self._maps:
            i = self._last(self._map_stamps)  # the latest /map played, as a robot's map topic
            return self._maps[i] if i >= 0 else None
        last = self._last(self._stamps)
        if last < self._mapped:
            return self._live
        if self._grid is None:
            self._grid = LogOddsGrid(LIVE_MAP_RESOLUTION, 20.0, 20.0, max_range=LIVE_MAP_RANGE,
                                     sensor_offset=self._offsets[0])
        for k in range(self._mapped, last + 1):  # each scan once, at its own pose
            self._grid.sensor_offset = self._offsets[k]
            self._grid.integrate(self._scans[k], self._poses[k])
        self._mapped = last + 1
        self._live = self._grid.to_occupancy(self._stamps[last])
        return self._live

    def pose_at(self, stamp: float) -> Pose2D | None:
        """The pose at ``stamp``, interpolated between the scans around it; None outside what was played."""
        if stamp > self._now:
            return None
        return self._pose_at(stamp)

    def _pose_at(self, stamp: float) -> Pose2D | None:
        if not self._stamps or stamp < self._stamps[0] or stamp > self._stamps[-1]:
            return None
        i = bisect.bisect_left(self._stamps, stamp)
        if self._stamps[i] == stamp or i == 0:
            return self._poses[i]
        t0, t1 = self._stamps[i - 1], self._stamps[i]
        a, b = self._poses[i - 1], self._poses[i]
        k = (stamp - t0) / (t1 - t0)
        turn = math.atan2(math.sin(b.yaw - a.yaw), math.cos(b.yaw - a.yaw))
        return Pose2D(a.x + k * (b.x - a.x), a.y + k * (b.y - a.y), a.yaw + k * turn)

    def scan_at(self, stamp: float) -> LaserScan | None:
        """The played scan nearest to ``stamp`` (within 0.5 s), None otherwise."""
        last = self._last(self._stamps)
        if last < 0:
            return None
        i = bisect.bisect_left(self._stamps, stamp, hi=last + 1)
        best = min((j for j in (i - 1, i) if 0 <= j <= last), key=lambda j: abs(self._stamps[j] - stamp))
        return self._scans[best] if abs(self._stamps[best] - stamp) <= SCAN_GAP else None

    def sensor(self, name: str) -> SensorReading | None:
        """A recording has no plugin sensors: any name is unknown."""
        raise UnknownSensorError(unknown_sensor_message(name, []))

    def sensor_names(self) -> list[str]:
        """No plugin sensors."""
        return []

    def sensor_kind(self, name: str) -> SensorKind:
        """Any name is unknown."""
        raise UnknownSensorError(unknown_sensor_message(name, []))

    # -- motion: refused -----------------------------------------------------------------------

    def _refusal(self, what: str) -> str:
        return (f"the recorded robot cannot {what}: it plays back {Path(self.source).name} and its poses are "
                "the recording's; run the mission on the sim or ros2 backend to move")

    def navigate_to(self, goal: Pose2D, tolerance: Tolerance | None = None) -> RefusedAction:
        """Refused: a handle already REJECTED with the reason."""
        return RefusedAction(self._refusal(f"navigate to ({goal.x:.2f}, {goal.y:.2f})"))

    def drive(self, v: float, w: float) -> None:
        """Zero velocity is accepted (it is a stop); any other raises BackendError with the reason."""
        if v != 0.0 or w != 0.0:
            raise BackendError(self._refusal(f"drive at {v:g} m/s, {w:g} rad/s"))

    def stop(self) -> None:
        """Nothing moves: always works."""

    def close(self) -> None:
        """Nothing to release; idempotent."""
        self.closed = True
