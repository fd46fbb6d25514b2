"""Projection of detections into the map frame, checked against the simulator's truth."""

from __future__ import annotations

import math

import numpy as np
import pytest

from missiontree.backends.sim import create_robot
from missiontree.perception.projection import camera_pose_at, centre_depth, project, to_camera
from missiontree.types import CameraIntrinsics, Detection, Pose2D, RGBDFrame


def boxes_from_truth(robot, frame) -> dict[str, tuple[float, float, float, float]]:
    """Boxes of the objects the frame shows, from the simulator's instance mask (scoring only)."""
    mask = robot.truth.instance_mask(frame.stamp)
    out = {}
    for inst, info in robot.truth.instances.items():
        if info.kind != "object":
            continue
        rows, cols = np.nonzero(mask == inst)
        inside = cols.min() > 1 and cols.max() < mask.shape[1] - 2 if len(cols) else False
        if len(rows) >= 150 and inside:  # whole in the image: a cut box shows part of the object
            out[info.name] = (
                float(cols.min()),
                float(rows.min()),
                float(cols.max() + 1),
                float(rows.max() + 1),
            )
    return out


@pytest.mark.parametrize("method", ["centre", "robust"])
def test_projected_objects_land_near_their_true_positions(method: str) -> None:
    """Boxes of objects in view, projected from depth with the frame's pose, land within 0.5 m of truth."""
    robot = create_robot({"world": "office", "seed": 3})
    robot.spin_until(0.5)
    checked = 0
    for _ in range(6):
        robot.drive(0.0, 1.0)
        robot.spin_until(robot.now() + 1.0)
        robot.stop()
        robot.spin_until(robot.now() + 0.4)
        frame = robot.rgbd()
        for name, box in boxes_from_truth(robot, frame).items():
            obj = robot.truth.object(name)
            p = project(frame, Detection(obj.label, 0.9, box), method=method)
            assert p is not None
            err = math.hypot(p.position[0] - obj.pose.x, p.position[1] - obj.pose.y)
            # within the benchmark's match radius; large furniture seen from one side: its centre lies up to
            # half its depth behind the face the camera sees
            assert err <= max(0.5, 0.35 + 0.5 * min(obj.size[0], obj.size[1])), (name, err)
            assert p.range <= 12.0
            checked += 1
    robot.close()
    assert checked >= 5


def test_centre_depth_is_the_median_of_a_small_square() -> None:
    """NAIS's depth: the median of the window at the box centre, ignoring invalid pixels."""
    depth = np.full((20, 20), 5.0, np.float32)
    depth[8:13, 8:13] = 2.0
    depth[10, 10] = np.nan
    assert centre_depth(depth, (5, 5, 15, 15), window=5) == 2.0
    assert centre_depth(depth, (5, 5, 15, 15), window=11) == 5.0
    assert math.isnan(centre_depth(np.zeros((4, 4)), (0, 0, 4, 4)))


def test_geometry_of_a_known_point() -> None:
    """A box centred 1 m right of the axis at 4 m depth lands there in the map; size from depth."""
    k = CameraIntrinsics(320, 240, 200.0, 200.0, 160.0, 120.0)
    depth = np.full((240, 240 // 240 * 320), 4.0, np.float32).reshape(240, 320)
    camera = Pose2D(1.0, 2.0, math.pi / 2)  # looking along +y
    frame = RGBDFrame(7.0, np.zeros((240, 320, 3), np.uint8), depth, k, camera, camera_height=0.4)
    u = 160.0 + 200.0 * 1.0 / 4.0  # 1 m to the right
    det = Detection("chair", 0.9, (u - 10, 100, u + 10, 140))
    p = project(frame, det, surface_offset=0.0)
    assert p.position[0] == pytest.approx(2.0) and p.position[1] == pytest.approx(6.0)
    assert p.position[2] == pytest.approx(0.4)
    assert p.size[0] == pytest.approx(0.4) and p.size[2] == pytest.approx(0.8)
    assert to_camera(camera, *p.xy) == pytest.approx((4.0, -1.0))


def test_the_pose_of_the_frames_instant_comes_from_the_history() -> None:
    """With a pose history the camera pose is the robot's pose at the frame's stamp, not the latest."""

    class History:
        def pose_at(self, stamp: float) -> Pose2D | None:
            return Pose2D(stamp, 0.0, 0.0) if stamp <= 10 else None

    k = CameraIntrinsics(4, 4, 2.0, 2.0, 2.0, 2.0)
    frame = RGBDFrame(3.0, np.zeros((4, 4, 3), np.uint8), np.ones((4, 4), np.float32), k, Pose2D(99, 99, 0))
    mount = Pose2D(0.1, 0.0, 0.0)
    assert camera_pose_at(frame, History(), mount) == Pose2D(3.1, 0.0, 0.0)
    late = RGBDFrame(11.0, frame.color, frame.depth, k, Pose2D(5, 5, 0))
    assert camera_pose_at(late, History(), mount) == Pose2D(5, 5, 0)  # outside the history: the frame's own
