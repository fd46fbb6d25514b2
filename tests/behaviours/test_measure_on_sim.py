"""The three distance methods on the simulator: seed 001's field-of-view mismatch, and its fix."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from missiontree.backends.sim import create_robot
from missiontree.behaviours.measure import measure
from missiontree.types import Detection

ROBOT = (1.0, 2.0)


def world_with_person(tmp_path: Path, bearing_deg: float, distance: float) -> tuple[Path, tuple[float, ...]]:
    """A 6 x 4 m room, the robot facing +x towards the wall 5 m ahead, one person standing still."""
    b = math.radians(bearing_deg)
    person = (ROBOT[0] + distance * math.cos(b), ROBOT[1] + distance * math.sin(b))
    world = {
        "name": "offaxis", "description": "one person standing off the robot's axis",
        "robot": {"profile": "turtlebot4", "start": {"x": ROBOT[0], "y": ROBOT[1], "yaw": 0.0}},
        "walls": {"height": 2.5, "thickness": 0.1, "polygons": [[[0, 0], [6, 0], [6, 4], [0, 4]]]},
        "rooms": [], "objects": [],
        "people": [{"id": "p1", "route": [list(person)], "speed": 0.0}],
    }
    path = tmp_path / "offaxis.yaml"
    path.write_text(yaml.safe_dump(world))
    return path, person


def person_box(robot, stamp: float) -> Detection:  # noqa: ANN001 - SimRobot, truth used for the oracle box
    """The person's box from the simulator's instance mask (a simulation oracle, as a perfect detector)."""
    mask = robot.truth.instance_mask(stamp)
    person_ids = [k for k, v in robot.truth.instances.items() if v.kind == "person"]
    hit = np.isin(mask, person_ids)
    cols, rows = np.flatnonzero(hit.any(axis=0)), np.flatnonzero(hit.any(axis=1))
    box = (float(cols[0]), float(rows[0]), float(cols[-1] + 1), float(rows[-1] + 1))
    return Detection("person", 1.0, box)


@pytest.mark.parametrize("bearing_deg", [25.0, -25.0])
def test_person_25_degrees_off_axis_is_measured_right_by_cone_and_depth_wrong_by_seed(
        tmp_path: Path, bearing_deg: float) -> None:
    """Seed 001 §4.5.8: at 25° the ±15° cone reads the wall (~5 m); the box cone and depth read ~1.2 m."""
    path, person = world_with_person(tmp_path, bearing_deg, 1.2)
    robot = create_robot({"world": str(path), "seed": 3})
    robot.spin_until(1.0)
    frame = robot.rgbd()
    assert frame is not None
    box = person_box(robot, frame.stamp)
    results = {m: measure(robot, frame, box, m) for m in ("seed", "cone", "depth")}
    assert results["seed"].distance > 4.5  # the back wall, as the seed found
    for method in ("cone", "depth"):
        got = results[method]
        assert got.distance == pytest.approx(1.2, abs=0.15), method
        assert got.position == pytest.approx(person, abs=0.15), method
        assert math.degrees(got.bearing) == pytest.approx(bearing_deg, abs=3.0), method


def test_person_straight_ahead_is_measured_right_by_all_three(tmp_path: Path) -> None:
    """Straight ahead the seed's cone works too (its nominal case, seed 001 Figure 4.3)."""
    path, _ = world_with_person(tmp_path, 0.0, 1.5)
    robot = create_robot({"world": str(path), "seed": 3})
    robot.spin_until(1.0)
    frame = robot.rgbd()
    box = person_box(robot, frame.stamp)
    for method in ("seed", "cone", "depth"):
        assert measure(robot, frame, box, method, surface_offset=0.1).distance == pytest.approx(
            1.5, abs=0.2), method


def test_person_behind_low_furniture_is_measured_at_the_person_not_the_furniture(tmp_path: Path) -> None:
    """A person 3.5 m ahead behind a 0.8 m sofa at 2 m, boxed whole: depth reads the person, not the sofa."""
    path, person = world_with_person(tmp_path, 0.0, 3.5)
    robot = create_robot({"world": str(path), "seed": 3})
    robot.spin_until(1.0)
    frame = robot.rgbd()
    assert frame is not None
    whole = person_box(robot, frame.stamp)  # the whole person, as a detector boxes someone partly hidden
    robot.close()
    world = yaml.safe_load(path.read_text())
    world["objects"] = [{"id": "sofa_1", "label": "sofa", "color": "grey", "size": [0.9, 1.6, 0.8],
                         "pose": {"x": ROBOT[0] + 2.0, "y": ROBOT[1]}}]
    path.write_text(yaml.safe_dump(world))
    robot = create_robot({"world": str(path), "seed": 3})
    robot.spin_until(1.0)
    frame = robot.rgbd()
    assert frame is not None
    got = measure(robot, frame, whole, "depth", surface_offset=0.1)
    assert got is not None and got.method == "depth"
    assert got.distance == pytest.approx(3.5, abs=0.25)
    assert got.position == pytest.approx(person, abs=0.25)


def test_person_too_near_to_show_their_chest_is_measured_at_their_legs(tmp_path: Path) -> None:
    """A person 0.5 m ahead, boxed short of the image's top, is read at their legs, not at the wall behind."""
    path, _ = world_with_person(tmp_path, 0.0, 0.5)
    robot = create_robot({"world": str(path), "seed": 3})
    robot.spin_until(1.0)
    frame = robot.rgbd()
    assert frame is not None
    x1, _, x2, y2 = person_box(robot, frame.stamp).box
    got = measure(robot, frame, Detection("person", 1.0, (x1, 30.0, x2, y2)), "depth", surface_offset=0.1)
    assert got is not None
    assert got.distance == pytest.approx(0.5, abs=0.2)
