"""The recorded backend: a recording played through the robot interface (motion refused).

``create_robot({"world": "<file>.rawlog", ...})`` reads an MRPT rawlog of 2-D scans and odometry
and returns a :class:`RecordedRobot`; ``"world": "<file>.mcap"`` reads a ROS 2 bag (rosbag2's MCAP
layout, TurtleBot 4 topics: :mod:`missiontree.mapping.ros2bag`, the ``realdata`` extra) with its
scans, /tf poses, RGB-D frames and /map. Options: ``world`` (the recording), ``rgbd`` (an MRPT
rawlog of RGB-D frames to play as well), ``correct`` (correct the odometry by scan matching; needs
the ``realdata`` extra), ``map`` (a map file to serve: any kind ``missiontree map convert`` reads),
``live_map`` (a bag: serve the map of the scans played instead of the bag's /map),
``frame_rate`` (a bag: images kept a second at most, default 5), ``namespace`` (a bag from a
namespaced robot: ``/robot1`` reads ``/robot1/scan``...), ``name``. From the command line they go
in the ``--config`` file's ``recorded:`` mapping (``world`` is ``--world``).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from missiontree.backends.recorded.robot import RecordedRobot
from missiontree.errors import ConfigError

__all__ = ["RecordedRobot", "create_robot"]

_OPTIONS = {"world", "rgbd", "correct", "map", "live_map", "frame_rate", "namespace", "name", "robot", "seed",
            "config", "sensors"}


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

    options = _with_config(dict(options or {}))
    source = options.get("world")
    if source and str(source).endswith(".mcap"):
        return _bag_robot(options)
    if not source or not str(source).endswith(".rawlog"):
        raise ConfigError("recorded backend: expected --world to name an MRPT .rawlog or a ROS 2 bag "
                          f"(.mcap), found {source!r}")
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


def _with_config(options: dict[str, Any]) -> dict[str, Any]:
    """The options, with a ``recorded:`` mapping of the --config file under them (given options win).

    Raises:
        ConfigError: An unknown option, or a ``recorded:`` entry that is not a mapping.
    """
    config = options.get("config")
    section = config.get("recorded") if isinstance(config, Mapping) else None
    if section is not None and not isinstance(section, Mapping):
        raise ConfigError(f"recorded backend: the config's 'recorded' entry must be a mapping, found "
                          f"{section!r}")
    merged = {**dict(section or {}), **options}
    unknown = sorted(set(merged) - _OPTIONS)
    if unknown:
        raise ConfigError(f"recorded backend: unknown options {unknown} (known: {sorted(_OPTIONS)})")
    return merged


def _bag_robot(options: dict[str, Any]) -> RecordedRobot:
    """A robot playing a ROS 2 bag (``rgbd`` and ``correct`` are rawlog options: refused)."""
    from missiontree.mapping.map_sources import MapSourceError, load_map_source
    from missiontree.mapping.ros2bag import FRAME_RATE, BagError, BagTopics, read_bag

    for option in ("rgbd", "correct"):
        if options.get(option):
            raise ConfigError(f"recorded backend: {option!r} applies to a rawlog, not to a bag "
                              f"(a bag carries its own frames and poses)")
    try:
        rate = options.get("frame_rate")  # a string that is no number: ValueError, refused below
        names = BagTopics().namespaced(str(options.get("namespace") or ""))
        bag = read_bag(options["world"], names, frame_rate=float(rate) if rate is not None else FRAME_RATE)
        if not bag.scans:
            raise BagError(f"{bag.source} has no scans on {names.scan}; its topics: "
                              f"{', '.join(sorted(bag.topics)) or 'none'} (a namespaced robot: set "
                              "namespace)")
        occupancy = load_map_source(options["map"]).grid if options.get("map") else None
        return RecordedRobot.from_bag(bag, occupancy, live_map=bool(options.get("live_map")),
                                      name=str(options.get("name") or "recorded"))
    except (BagError, MapSourceError, ValueError) as exc:
        raise ConfigError(f"recorded backend: {exc}") from None
