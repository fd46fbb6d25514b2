"""Lidar ray casting against analytic distances, the TurtleBot 4 index convention, limits and noise."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import ROOM

from missiontree.backends.sim import create_robot

QUIET = {"lidar": {"noise": 0.0}}


def _room_distance(x: float, y: float, angle: float, w: float = 6.0, h: float = 4.0) -> float:
    """Distance from (x, y) along ``angle`` to the walls of the axis-aligned room [0, w] x [0, h]."""
    c, s = math.cos(angle), math.sin(angle)
    ts = []
    if c > 1e-12:
        ts.append((w - x) / c)
    if c < -1e-12:
        ts.append(-x / c)
    if s > 1e-12:
        ts.append((h - y) / s)
    if s < -1e-12:
        ts.append(-y / s)
    return min(ts)


def _cylinder_distance(x: float, y: float, angle: float, cx: float, cy: float, r: float) -> float:
    dx, dy = math.cos(angle), math.sin(angle)
    fx, fy = x - cx, y - cy
    b = 2 * (dx * fx + dy * fy)
    c = fx * fx + fy * fy - r * r
    disc = b * b - 4 * c
    if disc < 0:
        return math.inf
    t = (-b - math.sqrt(disc)) / 2
    return t if t > 0 else math.inf


@pytest.mark.parametrize("accelerate", [True, False])
def test_ranges_match_analytic_room_distances(write_world, accelerate):
    """Every beam in an empty rectangular room reads the analytic wall distance within 2 cm."""
    robot = create_robot({"world": write_world(ROOM), "config": {**QUIET, "accelerate": accelerate}})
    scan = robot.scan()
    expected = np.array([_room_distance(2.0, 1.5, a) for a in scan.angles()])
    assert np.max(np.abs(scan.ranges - expected)) < 0.02


def test_ranges_match_a_rotated_robot(write_world):
    """With the robot turned, beam angles stay robot-frame and ranges stay analytic."""
    text = ROOM.replace("yaw: 0.0", "yaw: 0.7")
    robot = create_robot({"world": write_world(text), "config": QUIET})
    scan = robot.scan()
    expected = np.array([_room_distance(2.0, 1.5, 0.7 + a) for a in scan.angles()])
    assert np.max(np.abs(scan.ranges - expected)) < 0.02


def test_cylinder_is_seen_at_its_analytic_distance(write_world):
    """A cylinder crossing the scan plane shadows the wall behind it at its surface distance."""
    text = ROOM + """
objects:
  - {label: bin, shape: cylinder, size: [0.4, 0.4, 0.6], pose: {x: 4.0, y: 1.5}}
"""
    robot = create_robot({"world": write_world(text), "config": QUIET})
    scan = robot.scan()
    for angle, r in zip(scan.angles(), scan.ranges, strict=True):
        expected = min(_room_distance(2.0, 1.5, angle), _cylinder_distance(2.0, 1.5, angle, 4.0, 1.5, 0.2))
        assert abs(r - expected) < 0.02
    front = int(np.argmin(np.abs(scan.angles())))
    assert abs(scan.ranges[front] - 1.8) < 0.02


def test_objects_below_or_above_the_scan_plane_are_not_seen(write_world):
    """A cup on the floor and a shelf above 0.19 m do not appear in the scan; a tall box does."""
    text = ROOM + """
objects:
  - {label: cup, shape: cylinder, size: [0.09, 0.09, 0.1], pose: {x: 3.0, y: 1.5}}
  - {label: shelf, size: [0.3, 0.3, 0.3], pose: {x: 2.0, y: 2.5}, elevation: 0.9}
  - {label: box, size: [0.4, 0.4, 0.5], pose: {x: 2.0, y: 0.6}}
"""
    robot = create_robot({"world": write_world(text), "config": QUIET})
    scan = robot.scan()
    angles = scan.angles()
    front = int(np.argmin(np.abs(angles)))
    left = int(np.argmin(np.abs(angles - math.pi / 2)))
    right = int(np.argmin(np.abs(angles + math.pi / 2)))
    assert abs(scan.ranges[front] - 4.0) < 0.02   # through the cup to the east wall
    assert abs(scan.ranges[left] - 2.5) < 0.02    # under the shelf to the north wall
    assert abs(scan.ranges[right] - 0.7) < 0.02   # the box's north face at y = 0.8


def test_turtlebot4_index_convention():
    """Index 0 looks right, a quarter of the array ahead, half of it left (seed 001 §3.9)."""
    robot = create_robot({"world": "conformance", "config": QUIET})
    scan = robot.scan()
    n = len(scan.ranges)
    angles = np.angle(np.exp(1j * scan.angles()))
    assert angles[0] == pytest.approx(-math.pi / 2, abs=1e-9)
    assert angles[n // 4] == pytest.approx(0.0, abs=1e-9)
    assert angles[n // 2] == pytest.approx(math.pi / 2, abs=1e-9)
    assert scan.angle_min == pytest.approx(-math.pi) and scan.mount_yaw == pytest.approx(math.pi / 2)
    assert scan.ranges[n // 4] == pytest.approx(4.0, abs=0.02)   # the east wall, 4 m ahead
    assert scan.ranges[0] == pytest.approx(2.5, abs=0.02)        # the south wall, 2.5 m to the right


def test_person_legs_block_the_lidar(write_world):
    """A person standing ahead shows up as their nearest leg in front of the wall."""
    text = ROOM + """
people:
  - {id: p, route: [[3.5, 1.5]], speed: 0.0}
"""
    robot = create_robot({"world": write_world(text), "config": QUIET})
    scan = robot.scan()
    front = int(np.argmin(np.abs(scan.angles())))
    window = scan.ranges[front - 8: front + 9]
    assert 1.3 < np.min(window) < 1.5


def test_range_limits_give_inf_and_nan(write_world):
    """Beyond range_max a beam reads inf (no return); under range_min NaN (invalid)."""
    text = ROOM + """
objects:
  - {label: post, shape: cylinder, size: [0.1, 0.1, 1.0], pose: {x: 2.0, y: 1.8}}
"""
    robot = create_robot({"world": write_world(text),
                          "config": {"lidar": {"noise": 0.0, "range_max": 3.0, "range_min": 0.5}}})
    scan = robot.scan()
    angles = scan.angles()
    front = int(np.argmin(np.abs(angles)))
    left = int(np.argmin(np.abs(angles - math.pi / 2)))
    assert math.isinf(scan.ranges[front])          # east wall 4 m away, range_max 3 m
    assert math.isnan(scan.ranges[left])           # post surface 0.25 m away, below range_min


def test_noise_has_the_configured_spread(write_world):
    """Range noise has the configured standard deviation and zero mean."""
    robot = create_robot({"world": write_world(ROOM), "config": {"lidar": {"noise": 0.01}}, "seed": 5})
    errors = []
    for _ in range(20):
        robot.spin_until(robot.now() + 0.1)
        scan = robot.scan()
        expected = np.array([_room_distance(2.0, 1.5, a) for a in scan.angles()])
        errors.append(scan.ranges - expected)
    errors = np.concatenate(errors)
    assert abs(errors.std() - 0.01) < 0.002
    assert abs(errors.mean()) < 0.002
