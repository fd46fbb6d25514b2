"""Tests of the detector's reuse: a frame detected once, a model file opened once per process."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from perception_onnx import constant_yolo_model, yolo_output

from missiontree.perception.detectors import CLASS_SCORES, YoloOnnxDetector

NAMES = "{0: 'person', 1: 'cup'}"


def _model(tmp_path: Path) -> Path:
    out = yolo_output([(32, 32, 20, 10, [0.9, 0.0]), (10, 30, 6, 6, [0.0, 0.6])], 2)
    return constant_yolo_model(tmp_path / "m.onnx", out, names=NAMES)


def _counting(detector: YoloOnnxDetector) -> list[int]:
    runs: list[int] = []
    original = detector._run

    def run(tensor: np.ndarray) -> np.ndarray:
        runs.append(1)
        return original(tensor)

    detector._run = run  # type: ignore[method-assign]
    return runs


def test_the_same_frame_is_detected_once(tmp_path: Path) -> None:
    """A second detect on equal pixels (a copy, too) answers from memory without running the model."""
    detector = YoloOnnxDetector(_model(tmp_path))
    runs = _counting(detector)
    image = np.zeros((32, 64, 3), dtype=np.uint8)
    first = detector.detect(image)
    second = detector.detect(image.copy())
    assert len(runs) == 1
    assert [(d.label, d.score, d.box) for d in first] == [(d.label, d.score, d.box) for d in second]


def test_another_frame_runs_the_model(tmp_path: Path) -> None:
    """A frame whose pixels differ is detected anew."""
    detector = YoloOnnxDetector(_model(tmp_path))
    runs = _counting(detector)
    image = np.zeros((32, 64, 3), dtype=np.uint8)
    detector.detect(image)
    image[0, 0, 0] = 1
    detector.detect(image)
    assert len(runs) == 2


def test_a_caller_changing_its_detections_does_not_change_the_remembered_ones(tmp_path: Path) -> None:
    """Each answer is the caller's own copy: editing its attributes leaves the next answer as it was."""
    detector = YoloOnnxDetector(_model(tmp_path))
    image = np.zeros((32, 64, 3), dtype=np.uint8)
    first = detector.detect(image)
    first[0].attributes[CLASS_SCORES]["person"] = -1.0
    first[0].attributes["track"] = 7
    again = detector.detect(image)
    assert again[0].attributes[CLASS_SCORES]["person"] > 0 and "track" not in again[0].attributes


def test_recent_zero_detects_every_time(tmp_path: Path) -> None:
    """With recent=0 nothing is remembered."""
    detector = YoloOnnxDetector(_model(tmp_path), recent=0)
    runs = _counting(detector)
    image = np.zeros((32, 64, 3), dtype=np.uint8)
    detector.detect(image)
    detector.detect(image)
    assert len(runs) == 2


def test_detectors_on_one_model_file_share_one_session(tmp_path: Path) -> None:
    """The model file is opened once per process: a second detector on it reuses the session."""
    model = _model(tmp_path)
    assert YoloOnnxDetector(model)._session is YoloOnnxDetector(model)._session
    assert YoloOnnxDetector(model, threads=1)._session is not YoloOnnxDetector(model)._session


def test_a_frame_asked_with_and_without_the_mirror_pass_runs_its_single_pass_once(tmp_path: Path) -> None:
    """The single pass is shared by requests: mirror=False, then True, costs one more run, not two."""
    model = _model(tmp_path)
    detector = YoloOnnxDetector(model)
    runs = _counting(detector)
    image = np.zeros((32, 64, 3), dtype=np.uint8)
    detector.detect(image, mirror=False)
    mirrored = detector.detect(image, mirror=True)
    assert len(runs) == 2 and detector.passes == {"single": 1, "mirror": 1}
    fresh = YoloOnnxDetector(model, recent=0).detect(image, mirror=True)
    assert [(d.label, d.score, d.box) for d in mirrored] == [(d.label, d.score, d.box) for d in fresh]


def test_the_offline_vlm_person_check_mirrors_only_for_a_person_in_the_band(tmp_path: Path) -> None:
    """A cup in the band does not buy the offline VLM's person check a mirror pass; a person does."""
    from missiontree.reasoning.providers.offline_vlm import OfflineVisionModel

    for scores, mirrored in (([0.0, 0.5], 0), ([0.5, 0.0], 1)):
        out = yolo_output([(20, 20, 8, 8, scores)], 2)
        model = constant_yolo_model(tmp_path / f"m{mirrored}.onnx", out, names=NAMES)
        detector = YoloOnnxDetector(model, test_time_flip=True, flip_band=(0.3, 0.7), score_threshold=0.1)
        OfflineVisionModel(detector).surveillance(np.zeros((32, 64, 3), dtype=np.uint8))
        assert detector.passes == {"single": 1, "mirror": mirrored}


def test_the_reused_input_tensor_holds_what_a_fresh_one_would_across_image_shapes(tmp_path: Path) -> None:
    """Images of changing shapes (a resize among them) fill the reused tensor as preprocess does a new one."""
    detector = YoloOnnxDetector(_model(tmp_path), input_size=(64, 64))
    rng = np.random.default_rng(0)
    first = None
    for shape in ((32, 64), (64, 64), (32, 64), (20, 40), (100, 64), (32, 64)):
        image = rng.integers(0, 256, size=(*shape, 3), dtype=np.uint8)
        reused, box = detector._preprocess_reused(image)
        fresh, fresh_box = detector.preprocess(image)
        assert np.array_equal(reused, fresh) and box == fresh_box, shape
        if shape == (32, 64):
            first = reused if first is None else first
            assert reused is first  # the same buffer, not a new 1 MB tensor a call
