"""The recorded backend: a recording played through the robot interface (motion refused).

``create_robot({"world": "<file>.rawlog", ...})`` reads an MRPT rawlog of 2-D scans and odometry
and returns a :class:`RecordedRobot`. Options: ``world`` (the rawlog), ``rgbd`` (an MRPT rawlog of
RGB-D frames to play as well), ``correct`` (correct the odometry by scan matching; needs the
``realdata`` extra), ``map`` (a map file to serve: any kind ``missiontree map convert`` reads),
``name``.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from missiontree.backends.recorded.robot import RecordedRobot
from missiontree.errors import ConfigError

__all__ = ["RecordedRobot", "create_robot"]

_OPTIONS = {"world", "rgbd", "correct", "map", "name", "robot", "seed", "config", "sensors"}


def create_robot(options: Mapping[str, Any] | None = None) -> RecordedRobot:
    """Build a robot that plays back a rawlog (see the module docstring).

    Raises:
        ConfigError: No rawlog named, an unknown option, or a file that does not read.
        BackendUnavailableError: ``correct`` asked for and KISS-ICP is not installed.
    """
    from missiontree.mapping.map_sources import MapSourceError, load_map_source
    from missiontree.mapping.mrpt_archive import ArchiveError
    from missiontree.mapping.mrpt_rgbd import read_rgbd_frames
    from missiontree.mapping.rawlog import read_rawlog

    options = dict(options or {})
    unknown = sorted(set(options) - _OPTIONS)
    if unknown:
        raise ConfigError(f"recorded backend: unknown options {unknown} (known: {sorted(_OPTIONS)})")
    source = options.get("world")
    if not source or not str(source).endswith(".rawlog"):
        raise ConfigError(f"recorded backend: expected --world to name an MRPT .rawlog, found {source!r}")
    try:
        log = read_rawlog(source)
        frames = read_rgbd_frames(options["rgbd"]) if options.get("rgbd") else []
        occupancy = load_map_source(options["map"]).grid if options.get("map") else None
    except (ArchiveError, MapSourceError) as exc:
        raise ConfigError(f"recorded backend: {exc}") from None
    poses = None
    if options.get("correct"):
        from missiontree.mapping.scan_matching import correct_poses

        poses = correct_poses(log.scans, log.poses).poses
    try:
        return RecordedRobot(log, poses, frames, occupancy, name=str(options.get("name") or "recorded"))
    except ValueError as exc:
        raise ConfigError(f"recorded backend: {exc}") from None
