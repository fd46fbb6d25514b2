"""The shipped detector (``sim_detector``) on real images: MRPT's Kinect frame and Middlebury's pair.

It was trained on simulator renders only; these tests check what a person checks by eye, not a
score: it runs, its boxes lie in the image, and what it finds sits where the real depth says.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from missiontree.mapping.mrpt_datasets import find_dataset, missing_reason
from missiontree.mapping.mrpt_rgbd import read_rgbd_frames
from missiontree.perception.detectors import iou_matrix
from missiontree.perception.projection import project
from missiontree.perception.providers import create_sim_detector
from missiontree.perception.stereo import StereoCalibration, disparity_to_depth, stereo_disparity
from missiontree.types import CameraIntrinsics, Detection, Pose2D, RGBDFrame

pytestmark = pytest.mark.realdata

RGBD = "tests_rgbd.rawlog"
#: The bookshelf in the Kinect frame, drawn by eye (x1, y1, x2, y2): its top board to the frame's foot.
SHELF = (85.0, 195.0, 590.0, 480.0)
#: The Middlebury motorcycle pair's calibration for scikit-image's 4x down-sampled images.
MOTORCYCLE = StereoCalibration(focal=994.978, baseline=0.193001, cx=311.193, cy=254.877, doffs=31.086)


def iou(a: tuple[float, ...], b: tuple[float, ...]) -> float:
    """Intersection over union of two (x1, y1, x2, y2) boxes (the detector's own iou_matrix)."""
    return float(iou_matrix(np.array([a], float), np.array([b], float))[0, 0])


def assert_boxes_in_image(found: list[Detection], width: int, height: int) -> None:
    """Every box is finite, non-empty and inside the image; every score in [0, 1]."""
    for det in found:
        x1, y1, x2, y2 = det.box
        assert all(math.isfinite(v) for v in det.box), det
        assert -1 <= x1 < x2 <= width + 1 and -1 <= y1 < y2 <= height + 1, det
        assert 0.0 <= det.score <= 1.0


@pytest.fixture(scope="module")
def detector():  # noqa: ANN201 - the shipped YoloOnnxDetector
    pytest.importorskip("onnxruntime", reason="onnxruntime is not installed")
    return create_sim_detector({})


@pytest.fixture(scope="module")
def kinect_frame() -> RGBDFrame:
    path = find_dataset(RGBD)
    if path is None:
        pytest.skip(missing_reason(RGBD))
    return read_rgbd_frames(path)[0].to_frame(camera_height=1.0)


def test_detector_runs_on_the_kinect_frame_with_boxes_in_the_image(detector, kinect_frame) -> None:  # noqa: ANN001
    """On the real Kinect frame the shipped detector answers with finite boxes inside the 640 x 480 image."""
    found = detector.detect(kinect_frame.color)
    assert found, "the shipped detector found nothing at its threshold on the Kinect frame"
    assert_boxes_in_image(found, 640, 480)


def test_kinect_detections_sit_between_the_camera_and_the_wall(detector, kinect_frame) -> None:  # noqa: ANN001
    """Whatever it finds projects from the real depth to 1.5-2.6 m ahead (the shelf to the wall), in view."""
    found = detector.detect(kinect_frame.color)
    placed = [(det, project(kinect_frame, det, method="robust")) for det in found]
    assert any(p is not None for _, p in placed)
    half_fov = kinect_frame.intrinsics.hfov / 2
    for det, where in placed:
        if where is None:  # a box on depth holes only
            continue
        x, y = where.position[0], where.position[1]
        assert 1.5 < where.depth < 2.6, det
        assert abs(math.atan2(y, x)) < half_fov + 0.05, det
        assert np.all(np.isfinite(where.size)) and 0.0 < where.size[0] < 3.0, det


def test_kinect_bookshelf_is_found_on_the_bookshelf_in_front_of_the_wall(detector, kinect_frame) -> None:  # noqa: ANN001
    """A bookshelf box covers part of the real bookshelf and projects nearer than the wall above it."""
    found = detector.detect(kinect_frame.color)
    shelves = [d for d in found if d.label == "bookshelf" and iou(d.box, SHELF) > 0.3]
    assert shelves, "no bookshelf box on the bookshelf"
    where = project(kinect_frame, max(shelves, key=lambda d: d.score), method="robust")
    assert where is not None
    assert 1.6 < where.depth < np.nanmedian(kinect_frame.depth[:100])


def test_detector_on_the_middlebury_pair_places_its_boxes_at_stereo_depth(detector) -> None:  # noqa: ANN001
    """On Middlebury's motorcycle the boxes lie in the image and project 1.5-8 m ahead by stereo depth."""
    data = pytest.importorskip("skimage.data", reason="scikit-image (the realdata extra) is not installed")
    left, right, _ = data.stereo_motorcycle()
    depth = disparity_to_depth(stereo_disparity(left, right, max_disparity=64), MOTORCYCLE).astype(np.float32)
    h, w = depth.shape
    k = CameraIntrinsics(w, h, MOTORCYCLE.focal, MOTORCYCLE.focal, MOTORCYCLE.cx, MOTORCYCLE.cy)
    frame = RGBDFrame(0.0, left, depth, k, Pose2D(0.0, 0.0, 0.0), 1.0)
    found = detector.detect(left)
    assert found
    assert_boxes_in_image(found, w, h)
    placed = [project(frame, det, method="robust") for det in found]
    assert any(p is not None for p in placed)
    for where in placed:
        if where is not None:
            assert 1.5 < where.depth < 8.0
