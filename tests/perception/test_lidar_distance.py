"""Tests of the lidar distance methods: the seed's front cone (a) and the detection cone (b)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from missiontree.perception.lidar import (
    box_bearings,
    cone_distance,
    legs_at,
    position_from_range,
    seed_front_distance,
)
from missiontree.types import LaserScan, Pose2D


def turtlebot_scan(ranges: np.ndarray, stamp: float = 0.0) -> LaserScan:
    """A full-circle scan in the TurtleBot 4 layout: index 0 = right (-90°), front at 25 %."""
    n = len(ranges)
    return LaserScan(stamp, -math.pi / 2, 2 * math.pi / n, 0.1, 12.0, ranges.astype(np.float32))


Person = tuple[float, float, float]


def room_scan(n: int = 360, wall: float = 5.0, people: tuple[Person, ...] = ()) -> LaserScan:
    """A scan inside a circular wall of radius ``wall`` with round people at (range, bearing, radius)."""
    angles = -math.pi / 2 + 2 * math.pi / n * np.arange(n)
    ranges = np.full(n, wall)
    for rng, bearing, radius in people:
        px, py = rng * math.cos(bearing), rng * math.sin(bearing)
        dx, dy = np.cos(angles), np.sin(angles)
        along = dx * px + dy * py
        miss2 = px * px + py * py - along * along
        hit = (along > 0) & (miss2 <= radius * radius)
        t = along - np.sqrt(np.clip(radius * radius - miss2, 0, None))
        ranges = np.where(hit & (t < ranges), t, ranges)
    return turtlebot_scan(ranges)


def test_seed_measures_person_straight_ahead() -> None:
    """A person 1 m straight ahead is measured at about 1 m by the seed's cone."""
    scan = room_scan(people=((1.15, 0.0, 0.15),))
    assert seed_front_distance(scan) == pytest.approx(1.0, abs=0.05)


def test_seed_misses_person_25_degrees_off_axis() -> None:
    """A person 25° off the axis lies outside the ±15° cone: the seed measures the wall behind."""
    scan = room_scan(people=((1.15, math.radians(25), 0.15),))
    assert seed_front_distance(scan) == pytest.approx(5.0, abs=0.01)


def test_seed_uses_index_arithmetic_not_angle_metadata() -> None:
    """The seed assumes front at 25 % of the array whatever angle_min says (its exact convention)."""
    ranges = np.full(360, 5.0)
    ranges[90] = 2.0
    ranges[85:95] = 2.0
    shifted = LaserScan(0.0, 0.0, 2 * math.pi / 360, 0.1, 12.0, ranges)
    assert seed_front_distance(shifted) == pytest.approx(2.0)


def test_seed_centre_mask_drops_chassis_readings() -> None:
    """Readings under 0.75 m within ±5° are dropped (chassis), and the 10th percentile of the rest is used."""
    ranges = np.full(360, 3.0)
    ranges[88:93] = 0.6  # chassis "obstacle" in the centre zone
    assert seed_front_distance(turtlebot_scan(ranges)) == pytest.approx(3.0)


def test_seed_side_mask_keeps_readings_between_040_and_075() -> None:
    """On the sides (5°..15°) readings of 0.5 m survive; under 0.40 m they are dropped."""
    ranges = np.full(360, 3.0)
    ranges[78:84] = 0.5
    assert seed_front_distance(turtlebot_scan(ranges)) == pytest.approx(0.5)
    ranges[78:84] = 0.3
    assert seed_front_distance(turtlebot_scan(ranges)) == pytest.approx(3.0)


def test_seed_takes_tenth_percentile_not_minimum() -> None:
    """A single near reading (floor) does not set the distance: the 10th percentile does."""
    ranges = np.full(360, 3.0)
    ranges[80] = 1.0
    assert seed_front_distance(turtlebot_scan(ranges)) == pytest.approx(
        np.percentile(np.r_[np.full(29, 3.0), 1.0], 10))


def test_seed_empty_cone_is_infinite() -> None:
    """A cone with nothing but inf or zero readings gives inf, as in the seed."""
    ranges = np.full(360, np.inf)
    ranges[90] = 0.0
    assert seed_front_distance(turtlebot_scan(ranges)) == math.inf


def test_cone_measures_person_25_degrees_off_axis() -> None:
    """A cone centred on the person's bearing measures 1 m where the seed's cone reads the wall."""
    scan = room_scan(people=((1.15, math.radians(25), 0.15),))
    reading = cone_distance(scan, math.radians(25), math.radians(6))
    assert reading.found
    assert reading.distance == pytest.approx(1.0, abs=0.05)
    assert reading.bearing == pytest.approx(math.radians(25), abs=math.radians(3))


@pytest.mark.parametrize("bearing_deg", [-35, -20, -5, 0, 10, 30, 35])
def test_cone_measures_person_across_camera_field_of_view(bearing_deg: float) -> None:
    """Across a 70° camera field of view the cone finds the person's near surface within 5 cm."""
    bearing = math.radians(bearing_deg)
    scan = room_scan(n=720, people=((2.15, bearing, 0.15),))
    reading = cone_distance(scan, bearing, math.radians(3))
    assert reading.distance == pytest.approx(2.0, abs=0.05)


def test_cone_ignores_a_lone_stray_return_in_front() -> None:
    """One spurious short return before the target's cluster is not taken as the target."""
    scan = room_scan(people=((2.15, 0.0, 0.15),))
    ranges = np.array(scan.ranges)
    ranges[90] = 0.9
    stray = turtlebot_scan(ranges)
    assert cone_distance(stray, 0.0, math.radians(6)).distance == pytest.approx(2.0, abs=0.05)


def test_cone_without_returns_is_not_found() -> None:
    """A cone aimed where the scan holds no valid return reports nothing found."""
    reading = cone_distance(turtlebot_scan(np.full(360, np.inf)), 0.3)
    assert not reading.found
    assert reading.distance == math.inf


def test_cone_respects_scan_angle_layout() -> None:
    """The cone uses the scan's angle_min and mount_yaw, not the TurtleBot index convention."""
    ranges = np.full(360, 5.0)
    ranges[0:3] = 1.5
    ranges[-2:] = 1.5
    centred = LaserScan(0.0, 0.0, 2 * math.pi / 360, 0.1, 12.0, ranges)
    assert cone_distance(centred, 0.0, math.radians(3)).distance == pytest.approx(1.5)


def test_box_bearings_of_a_box_left_of_centre() -> None:
    """A box left of the principal point has a positive bearing; its half-width is its angular size."""
    bearing, half = box_bearings(Pose2D(0, 0, 0.1), Pose2D(0, 0, 0.1), 100, 140, fx=200.0, cx=160.0)
    assert bearing == pytest.approx((math.atan2(60, 200) + math.atan2(20, 200)) / 2)
    assert half == pytest.approx((math.atan2(60, 200) - math.atan2(20, 200)) / 2)


def test_position_from_range_uses_robot_pose() -> None:
    """A return 2 m at +90° from a robot facing +x at (1, 1) is at (1, 3)."""
    x, y = position_from_range(Pose2D(1.0, 1.0, 0.0), math.pi / 2, 2.0)
    assert (x, y) == pytest.approx((1.0, 3.0))


def test_cone_keeps_a_single_beam_target_in_a_narrow_cone() -> None:
    """A far person's leg caught by one beam in a narrow cone is the target, not the wall behind."""
    ranges = np.full(360, 7.0)
    ranges[90] = 4.0
    reading = cone_distance(turtlebot_scan(ranges), 0.0, math.radians(2.5))
    assert reading.distance == pytest.approx(4.0)


def test_legs_at_finds_a_person_standing_clear_of_the_wall() -> None:
    """Two legs 1.5 m away in front of a wall 5 m away are leg-like at their bearing and range."""
    scan = room_scan(n=360, people=((1.5, math.radians(10), 0.07), (1.5, math.radians(18), 0.07)))
    assert legs_at(scan, math.radians(14), 1.45)


def test_legs_at_refuses_a_wall() -> None:
    """A flat wall at the expected range is not legs, whatever the camera thought it saw."""
    ranges = np.full(360, 2.0)
    assert not legs_at(turtlebot_scan(ranges), 0.0, 2.0)


def test_legs_at_refuses_when_nothing_is_near_the_expected_range() -> None:
    """A leg at 3 m does not vouch for a detection measured at 1.5 m."""
    scan = room_scan(people=((3.0, 0.0, 0.07),))
    assert not legs_at(scan, 0.0, 1.5)
