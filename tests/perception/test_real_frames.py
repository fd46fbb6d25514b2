"""Perception on real frames: MRPT's Kinect frame (mrpt-common) and scikit-image's Middlebury stereo pair."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from missiontree.mapping.mrpt_archive import ArchiveError
from missiontree.mapping.mrpt_datasets import find_dataset, missing_reason
from missiontree.mapping.mrpt_rgbd import read_rgbd_frames
from missiontree.perception.colour import dominant_colour
from missiontree.perception.depth_geometry import (
    back_project,
    find_floor,
    fit_plane,
    remove_plane,
    valid_share,
)
from missiontree.perception.projection import project
from missiontree.perception.stereo import StereoCalibration, disparity_to_depth, stereo_disparity
from missiontree.types import CameraIntrinsics, Detection

RGBD = find_dataset("tests_rgbd.rawlog") or Path("/nonexistent/tests_rgbd.rawlog")
MISSING = missing_reason("tests_rgbd.rawlog")
#: The Middlebury motorcycle pair's calibration for scikit-image's 4x down-sampled images (its docstring).
MOTORCYCLE = StereoCalibration(focal=994.978, baseline=0.193001, cx=311.193, cy=254.877, doffs=31.086)
#: Box (x1, y1, x2, y2) of the black briefcase on top of the bookshelf, read off the colour image by eye.
BRIEFCASE = (135.0, 155.0, 285.0, 200.0)


def level_floor_depth(height: float = 0.3,
                      size: tuple[int, int] = (120, 160)) -> tuple[np.ndarray, CameraIntrinsics]:
    """Depth of a level camera ``height`` m over a flat floor (rows above the horizon see nothing)."""
    rows, cols = size
    k = CameraIntrinsics(cols, rows, 100.0, 100.0, cols / 2, rows / 2)
    v = np.arange(rows)[:, None].repeat(cols, axis=1).astype(float)
    with np.errstate(divide="ignore"):
        depth = np.where(v > k.cy + 1, height * k.fy / (v - k.cy), np.nan)
    return depth.astype(np.float32), k


def test_floor_of_a_level_camera_is_its_height_below() -> None:
    """A level camera 0.3 m over a floor finds the floor 0.3 m below, facing up."""
    depth, k = level_floor_depth()
    floor = find_floor(back_project(depth, k))
    assert floor is not None
    assert floor.distance == pytest.approx(0.3, abs=0.005)
    assert floor.angle_to(np.array([0.0, -1.0, 0.0])) < math.radians(1)


def test_removing_the_floor_keeps_what_stands_on_it() -> None:
    """With the floor removed, only the box standing on it is left."""
    depth, k = level_floor_depth()
    depth[70:85, 70:90] = 1.0  # a box face 1 m ahead, 0.1 to 0.24 m below the eye
    points = back_project(depth, k)
    floor = find_floor(points)
    assert floor is not None
    left = remove_plane(points, floor)
    assert len(left) == 300 and np.allclose(left[:, 2], 1.0)


def test_a_ceiling_is_no_floor() -> None:
    """A horizontal plane above the camera is not taken for the floor."""
    depth, k = level_floor_depth()
    assert find_floor(back_project(depth[::-1].copy(), k)) is None


def test_disparity_to_depth_leaves_unknown_as_nan() -> None:
    """Disparities that are NaN, inf or make a non-positive sum give NaN depth, not 0 or inf."""
    calibration = StereoCalibration(100, 0.1, 0, 0, 30)
    depth = disparity_to_depth(np.array([10.0, np.nan, np.inf, -40.0]), calibration)
    assert depth[0] == pytest.approx(0.25) and np.isnan(depth[1:]).all()


def test_an_rgbd_reader_refuses_other_observations(tmp_path: Path) -> None:
    """A rawlog of 2-D scans is no RGB-D log: the reader names the class it found."""
    name = b"CObservation2DRangeScan"
    path = tmp_path / "scans.rawlog"
    path.write_bytes(bytes([0x80 | len(name)]) + name + b"\x06")
    with pytest.raises(ArchiveError, match="CObservation2DRangeScan"):
        read_rgbd_frames(path)


@pytest.fixture(scope="module")
def kinect():  # noqa: ANN201 - the RgbdObservation
    if not RGBD.is_file():
        pytest.skip(MISSING)
    return read_rgbd_frames(RGBD)[0]


@pytest.mark.realdata
def test_kinect_frame_reads_with_its_holes(kinect) -> None:  # noqa: ANN001
    """The Kinect frame is 640 x 480 depth and colour; a tenth of its depth is missing, the rest 1.5-2.6 m."""
    assert kinect.depth.shape == (480, 640) and kinect.color.shape == (480, 640, 3)
    assert 0.85 < valid_share(kinect.depth) < 0.95
    assert 1.5 < np.nanmin(kinect.depth) and np.nanmax(kinect.depth) < 2.6
    assert kinect.depth_camera.fx == pytest.approx(572.88, abs=0.01)


@pytest.mark.realdata
def test_kinect_wall_above_the_shelf_is_a_flat_plane_2_2_m_away(kinect) -> None:  # noqa: ANN001
    """The bare wall above the bookshelf is one plane, flat to 2 cm, about 2.2 m away, facing the camera."""
    frame = kinect.to_frame()
    wall = fit_plane(back_project(frame.depth[:130], frame.intrinsics, step=2))
    assert wall is not None
    assert 2.0 < wall.distance < 2.4
    assert wall.rms < 0.02 and wall.share > 0.6
    assert wall.angle_to(np.array([0.0, 0.0, 1.0])) < math.radians(20)


@pytest.mark.realdata
def test_kinect_frame_shows_no_floor(kinect) -> None:  # noqa: ANN001
    """The frame shows a bookshelf and a wall: no floor is found (shelf boards are not taken for one)."""
    frame = kinect.to_frame()
    assert find_floor(back_project(frame.depth, frame.intrinsics, step=4)) is None


@pytest.mark.realdata
def test_kinect_briefcase_sits_in_front_of_the_wall(kinect) -> None:  # noqa: ANN001
    """The briefcase projects 1.7-1.9 m ahead, left of centre, about 0.45 m wide, nearer than the wall."""
    frame = kinect.to_frame(camera_height=1.0)
    found = project(frame, Detection("suitcase", 0.9, BRIEFCASE), method="robust")
    assert found is not None
    assert 1.7 < found.depth < 1.9 < np.nanmedian(frame.depth[:100])
    assert found.position[1] > 0.2  # left of the optical axis (y to the left in the map frame)
    assert 0.35 < found.size[0] < 0.6


@pytest.mark.realdata
def test_kinect_colours_are_named_as_seen(kinect) -> None:  # noqa: ANN001
    """The wall reads white, the briefcase black, the shelf's top board brown."""
    assert dominant_colour(kinect.color, (100, 10, 500, 120)).name == "white"
    assert dominant_colour(kinect.color, BRIEFCASE).name == "black"
    assert dominant_colour(kinect.color, (100, 200, 600, 215)).name == "brown"


@pytest.mark.realdata
def test_stereo_depth_of_the_middlebury_motorcycle_matches_its_ground_truth() -> None:
    """Semi-global matching covers 80 % of the motorcycle pair, 85 % of that within 5 % of the true depth."""
    data = pytest.importorskip("skimage.data", reason="scikit-image (the realdata extra) is not installed")
    left, right, truth = data.stereo_motorcycle()
    depth = disparity_to_depth(stereo_disparity(left, right, max_disparity=64), MOTORCYCLE)
    true_depth = disparity_to_depth(truth, MOTORCYCLE)
    both = np.isfinite(depth) & np.isfinite(true_depth)
    error = np.abs(depth[both] - true_depth[both]) / true_depth[both]
    assert np.isfinite(depth).mean() > 0.8
    assert np.mean(error < 0.05) > 0.85
    assert 2.0 < np.nanmedian(depth) < 4.0  # the motorcycle stands 2 to 4 m from the cameras
