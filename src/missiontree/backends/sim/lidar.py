"""A planar lidar by exact ray casting, with the TurtleBot 4 index convention.

Beams are cast in the horizontal plane at the mount height against every prism that crosses
it: walls, objects tall enough (a cup on the floor is below a 0.19 m scan plane), and people's
legs. Index ``i`` looks along ``mount_yaw + angle_min + i * angle_increment`` in the robot
frame; the TurtleBot 4 profile mounts the RPLIDAR at +90° and starts at -180°, so index 0 looks
right (-90°), a quarter of the array ahead and half of it left (the patrol-robot thesis §3.9), and
``LaserScan.angles()`` returns robot-frame angles. Readings beyond ``range_max`` are ``inf``
(no return), readings under ``range_min`` NaN (invalid), as sensor_msgs/LaserScan has it.
"""

from __future__ import annotations

import math

import numpy as np

from missiontree.backends.sim.raycast import Primitives, fan_first_hit
from missiontree.backends.sim.schema import LidarSpec
from missiontree.types import LaserScan, Pose2D


class Lidar:
    """Produces LaserScans from the true pose of the robot."""

    def __init__(self, spec: LidarSpec, rng: np.random.Generator, accelerate: bool = True) -> None:
        self.spec = spec
        self.rng = rng
        self.accelerate = accelerate
        self.mount_yaw = math.radians(spec.mount.yaw_deg)
        self.angle_min = math.radians(spec.angle_min_deg)
        self.angle_increment = 2.0 * math.pi / spec.beams
        self.robot_angles = self.mount_yaw + self.angle_min + self.angle_increment * np.arange(spec.beams)
        self._static_key: int | None = None
        self._static_plane = Primitives.empty()

    def plane_primitives(self, static: Primitives, dynamic: Primitives) -> tuple[np.ndarray, np.ndarray]:
        """Kinds and geometry of the prisms crossing the scan plane (static part cut once per world)."""
        if self._static_key != id(static):
            self._static_key = id(static)
            self._static_plane = static.crossing(self.spec.mount.z)
        z = self.spec.mount.z
        keep = (dynamic.z[:, 0] <= z) & (dynamic.z[:, 1] >= z)
        return (np.concatenate([self._static_plane.kind, dynamic.kind[keep]]),
                np.concatenate([self._static_plane.geom, dynamic.geom[keep]]))

    def scan(self, pose: Pose2D, stamp: float, static: Primitives, dynamic: Primitives) -> LaserScan:
        """Cast every beam from the sensor at the robot's true ``pose``; ``stamp`` is the scan time."""
        ox, oy = pose.transform(self.spec.mount.x, self.spec.mount.y)
        angle0 = pose.yaw + self.mount_yaw + self.angle_min
        kind, geom = self.plane_primitives(static, dynamic)
        ranges = fan_first_hit(ox, oy, angle0, self.angle_increment, self.spec.beams, kind, geom,
                               self.accelerate)
        if self.spec.noise > 0:
            ranges += self.rng.normal(0.0, self.spec.noise, len(ranges))
        ranges[ranges > self.spec.range_max] = np.inf
        ranges[ranges < self.spec.range_min] = np.nan
        ranges = ranges.astype(np.float32)
        return LaserScan(
            stamp=stamp, angle_min=self.angle_min, angle_increment=self.angle_increment,
            range_min=self.spec.range_min, range_max=self.spec.range_max, ranges=ranges,
            mount_yaw=self.mount_yaw, frame_id=self.spec.frame_id,
        )
