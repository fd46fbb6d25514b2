"""Differential drive: ICC integration against the closed form, wheel kinematics, limits, odometry."""

from __future__ import annotations

import math

import numpy as np
import pytest

from missiontree.backends.sim.kinematics import DiffDrive, Odometry, body_velocity, icc_step, wheel_speeds
from missiontree.backends.sim.schema import LimitsSpec, OdometrySpec, WheelsSpec
from missiontree.types import Pose2D


def _closed_form(p: Pose2D, v: float, w: float, t: float) -> tuple[float, float, float]:
    """Position on the circle about the ICC at time t (seed 002 §1)."""
    r = v / w
    icc_x, icc_y = p.x - r * math.sin(p.yaw), p.y + r * math.cos(p.yaw)
    theta = p.yaw + w * t
    return icc_x + r * math.sin(theta), icc_y - r * math.cos(theta), theta


@pytest.mark.parametrize(("v", "w"), [(0.3, 0.5), (0.2, -1.2), (-0.1, 0.8)])
def test_icc_steps_match_the_closed_form_circle(v, w):
    """Many small ICC steps at constant (v, w) land exactly on the closed-form circle."""
    start = Pose2D(1.0, -2.0, 0.4)
    pose = start
    for _ in range(400):
        pose = icc_step(pose, v, w, 0.05)
    x, y, theta = _closed_form(start, v, w, 20.0)
    assert pose.x == pytest.approx(x, abs=1e-9) and pose.y == pytest.approx(y, abs=1e-9)
    assert math.remainder(pose.yaw - theta, 2 * math.pi) == pytest.approx(0.0, abs=1e-9)


def test_one_long_step_equals_many_short_ones():
    """ICC integration is exact: one 5 s step equals a hundred 0.05 s steps."""
    start = Pose2D(0.0, 0.0, 0.0)
    many = start
    for _ in range(100):
        many = icc_step(many, 0.25, 0.9, 0.05)
    one = icc_step(start, 0.25, 0.9, 5.0)
    assert (one.x, one.y) == pytest.approx((many.x, many.y), abs=1e-9)


def test_straight_and_spin_in_place():
    """W = 0 moves straight along the heading; v = 0 turns without moving."""
    p = icc_step(Pose2D(1.0, 1.0, math.pi / 2), 0.3, 0.0, 2.0)
    assert (p.x, p.y, p.yaw) == pytest.approx((1.0, 1.6, math.pi / 2))
    q = icc_step(Pose2D(1.0, 1.0, 0.0), 0.0, 1.0, 1.0)
    assert (q.x, q.y, q.yaw) == pytest.approx((1.0, 1.0, 1.0))


def test_wheel_kinematics_round_trip():
    """Forward kinematics inverts the inverse: v = r/2 (phiR + phiL), w = r/L (phiR - phiL)."""
    wheels = WheelsSpec()
    right, left = wheel_speeds(0.25, 0.7, wheels)
    assert right > left
    assert body_velocity(right, left, wheels) == pytest.approx((0.25, 0.7))
    assert body_velocity(1.0, 1.0, wheels) == pytest.approx((wheels.radius, 0.0))


def test_speed_and_acceleration_limits():
    """Commands are clipped to the top speeds and approached at the acceleration limits."""
    base = DiffDrive(Pose2D(0, 0, 0), LimitsSpec(max_v=0.31, max_w=1.9, max_acc=1.0, max_alpha=4.0))
    base.command(5.0, -9.0)
    assert (base.cmd_v, base.cmd_w) == (0.31, -1.9)
    _, v, w = base.propose(0.1)
    assert v == pytest.approx(0.1) and w == pytest.approx(-0.4)


def test_odometry_noise_drifts_deterministically():
    """With noise the estimate drifts from the truth, identically for the same seed."""
    def run(seed: int) -> Pose2D:
        spec = OdometrySpec(noise_v=0.05, noise_w=0.05)
        odom = Odometry(Pose2D(0, 0, 0), spec, np.random.default_rng(seed))
        for _ in range(200):
            odom.update(0.3, 0.2, 0.05)
        return odom.pose
    truth = Pose2D(0, 0, 0)
    for _ in range(200):
        truth = icc_step(truth, 0.3, 0.2, 0.05)
    a, b, c = run(1), run(1), run(2)
    assert a == b and a != c
    assert a.distance_to(truth) > 1e-3
