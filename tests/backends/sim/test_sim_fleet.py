"""Several simulated robots in one world: sensing, collisions, avoidance, determinism, starts, truth."""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from pathlib import Path

import cv2
import numpy as np
import pytest

from missiontree.backends.sim import create_robot
from missiontree.backends.sim.fleet import (
    ROBOT_KIND,
    FleetRobot,
    SimFleet,
    create_fleet,
    fleet_starts,
    robot_seed,
)
from missiontree.backends.sim.render import OTHER_ROBOT_BGR
from missiontree.backends.sim.world import load_world
from missiontree.errors import ConfigError
from missiontree.robot.actions import ActionStatus
from missiontree.robot.conformance import RobotConformance
from missiontree.types import LaserScan, Pose2D, Tolerance

ANY = 2 * math.pi
WEST = Pose2D(1.0, 2.5, 0.0)      # the conformance world's start, 4 m from the east wall


def _front(scan: LaserScan) -> float:
    """The range of the beam looking straight ahead."""
    angles = np.angle(np.exp(1j * scan.angles()))
    return float(scan.ranges[int(np.argmin(np.abs(angles)))])


def _pair(second: Pose2D, seed: int = 0) -> SimFleet:
    return create_fleet("conformance", robots=2, seed=seed, starts=[WEST, second])


def _spin(fleet: SimFleet, seconds: float, until: Callable[[], bool] = lambda: False) -> None:
    end = fleet.now() + seconds
    while fleet.now() < end - 1e-9 and not until():
        fleet.spin_until(fleet.now() + 0.5)


def test_lidar_sees_the_other_robot_as_a_body_of_its_footprint() -> None:
    """A robot 1.5 m ahead shows in the front beam at 1.5 m less its footprint radius, not the wall at 4 m."""
    fleet = _pair(Pose2D(2.5, 2.5, 0.0))
    scan = fleet[0].scan()
    assert scan is not None
    assert _front(scan) == pytest.approx(1.5 - fleet.radius, abs=0.05)


def test_robot_does_not_see_itself() -> None:
    """The second robot's front beam reaches the east wall (its own body is not in its scan)."""
    fleet = _pair(Pose2D(2.5, 2.5, 0.0))
    scan = fleet[1].scan()
    assert scan is not None
    assert _front(scan) == pytest.approx(2.5, abs=0.05)


def test_camera_renders_the_other_robot_with_its_instance() -> None:
    """The first robot's frame shows the second robot's body: its instance id in the mask, in body colour."""
    fleet = _pair(Pose2D(2.5, 2.5, 0.0))
    frame = fleet[0].rgbd()
    assert frame is not None
    mask = fleet[0].truth.instance_mask(frame.stamp)
    assert mask is not None
    body = mask == fleet.instance_ids[1]
    assert body.sum() > 500
    colour = frame.color[body].astype(float).mean(axis=0)
    assert np.all(np.abs(colour - np.array(fleet.rgb)) < 60)
    seen = fleet.truth.robots["robot1"].visible_at(frame.stamp)
    assert seen["robot2"].kind == ROBOT_KIND


def test_collision_between_robots_is_refused_and_counted() -> None:
    """Two robots driven head-on stop at contact: their bodies never overlap and each reports a bump."""
    fleet = _pair(Pose2D(2.5, 2.5, math.pi))
    fleet[0].drive(0.2, 0.0)
    fleet[1].drive(0.2, 0.0)
    _spin(fleet, 10.0)
    assert fleet.truth.min_separation.gap > -1e-6
    assert fleet.truth.min_separation.gap < 0.02
    assert all(robot.bump_report()["contacts"] >= 1 for robot in fleet)
    assert all(robot.bump_report()["refused_by_robots"] >= 1 for robot in fleet)


def test_navigation_avoids_a_robot_standing_in_its_path() -> None:
    """A goal straight through a standing robot succeeds around it, with no contact."""
    fleet = _pair(Pose2D(2.6, 2.5, 0.0))
    handle = fleet[0].navigate_to(Pose2D(4.2, 2.5, 0.0), Tolerance(xy=0.25, yaw=ANY))
    _spin(fleet, 60.0, until=lambda: handle.status().done)
    assert handle.status() is ActionStatus.SUCCEEDED, handle.result()
    assert fleet[0].bump_report()["contacts"] == 0
    assert fleet.truth.min_separation.gap > 0.0


def test_two_robots_swap_places_head_on_without_contact() -> None:
    """Robots sent to each other's start both arrive, avoiding each other by what their lidars show."""
    fleet = _pair(Pose2D(4.0, 2.5, math.pi))
    first = fleet[0].navigate_to(Pose2D(4.0, 2.5, 0.0), Tolerance(xy=0.25, yaw=ANY))
    second = fleet[1].navigate_to(Pose2D(1.0, 2.5, 0.0), Tolerance(xy=0.25, yaw=ANY))
    _spin(fleet, 90.0, until=lambda: first.status().done and second.status().done)
    assert first.status() is ActionStatus.SUCCEEDED and second.status() is ActionStatus.SUCCEEDED
    assert all(robot.bump_report()["contacts"] == 0 for robot in fleet)


def test_spinning_one_robot_advances_the_whole_fleet() -> None:
    """spin_until on any fleet robot brings every robot's clock to that time."""
    fleet = create_fleet("conformance", robots=3, seed=0)
    fleet[2].spin_until(1.0)
    assert [robot.now() for robot in fleet] == pytest.approx([1.0, 1.0, 1.0])


def _run(seed: int) -> tuple[list[np.ndarray], list[tuple[float, float, float]]]:
    fleet = create_fleet("office", robots=2, seed=seed, config={"odometry": {"noise_v": 0.02}})
    fleet[0].navigate_to(Pose2D(4.0, 4.0, 0.0))
    fleet[1].drive(0.1, 0.3)
    fleet.spin_until(4.0)
    scans = [np.asarray(robot.scan().ranges) for robot in fleet]  # type: ignore[union-attr]
    return scans, [(r.pose().pose.x, r.pose().pose.y, r.pose().pose.yaw) for r in fleet]  # type: ignore[union-attr]


def test_fleet_is_deterministic_per_seed() -> None:
    """The same seed gives the same scans and pose estimates; another seed gives other noise."""
    a, b, c = _run(5), _run(5), _run(6)
    for x, y in zip(a[0], b[0], strict=True):
        np.testing.assert_array_equal(x, y)
    assert a[1] == b[1]
    assert not np.array_equal(a[0][1], c[0][1])


def test_a_fleet_of_one_is_the_single_robot() -> None:
    """A one-robot fleet produces the single SimRobot's scans and trajectory exactly."""
    single = create_robot({"world": "conformance", "seed": 4})
    fleet = create_fleet("conformance", robots=1, seed=4)
    for robot in (single, fleet[0]):
        robot.navigate_to(Pose2D(4.2, 4.2, 0.0))
        robot.spin_until(6.0)
    np.testing.assert_array_equal(single.scan().ranges, fleet[0].scan().ranges)  # type: ignore[union-attr]
    assert single.trajectory == fleet[0].trajectory


def test_robot_seeds_keep_the_run_seed_for_the_first_robot() -> None:
    """Robot 0 uses the run seed itself; the others get distinct seeds derived from it."""
    assert robot_seed(7, 0) == 7
    assert len({robot_seed(7, i) for i in range(8)}) == 8


def test_automatic_starts_are_free_spaced_and_begin_at_the_world_start() -> None:
    """Default starts: the world's start first, every start clear of walls, bodies kept apart."""
    world = load_world("office")
    starts = fleet_starts(world, 4, 0.17)
    assert starts[0] == world.start
    for i, a in enumerate(starts):
        assert world.clearance(a.x, a.y) >= 0.17
        for b in starts[i + 1:]:
            assert math.hypot(a.x - b.x, a.y - b.y) >= 2 * 0.17 + 0.5 - 1e-9


def test_overlapping_starts_are_a_config_error() -> None:
    """Two robots given starts closer than their bodies allow are refused, naming both."""
    with pytest.raises(ConfigError, match="robot1 and robot2"):
        _pair(Pose2D(1.2, 2.5, 0.0))


def test_too_many_robots_is_a_config_error() -> None:
    """A count past the limit is refused with the allowed range."""
    with pytest.raises(ConfigError, match="from 1 to"):
        create_fleet("conformance", robots=40)


def test_truth_reports_every_robot() -> None:
    """The fleet's ground truth reports each robot's pose, distance and bumps, and the closest approach."""
    fleet = create_fleet("office", robots=3, seed=0)
    fleet[1].drive(0.2, 0.0)
    fleet.spin_until(2.0)
    report = fleet.truth.report()
    assert set(report["robots"]) == {"robot1", "robot2", "robot3"}
    assert report["robots"]["robot2"]["driven_m"] > 0.2
    assert report["robots"]["robot1"]["driven_m"] == 0.0
    assert report["min_separation"]["gap_m"] > -1e-6
    assert create_fleet("office", robots=1).truth.report()["min_separation"] is None


class _FleetConformance(RobotConformance):
    """The conformance suite for one robot of a two-robot fleet in the conformance room."""

    index = 0

    @pytest.fixture
    def robot(self, conformance_world: str) -> Iterator[FleetRobot]:
        # the second robot stands 0.9 m to the right of the first, off every goal's path and beam
        fleet = create_fleet(conformance_world, robots=2, seed=3, starts=[WEST, Pose2D(1.0, 1.6, 0.0)])
        yield fleet[self.index]
        fleet.close()

    @pytest.fixture
    def silence(self, robot: FleetRobot) -> Callable[[str], None]:
        return robot.silence


class TestFirstFleetRobotConformance(_FleetConformance):
    index = 0


class TestSecondFleetRobotConformance(_FleetConformance):
    index = 1


def test_unknown_map_marks_the_other_robot_and_clears_it_once_gone() -> None:
    """Learning its map, a robot marks the other's body occupied, and free again after it drove away."""
    fleet = create_fleet("conformance", robots=2, seed=0, starts=[WEST, Pose2D(2.6, 2.5, 0.0)],
                         unknown_map=True)
    fleet.spin_until(0.5)
    grid = fleet[0].occupancy()
    assert grid is not None
    row, col = grid.world_to_cell(2.6 - fleet.radius, 2.5)
    assert grid.data[row, col] == 100
    away = fleet[1].navigate_to(Pose2D(2.6, 4.2, 0.0), Tolerance(xy=0.25, yaw=ANY))
    _spin(fleet, 30.0, until=lambda: away.status().done)
    assert away.status() is ActionStatus.SUCCEEDED
    fleet.spin_until(fleet.now() + 2.0)
    grid = fleet[0].occupancy()
    assert grid is not None
    assert grid.data[row, col] == 0


def test_top_down_picture_draws_the_other_robots(tmp_path: Path) -> None:
    """A fleet robot's picture shows the other robot in its own colour; a single robot's has none of it."""
    fleet = _pair(Pose2D(2.5, 2.5, math.pi / 2))
    fleet[1].drive(0.2, 0.0)
    fleet.spin_until(3.0)
    single = create_robot({"world": "conformance"})

    def other_pixels(robot: object, out: Path) -> int:
        [path] = robot.draw(out, [])  # type: ignore[attr-defined]
        image = cv2.imread(str(path))
        return int(np.all(image == np.array(OTHER_ROBOT_BGR), axis=2).sum())

    assert other_pixels(fleet[0], tmp_path / "fleet") > 50
    assert other_pixels(single, tmp_path / "single") == 0
