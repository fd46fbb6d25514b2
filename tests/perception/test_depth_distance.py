"""Tests of the depth distance method (c) and the projection of detections to map positions."""

from __future__ import annotations

import math

import numpy as np
import pytest

from missiontree.perception.depth import box_depth, centre_region, detection_position, pixel_to_map
from missiontree.types import CameraIntrinsics, Detection, Pose2D, RGBDFrame

K = CameraIntrinsics(width=320, height=240, fx=228.5, fy=228.5, cx=160.0, cy=120.0)


ORIGIN = Pose2D(0.0, 0.0, 0.0)


def frame_with(depth: np.ndarray, pose: Pose2D = ORIGIN) -> RGBDFrame:
    return RGBDFrame(1.0, np.zeros((240, 320, 3), np.uint8), depth.astype(np.float32), K, pose)


def person_frame(person_depth: float, x1: int, x2: int, background: float = 6.0) -> RGBDFrame:
    """A wall at ``background`` with a person slab at ``person_depth`` between columns x1 and x2."""
    depth = np.full((240, 320), background)
    depth[40:230, x1:x2] = person_depth
    depth[150:230, (x1 + x2) // 2 - 2:(x1 + x2) // 2 + 2] = background  # gap between the legs
    return frame_with(depth)


def test_centre_region_is_clipped_to_the_image() -> None:
    """The centre region of a box hanging off the image's edge stays inside it."""
    assert centre_region((300, 100, 400, 200), 320, 240) == (305, 125, 315, 175)


def test_box_depth_ignores_background_between_legs() -> None:
    """The median of the nearest cluster is the person's depth, not the wall seen between the legs."""
    frame = person_frame(1.6, 140, 180)
    reading = box_depth(frame, (135, 35, 185, 235))
    assert reading.found
    assert reading.depth == pytest.approx(1.6)


def test_box_depth_when_background_dominates_box_edges() -> None:
    """A loose box whose centre still holds the person measures the person."""
    frame = person_frame(2.0, 150, 170)
    assert box_depth(frame, (110, 20, 210, 239)).depth == pytest.approx(2.0)


def test_box_depth_ignores_invalid_pixels() -> None:
    """NaN and zero depths are skipped; an all-invalid box reports nothing found."""
    depth = np.full((240, 320), np.nan)
    depth[:, :10] = 0.0
    assert not box_depth(frame_with(depth), (0, 0, 50, 50)).found


def test_box_depth_uses_mask_when_given() -> None:
    """With an instance mask only the masked pixels count."""
    depth = np.full((240, 320), 4.0)
    depth[100:140, 150:170] = 1.2
    mask = np.zeros((240, 320), bool)
    mask[100:140, 150:152] = True
    frame = frame_with(depth)
    assert box_depth(frame, (100, 80, 220, 160), mask=mask).depth == pytest.approx(1.2)


def test_pixel_to_map_projects_through_camera_pose() -> None:
    """A pixel at the principal point at depth 2 lies 2 m along the camera's heading."""
    frame = frame_with(np.ones((240, 320)), Pose2D(1.0, 2.0, math.pi / 2))
    assert pixel_to_map(frame, K.cx, 2.0) == pytest.approx((1.0, 4.0))


@pytest.mark.parametrize("bearing_deg", [-30, -25, 0, 15, 25, 30])
def test_detection_position_recovers_off_axis_person(bearing_deg: float) -> None:
    """A person at 1.2 m range and any bearing in the field of view is placed within 2 cm."""
    bearing = math.radians(bearing_deg)
    rng = 1.2
    z = rng * math.cos(bearing)
    u = K.cx - math.tan(bearing) * K.fx
    depth = np.full((240, 320), 6.0)
    depth[40:230, int(u) - 12:int(u) + 12] = z
    det = Detection("person", 0.9, (u - 12, 40, u + 12, 230))
    x, y, measured = detection_position(frame_with(depth, Pose2D(0.5, -0.5, 0.0)), det)
    assert measured == pytest.approx(rng, abs=0.02)
    assert (x, y) == pytest.approx((0.5 + rng * math.cos(bearing), -0.5 + rng * math.sin(bearing)), abs=0.02)


def test_detection_position_adds_surface_offset_along_the_ray() -> None:
    """The surface offset moves the estimate away from the camera along the ray to the centre."""
    depth = np.full((240, 320), 6.0)
    depth[40:230, 150:170] = 2.0
    det = Detection("person", 0.9, (150, 40, 170, 230))
    x, y, rng = detection_position(frame_with(depth), det, surface_offset=0.15)
    assert rng == pytest.approx(2.15, abs=0.01)
    assert x == pytest.approx(2.15, abs=0.01)


def test_box_depth_drops_the_floor_at_the_persons_feet() -> None:
    """Floor pixels in the box's lower part (nearer than the person) are not taken as the target."""
    k = K
    depth = np.full((240, 320), 6.0)
    rows = np.arange(240)[:, None]
    floor = np.where(rows > k.cy + 1, 0.4 * k.fy / np.maximum(rows - k.cy, 1e-6), np.inf)  # camera 0.4 m high
    depth = np.minimum(depth, np.broadcast_to(floor, depth.shape))
    depth[20:150, 140:180] = 2.5  # the person's body above the floor line
    frame = RGBDFrame(1.0, np.zeros((240, 320, 3), np.uint8), depth.astype(np.float32), K, ORIGIN, 0.4)
    reading = box_depth(frame, (130, 20, 190, 239))
    assert reading.depth == pytest.approx(2.5)


def test_box_depth_finds_the_target_in_a_loose_box() -> None:
    """A box much wider than the person still measures the person, and says in which column they are."""
    depth = np.full((240, 320), 5.0)
    depth[30:230, 200:230] = 1.8
    reading = box_depth(frame_with(depth), (100, 20, 240, 235))
    assert reading.depth == pytest.approx(1.8)
    assert reading.column == pytest.approx(214.5, abs=1.0)
