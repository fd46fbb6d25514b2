"""Differential drive kinematics integrated exactly over the instantaneous centre of curvature.

As in the vision-language object-search report (§1).

Wheel speeds map to body velocity as ``v = r/2 (phi_R + phi_L)``, ``w = r/L (phi_R - phi_L)``;
for a velocity held constant over a step the pose moves on a circle about the ICC, which
:func:`icc_step` integrates in closed form (no Euler error, so a long straight run or a spin
in place is exact). :class:`DiffDrive` adds speed and acceleration limits; :class:`Odometry`
integrates what the wheels report, with optional noise, into the robot's own pose estimate.
"""

from __future__ import annotations

import math

import numpy as np

from missiontree.backends.sim.schema import LimitsSpec, OdometrySpec, WheelsSpec
from missiontree.types import Pose2D, wrap_angle

_STRAIGHT = 1e-9


def icc_step(pose: Pose2D, v: float, w: float, dt: float) -> Pose2D:
    """Pose after moving with body velocity (v, w) for ``dt`` seconds, exactly.

    With ``w != 0`` the robot turns about the ICC at distance ``R = v / w`` to its left;
    with ``w == 0`` it moves straight.
    """
    theta = pose.yaw
    if abs(w) < _STRAIGHT:
        return Pose2D(pose.x + v * math.cos(theta) * dt, pose.y + v * math.sin(theta) * dt, theta)
    radius = v / w
    theta2 = theta + w * dt
    return Pose2D(
        pose.x + radius * (math.sin(theta2) - math.sin(theta)),
        pose.y - radius * (math.cos(theta2) - math.cos(theta)),
        wrap_angle(theta2),
    )


def body_velocity(phi_right: float, phi_left: float, wheels: WheelsSpec) -> tuple[float, float]:
    """Forward kinematics: wheel angular speeds (rad/s) to body (v, w)."""
    v = wheels.radius / 2.0 * (phi_right + phi_left)
    w = wheels.radius / wheels.track * (phi_right - phi_left)
    return v, w


def wheel_speeds(v: float, w: float, wheels: WheelsSpec) -> tuple[float, float]:
    """Inverse kinematics: body (v, w) to wheel angular speeds (right, left) in rad/s."""
    right = (v + w * wheels.track / 2.0) / wheels.radius
    left = (v - w * wheels.track / 2.0) / wheels.radius
    return right, left


def _approach(current: float, target: float, max_step: float) -> float:
    if target > current:
        return min(target, current + max_step)
    return max(target, current - max_step)


class DiffDrive:
    """The robot's true motion: commanded velocity limited in speed and acceleration."""

    def __init__(self, pose: Pose2D, limits: LimitsSpec) -> None:
        self.pose = pose
        self.limits = limits
        self.v = 0.0
        self.w = 0.0
        self.cmd_v = 0.0
        self.cmd_w = 0.0

    def command(self, v: float, w: float) -> None:
        """Set the target body velocity; clipped to the speed limits."""
        self.cmd_v = max(-self.limits.max_v, min(self.limits.max_v, float(v)))
        self.cmd_w = max(-self.limits.max_w, min(self.limits.max_w, float(w)))

    def halt(self) -> None:
        """Stop at once (a bump): velocity and command become zero."""
        self.v = self.w = self.cmd_v = self.cmd_w = 0.0

    def propose(self, dt: float) -> tuple[Pose2D, float, float]:
        """The pose and velocity after ``dt`` if nothing is in the way (does not move)."""
        v = _approach(self.v, self.cmd_v, self.limits.max_acc * dt)
        w = _approach(self.w, self.cmd_w, self.limits.max_alpha * dt)
        return icc_step(self.pose, v, w, dt), v, w

    def accept(self, pose: Pose2D, v: float, w: float) -> None:
        """Commit a proposed step."""
        self.pose, self.v, self.w = pose, v, w


class Odometry:
    """The robot's own pose estimate: the wheels' motion integrated with optional noise."""

    def __init__(self, pose: Pose2D, spec: OdometrySpec, rng: np.random.Generator) -> None:
        self.pose = pose
        self.spec = spec
        self.rng = rng

    def update(self, v: float, w: float, dt: float) -> Pose2D:
        """Integrate the measured body velocity over ``dt``."""
        if self.spec.noise_v > 0 and v != 0.0:
            v *= 1.0 + self.rng.normal(0.0, self.spec.noise_v)
        if self.spec.noise_w > 0 and (w != 0.0 or v != 0.0):
            w = w * (1.0 + self.rng.normal(0.0, self.spec.noise_w)) + self.rng.normal(
                0.0, self.spec.noise_w * 0.05 * abs(v))
        self.pose = icc_step(self.pose, v, w, dt)
        return self.pose
