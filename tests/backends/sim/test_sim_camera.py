"""RGB-D rendering against geometry: wall and floor depth, objects' colour and mask, people, sizes."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import ROOM

from missiontree.backends.sim import create_robot
from missiontree.backends.sim.camera import intrinsics_for
from missiontree.backends.sim.schema import CameraSpec

CAM_X = 2.0 + 0.06   # the camera sits 6 cm ahead of the robot centre
CAM_H = 0.40


def _columns_a(frame):
    k = frame.intrinsics
    return (k.cx - np.arange(k.width)) / k.fx


def _rows_b(frame):
    k = frame.intrinsics
    return (k.cy - np.arange(k.height)) / k.fy


def test_perpendicular_wall_has_constant_depth(write_world):
    """Every pixel on the wall straight ahead reads its distance along the optical axis (±1 cm)."""
    robot = create_robot({"world": write_world(ROOM)})
    frame = robot.rgbd()
    mask = robot.truth.instance_mask(frame.stamp)
    a, b = _columns_a(frame), _rows_b(frame)
    d = 6.0 - CAM_X
    cols = (1.5 + d * a > 0.05) & (1.5 + d * a < 3.95)
    rows = (CAM_H + d * b > 0.02) & (CAM_H + d * b < 2.48)
    region = np.ix_(rows, cols)
    assert (mask[region] == 1).all()
    assert np.max(np.abs(frame.depth[region] - d)) < 0.01


def test_floor_depth_follows_camera_height(write_world):
    """A floor pixel in row v reads depth h * fy / (v - cy), where its ray meets the floor."""
    robot = create_robot({"world": write_world(ROOM)})
    frame = robot.rgbd()
    k = frame.intrinsics
    b = _rows_b(frame)
    mask = robot.truth.instance_mask(frame.stamp)
    floor_rows = np.flatnonzero(-b * (6.0 - CAM_X) > CAM_H + 0.05)
    assert len(floor_rows) > 10
    expected = CAM_H / (-b[floor_rows])
    u = int(round(k.cx))
    assert (mask[floor_rows, u] == 0).all()
    assert np.max(np.abs(frame.depth[floor_rows, u] - expected)) < 0.01


def test_box_front_face_depth_colour_and_mask(write_world):
    """A red box ahead shows red at its front-face depth, and the mask names it."""
    text = ROOM + """
objects:
  - {id: red_box, label: box, color: red, size: [0.4, 0.6, 0.8], pose: {x: 4.0, y: 1.5}}
"""
    robot = create_robot({"world": write_world(text)})
    frame = robot.rgbd()
    k = frame.intrinsics
    u, v = int(round(k.cx)), int(round(k.cy))
    assert frame.depth[v, u] == pytest.approx(3.8 - CAM_X, abs=0.01)
    r, g, bl = frame.color[v, u].astype(int)
    assert r > 120 and r > 3 * g and r > 3 * bl
    inst = robot.truth.instance_mask(frame.stamp)[v, u]
    assert robot.truth.instances[inst].name == "red_box"
    assert "red_box" in robot.truth.visible_at(frame.stamp)


def test_low_box_shows_its_top(write_world):
    """A box lower than the camera shows its top: pixels of it deeper than its front face."""
    text = ROOM + """
objects:
  - {id: low, label: box, color: blue, size: [0.6, 0.6, 0.2], pose: {x: 3.5, y: 1.5}}
"""
    robot = create_robot({"world": write_world(text)})
    frame = robot.rgbd()
    mask = robot.truth.instance_mask(frame.stamp)
    inst = next(i for i, info in robot.truth.instances.items() if info.name == "low")
    depths = frame.depth[mask == inst]
    front = 3.2 - CAM_X
    assert depths.min() == pytest.approx(front, abs=0.01)
    assert depths.max() > front + 0.3


def test_numba_and_numpy_render_the_same_image():
    """The accelerated and the numpy renderers give identical colour, depth and mask."""
    images = []
    for accelerate in (True, False):
        robot = create_robot({"world": "office", "config": {"accelerate": accelerate}})
        robot.drive(0.0, 0.6)
        robot.spin_until(1.0)
        frame = robot.rgbd()
        images.append((frame.color, frame.depth, robot.truth.instance_mask(frame.stamp)))
    (c1, d1, m1), (c2, d2, m2) = images
    assert np.array_equal(c1, c2) and np.array_equal(m1, m2)
    assert np.allclose(d1, d2, equal_nan=True)


def test_people_are_rendered_and_recorded_as_visible(write_world):
    """A person standing ahead fills pixels of the frame and ground truth lists them as visible."""
    text = ROOM + """
people:
  - {id: alice, route: [[4.0, 1.5]], speed: 0.0, shirt_rgb: [0, 200, 0]}
"""
    robot = create_robot({"world": write_world(text)})
    frame = robot.rgbd()
    seen = robot.truth.visible_at(frame.stamp)
    assert seen["alice"].kind == "person" and seen["alice"].pixels > 500
    k = frame.intrinsics
    torso_row = int(round(k.cy - (1.1 - CAM_H) / (4.0 - 0.19 - CAM_X) * k.fy))
    r, g, b = frame.color[torso_row, int(round(k.cx))].astype(int)
    assert g > 100 and g > 2 * r


def test_image_size_and_field_of_view_are_configurable():
    """Width, height and horizontal field of view follow the configuration."""
    robot = create_robot({"world": "conformance", "config": {"camera": {"width": 160, "height": 100,
                                                                         "hfov_deg": 60}}})
    frame = robot.rgbd()
    assert frame.color.shape == (100, 160, 3) and frame.depth.shape == (100, 160)
    assert math.degrees(frame.intrinsics.hfov) == pytest.approx(60.0)
    assert intrinsics_for(CameraSpec()).width == 320


def test_frame_carries_the_estimated_camera_pose(write_world):
    """The frame's camera pose is the robot's estimate moved to the camera mount."""
    robot = create_robot({"world": write_world(ROOM)})
    frame = robot.rgbd()
    assert frame.camera_pose.x == pytest.approx(CAM_X) and frame.camera_pose.y == pytest.approx(1.5)
    assert frame.camera_height == pytest.approx(CAM_H)


def test_kept_masks_are_uint16_and_name_the_same_instances(write_world):
    """The truth keeps each frame's mask in half the memory (uint16), with the camera's instance ids."""
    robot = create_robot({"world": write_world(ROOM)})
    frame = robot.rgbd()
    mask = robot.truth.instance_mask(frame.stamp)
    assert mask.dtype == np.uint16
    assert mask.shape == frame.depth.shape
    assert set(np.unique(mask).tolist()) <= set(robot.truth.instances) | {0}
    assert (mask == 1).any()  # the wall ahead
