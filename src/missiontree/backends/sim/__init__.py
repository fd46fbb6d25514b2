"""The simulated backend: a deterministic, headless, faster-than-real-time TurtleBot world.

``create_robot`` builds a :class:`SimRobot` from options; ``load_world`` loads and checks a world
file. Nothing outside the CLI and tests should import this package (imports point down only).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from missiontree.backends.sim.robot import SimRobot
from missiontree.backends.sim.world import World, load_robot_profile, load_world
from missiontree.errors import ConfigError

__all__ = ["SimRobot", "World", "create_robot", "load_robot_profile", "load_world"]

_OPTIONS = {"world", "robot", "seed", "config", "name"}


def create_robot(options: Mapping[str, Any] | None = None) -> SimRobot:
    """Build a simulated robot.

    Args:
        options: ``world`` (a shipped name such as ``office`` or a path; default ``office``),
            ``robot`` (profile name or path; default: the world's profile, normally
            ``turtlebot4``), ``seed`` (int, default 0), ``config`` (a dict merged over the robot
            profile, e.g. ``{"lidar": {"rate": 20}, "camera": {"width": 640, "height": 480},
            "odometry": {"noise_v": 0.02}, "accelerate": False}``), ``name``.

    Raises:
        WorldFileError: The world, the profile or an override is broken (file:line problems).
        ConfigError: An unknown option.
    """
    opts = dict(options or {})
    unknown = sorted(set(opts) - _OPTIONS)
    if unknown:
        raise ConfigError(f"unknown simulator option(s) {', '.join(unknown)}; "
                          f"expected: {', '.join(sorted(_OPTIONS))}")
    world = load_world(opts.get("world", "office"))
    profile = load_robot_profile(opts.get("robot") or world.profile_name, opts.get("config") or None)
    seed = opts.get("seed", 0)
    if not isinstance(seed, int) or isinstance(seed, bool):
        raise ConfigError(f"simulator option seed: expected an integer, found {seed!r}")
    return SimRobot(world, profile, seed=seed, name=str(opts.get("name", "sim")))
