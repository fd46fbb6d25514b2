"""The simulated backend: a deterministic, headless, faster-than-real-time TurtleBot world.

``create_robot`` builds a :class:`SimRobot` from options; ``load_world`` loads and checks a world
file. Nothing outside the CLI and tests should import this package (imports point down only).
"""

from __future__ import annotations

from collections.abc import Mapping
from os import PathLike
from typing import Any

# importing the floorplans registers the `floorplan:` world source, the placement `map:`, the MRPT
# grids `mrpt:`, the generator `generated:` (MAX_SEED is its seed bound)
from missiontree.backends.sim import floorplans as _floorplans  # noqa: F401
from missiontree.backends.sim import mrpt_worlds as _mrpt_worlds  # noqa: F401
from missiontree.backends.sim.generator import MAX_SEED
from missiontree.backends.sim.robot import SimRobot
from missiontree.backends.sim.world import World, load_robot_profile, load_world
from missiontree.errors import ConfigError
from missiontree.robot.sensors import sensor_kinds_from_options

__all__ = ["SimRobot", "World", "create_robot", "load_robot_profile", "load_world"]

_OPTIONS = {"world", "robot", "seed", "config", "name", "unknown_map", "sensors"}


def create_robot(options: Mapping[str, Any] | None = None) -> SimRobot:
    """Build a simulated robot.

    Args:
        options: ``world`` (a shipped name such as ``office`` or a path; default ``office``),
            ``robot`` (profile name or path; default: the world's profile, normally
            ``turtlebot4``), ``seed`` (a whole number from 0, default 0), ``config`` (a dict merged
            over the robot profile, e.g. ``{"lidar": {"rate": 20}, "camera": {"width": 640, "height": 480},
            "odometry": {"noise_v": 0.02}, "accelerate": False}``), ``name``, ``unknown_map`` (bool:
            the robot starts knowing nothing and learns its map from its lidar), ``sensors`` (the
            plugin sensor kinds; default: those of the plugins that load, see
            :func:`missiontree.robot.sensors.sensor_kinds_from_options`).

    Raises:
        WorldFileError: The world, the profile or an override is broken (file:line problems).
        ConfigError: An unknown option.
    """
    opts = dict(options or {})
    unknown = sorted(set(opts) - _OPTIONS)
    if unknown:
        raise ConfigError(f"unknown simulator option(s) {', '.join(unknown)}; "
                          f"expected: {', '.join(sorted(_OPTIONS))}")
    seed = opts.get("seed", 0)
    if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed <= MAX_SEED:
        raise ConfigError(f"simulator option seed: expected a whole number from 0 to {MAX_SEED}, "
                          f"found {seed!r}")
    for key in ("world", "robot", "name"):
        if key in opts and opts[key] is not None and not isinstance(opts[key], str | PathLike):
            raise ConfigError(f"simulator option {key}: expected a name or a path, found {opts[key]!r}")
    config = opts.get("config") or None
    if config is not None and not isinstance(config, Mapping):
        raise ConfigError(f"simulator option config: expected a mapping of robot profile overrides, "
                          f"found {type(config).__name__}")
    world = load_world(opts.get("world") or "office")
    profile = load_robot_profile(opts.get("robot") or world.profile_name, dict(config) if config else None)
    unknown_map = opts.get("unknown_map") or False
    if not isinstance(unknown_map, bool):
        raise ConfigError(f"simulator option unknown_map: expected true or false, found {unknown_map!r}")
    sensors = sensor_kinds_from_options(opts)
    return SimRobot(world, profile, seed=seed, name=str(opts.get("name") or "sim"), unknown_map=unknown_map,
                    sensors=sensors)
