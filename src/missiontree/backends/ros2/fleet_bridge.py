"""Several simulated robots served over ROS 2 in one world, each under its own namespace.

``missiontree sim-ros --robots N`` builds a :class:`~missiontree.backends.sim.fleet.SimFleet` and
serves each robot as a namespaced TurtleBot 4 with Nav2 would be: ``/robot1/scan``, ``/robot1/odom``,
``/robot1/oakd/...``, ``/robot1/map``, ``/robot1/navigate_to_pose``, and TF on ``/robot1/tf`` and
``/robot1/tf_static`` with unprefixed frame names (``map``, ``odom``, ``base_link``): the
per-namespace TF of Nav2's multi-robot bringup and of TurtleBot 4's namespacing. ``/clock`` is
global. Each robot's simulator controls are on ``/robot1/missiontree/sim/control`` (``kill`` among
them, see :meth:`~missiontree.backends.ros2.bridge.SimBridge.vanish`).
"""

from __future__ import annotations

import threading
from collections.abc import Sequence
from typing import TYPE_CHECKING

from missiontree.backends.ros2.bridge import SimBridge
from missiontree.backends.ros2.profile import load_profile
from missiontree.errors import ConfigError

if TYPE_CHECKING:
    from missiontree.backends.sim.fleet import SimFleet

__all__ = ["serve_fleet"]


def serve_fleet(fleet: SimFleet, profile: str, *, domain_id: int | None, rate: float, sim_time: bool,
                paused: bool, kills: Sequence[tuple[str, float]] = ()) -> SimBridge:
    """One bridge per robot of ``fleet``, each under ``/<robot name>``; returns the lead (robot 1's).

    Running the lead (:meth:`SimBridge.run`) steps the whole fleet and serves every robot; closing
    it closes them all.

    Args:
        fleet: The simulated robots (their names become the namespaces).
        profile: The ROS 2 profile every robot is served as (config/backends name or path).
        domain_id: ROS_DOMAIN_ID (None: the environment's).
        rate: Simulated seconds per wall second.
        sim_time: Stamp with simulated time and publish /clock.
        paused: Hold the fleet's clock until the first goal or velocity command to any robot.
        kills: ``(robot, simulated seconds)``: that robot's NavigateToPose server vanishes then.

    Raises:
        ConfigError: A kill names no robot of the fleet.
    """
    names = list(fleet.names)
    for victim, _ in kills:
        if victim not in names:
            raise ConfigError(f"--kill-robot {victim}: no such robot; robots: {', '.join(names)}")
    lock = threading.RLock()  # the fleet steps as one: every bridge's simulator calls hold one lock
    bridges: list[SimBridge] = []
    for robot in fleet.robots:
        served = load_profile(profile, {"namespace": f"/{robot.name}", "domain_id": domain_id})
        bridges.append(SimBridge(lambda r=robot: r, served, rate=rate, sim_time=sim_time,  # type: ignore[misc]
                                 paused=paused, lock=lock))
    lead = bridges[0]
    lead.peers = bridges[1:]
    for peer in lead.peers:
        peer.lead = lead
    by_name = dict(zip(names, bridges, strict=True))
    lead.kills = sorted(((at, by_name[victim]) for victim, at in kills), key=lambda kill: kill[0])
    return lead
