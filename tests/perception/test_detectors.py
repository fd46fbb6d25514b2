from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from perception_onnx import constant_yolo_model, yolo_output

from missiontree.errors import ModelConfigError, ModelError
from missiontree.perception.detectors import (
    CLASS_SCORES,
    Detector,
    YoloOnnxDetector,
    check_image,
    checked_detections,
    decode_yolo,
    decode_yolo_with_scores,
    iou_matrix,
    letterbox,
    nms,
    parse_names,
)
from missiontree.types import Detection

NAMES = "{0: 'person', 1: 'cup'}"


def _image(h: int = 48, w: int = 64) -> np.ndarray:
    return np.zeros((h, w, 3), dtype=np.uint8)


def test_letterbox_fits_wide_image_and_pads_top_and_bottom() -> None:
    """A 2:1 image in a square input is scaled to the width and centred vertically."""
    padded, box = letterbox(np.full((50, 100, 3), 7, np.uint8), 64, 64)
    assert padded.shape == (64, 64, 3)
    assert box.scale == pytest.approx(0.64)
    assert (box.pad_x, box.pad_y) == (0.0, 16.0)
    assert (padded[:16] == 114).all() and (padded[48:] == 114).all()
    assert (padded[16:48] == 7).all()


def test_letterbox_box_maps_back_to_image_pixels() -> None:
    """A box drawn in input pixels maps back to the same place in the original image."""
    _, box = letterbox(_image(240, 320), 256, 320)
    back = box.to_image(np.array([[10.0, 8.0 + 20.0, 110.0, 8.0 + 120.0]]), 320, 240)
    np.testing.assert_allclose(back, [[10.0, 20.0, 110.0, 120.0]])


def test_letterbox_to_image_clips_to_the_image() -> None:
    """Boxes reaching into the padding are clipped at the image border."""
    _, box = letterbox(_image(32, 64), 64, 64)
    back = box.to_image(np.array([[-5.0, 0.0, 70.0, 64.0]]), 64, 32)
    np.testing.assert_allclose(back, [[0.0, 0.0, 64.0, 32.0]])


def test_iou_matrix_of_identical_disjoint_and_half_overlapping_boxes() -> None:
    """IoU is 1 for equal boxes, 0 for disjoint ones and 1/3 for boxes sharing half their area."""
    a = np.array([[0.0, 0.0, 10.0, 10.0]])
    b = np.array([[0.0, 0.0, 10.0, 10.0], [20.0, 20.0, 30.0, 30.0], [5.0, 0.0, 15.0, 10.0]])
    np.testing.assert_allclose(iou_matrix(a, b), [[1.0, 0.0, 1.0 / 3.0]])


def test_nms_drops_weaker_overlapping_box_of_the_same_class() -> None:
    """Of two heavily overlapping boxes of one class only the stronger one is kept."""
    boxes = np.array([[0, 0, 10, 10], [1, 1, 11, 11], [50, 50, 60, 60]], dtype=np.float32)
    keep = nms(boxes, np.array([0.6, 0.9, 0.5]), np.array([0, 0, 0]), 0.45)
    assert keep.tolist() == [1, 2]


def test_nms_keeps_overlapping_boxes_of_different_classes() -> None:
    """Class-wise NMS never lets a box suppress a box of another class."""
    boxes = np.array([[0, 0, 10, 10], [1, 1, 11, 11]], dtype=np.float32)
    keep = nms(boxes, np.array([0.9, 0.6]), np.array([0, 1]), 0.45)
    assert keep.tolist() == [0, 1]


def test_nms_of_nothing_is_nothing() -> None:
    """No candidates give no kept indices."""
    assert nms(np.zeros((0, 4)), np.zeros(0), np.zeros(0, int), 0.5).tolist() == []


def test_decode_yolo_thresholds_and_converts_centre_boxes() -> None:
    """Candidates under the threshold go; kept ones come back as xyxy with their best class."""
    out = yolo_output([(20, 20, 10, 4, [0.1, 0.8]), (40, 40, 8, 8, [0.2, 0.1])], 2)
    boxes, scores, classes = decode_yolo(out, 2, 0.25, 0.45, 100)
    np.testing.assert_allclose(boxes, [[15, 18, 25, 22]])
    np.testing.assert_allclose(scores, [0.8])
    assert classes.tolist() == [1]


def test_decode_yolo_multi_label_reports_a_box_under_each_class_above_the_threshold() -> None:
    """An ambiguous box comes back once per class above the threshold, each with its own score."""
    out = yolo_output([(20, 20, 10, 4, [0.5, 0.4]), (40, 40, 8, 8, [0.2, 0.1])], 2)
    boxes, scores, classes = decode_yolo(out, 2, 0.15, 0.45, 100, multi_label=True)
    assert [(int(c), round(float(s), 2)) for c, s in zip(classes, scores, strict=True)] == [
        (0, 0.5), (1, 0.4), (0, 0.2)]
    np.testing.assert_allclose(boxes[:2], [[15, 18, 25, 22], [15, 18, 25, 22]])
    _, _, single = decode_yolo(out, 2, 0.15, 0.45, 100)
    assert single.tolist() == [0, 0]  # without it: each box once, under its best class


def test_parse_names_reads_ultralytics_dict_text() -> None:
    """The names metadata Ultralytics writes (a dict as text) gives names in id order."""
    assert parse_names("{1: 'cup', 0: 'person'}") == ["person", "cup"]


def test_onnx_detector_finds_boxes_in_image_pixels(tmp_path: Path) -> None:
    """A real ONNX model's output is decoded, NMS-filtered and mapped back to the image."""
    out = yolo_output(
        [
            (32, 32, 20, 10, [0.9, 0.0]),  # person in the middle
            (33, 32, 20, 10, [0.7, 0.0]),  # duplicate of it, suppressed
            (10, 30, 6, 6, [0.0, 0.6]),  # a cup on the left
            (50, 50, 6, 6, [0.1, 0.2]),  # too weak
        ],
        2,
    )
    model = constant_yolo_model(tmp_path / "m.onnx", out, names=NAMES)
    detector = YoloOnnxDetector(model)
    found = detector.detect(_image(32, 64))  # letterboxed into 64x64 at scale 1, pad_y 16
    assert [(d.label, round(d.score, 2)) for d in found] == [("person", 0.9), ("cup", 0.6)]
    np.testing.assert_allclose(found[0].box, (22, 11, 42, 21))
    np.testing.assert_allclose(found[1].box, (7, 11, 13, 17))
    assert isinstance(detector, Detector)
    assert detector.labels == ["person", "cup"]


def test_onnx_detector_takes_names_from_a_labels_file(tmp_path: Path) -> None:
    """Without names in the metadata, a labels file with one name a line names the classes."""
    model = constant_yolo_model(tmp_path / "m.onnx", yolo_output([(5, 5, 2, 2, [0.0, 0.9])], 2))
    labels = tmp_path / "labels.txt"
    labels.write_text("dog\ncat\n")
    found = YoloOnnxDetector(model, labels_file=labels).detect(_image(64, 64))
    assert [d.label for d in found] == ["cat"]


def test_onnx_detector_with_dynamic_input_uses_the_configured_size(tmp_path: Path) -> None:
    """A model with symbolic height and width runs at the input size the config gives."""
    model = constant_yolo_model(
        tmp_path / "m.onnx", yolo_output([(5, 5, 2, 2, [0.9])], 1), input_hw=("h", "w"), names="['a']"
    )
    detector = YoloOnnxDetector(model, input_size=(32, 48))
    assert (detector.input_height, detector.input_width) == (32, 48)


def test_missing_model_file_is_a_clear_error(tmp_path: Path) -> None:
    """A model path that does not exist names the provider, the path and the fix."""
    with pytest.raises(ModelConfigError, match=r"'yolo_onnx'.*does not exist.*models config"):
        YoloOnnxDetector(tmp_path / "nope.onnx")


def test_file_that_is_not_onnx_is_a_clear_error(tmp_path: Path) -> None:
    """A file onnxruntime cannot read is reported as not a loadable ONNX model."""
    bad = tmp_path / "bad.onnx"
    bad.write_bytes(b"not a model")
    with pytest.raises(ModelConfigError, match="not a loadable ONNX model"):
        YoloOnnxDetector(bad)


def test_wrong_output_shape_is_a_clear_error(tmp_path: Path) -> None:
    """An end-to-end export ([1, N, 6]) is refused with the expected layout and the fix."""
    model = constant_yolo_model(tmp_path / "m.onnx", np.zeros((1, 300, 6), np.float32), names=NAMES)
    with pytest.raises(ModelConfigError, match=r"\[1, 300, 6\].*expected one output \[1, 4 \+ classes, N\]"):
        YoloOnnxDetector(model)


def test_class_count_that_disagrees_with_labels_is_a_clear_error(tmp_path: Path) -> None:
    """Three class rows against two names is refused, pointing at the labels."""
    model = constant_yolo_model(tmp_path / "m.onnx", np.zeros((1, 7, 10), np.float32), names=NAMES)
    with pytest.raises(ModelConfigError, match=r"\[1, 6, N\] for its 2 class names"):
        YoloOnnxDetector(model)


def test_model_without_names_or_labels_file_is_a_clear_error(tmp_path: Path) -> None:
    """A model with no names metadata and no labels file asks for a labels file."""
    model = constant_yolo_model(tmp_path / "m.onnx", np.zeros((1, 6, 10), np.float32))
    with pytest.raises(ModelConfigError, match="labels_file"):
        YoloOnnxDetector(model)


@pytest.mark.parametrize(
    ("image", "found"),
    [
        (np.zeros((0, 10, 3), np.uint8), "empty"),
        (np.zeros((10, 10), np.uint8), "shape HxWx3"),
        (np.zeros((10, 10, 4), np.uint8), "shape HxWx3"),
        (np.zeros((10, 10, 3), np.float32), "dtype float32"),
        ([[1, 2, 3]], "list"),
    ],
)
def test_bad_images_are_clear_errors(image: object, found: str) -> None:
    """Empty, grey, RGBA, float or non-array images are refused with what was found."""
    with pytest.raises(ModelConfigError, match=found):
        check_image(image, "yolo_onnx")


def test_detect_refuses_a_bad_image_naming_the_provider(tmp_path: Path) -> None:
    """detect() checks the image before running the model and names the provider."""
    model = constant_yolo_model(tmp_path / "m.onnx", np.zeros((1, 6, 10), np.float32), names=NAMES)
    with pytest.raises(ModelConfigError, match="detector 'mine'.*empty"):
        YoloOnnxDetector(model, name="mine").detect(np.zeros((0, 0, 3), np.uint8))


def test_check_runs_the_model_and_describes_it(tmp_path: Path) -> None:
    """check() (used by `missiontree models`) runs a blank frame and names the model and classes."""
    model = constant_yolo_model(tmp_path / "m.onnx", np.zeros((1, 6, 10), np.float32), names=NAMES)
    assert YoloOnnxDetector(model).check() == (
        "YOLO-layout ONNX detector m.onnx (input 64x64, 2 classes: person, cup)"
    )


# -- a detector's answer is checked where it enters -------------------------------------------------

def test_non_finite_model_output_is_dropped_and_the_model_check_fails(tmp_path: Path) -> None:
    """A model emitting NaN/inf candidates: detect() keeps only the finite box; check() calls it unusable."""
    out = yolo_output(
        [
            (32, 32, 20, 10, [0.9, 0.0]),  # a good person box
            (float("nan"), 32, 20, 10, [0.95, 0.0]),  # a NaN centre, the best score
            (10, 30, float("inf"), 6, [0.0, 0.8]),  # an infinite width
            (40, 40, 6, 6, [float("nan"), 0.0]),  # a NaN score
        ],
        2,
    )
    detector = YoloOnnxDetector(constant_yolo_model(tmp_path / "nan.onnx", out, names=NAMES))
    found = detector.detect(_image(32, 64))
    assert [(d.label, round(d.score, 2)) for d in found] == [("person", 0.9)]
    assert all(np.isfinite(d.box).all() for d in found)
    with pytest.raises(ModelError, match="non-finite numbers"):
        detector.check()


def test_checked_detections_drops_clips_and_says_why() -> None:
    """Non-finite, inverted and outside boxes are dropped with a reason; one past the border is clipped."""
    dets = [
        Detection("person", 0.9, (10.0, 10.0, 50.0, 100.0)),
        Detection("person", 0.9, (300.0, 200.0, 400.0, 300.0)),  # reaches past the 320x240 border
        Detection("person", 0.9, (float("nan"), 0.0, 5.0, 5.0)),
        Detection("person", float("inf"), (0.0, 0.0, 5.0, 5.0)),
        Detection("person", 0.9, (90000.0, 90000.0, 90010.0, 90010.0)),
        Detection("person", 0.9, (50.0, 50.0, 10.0, 60.0)),  # inverted
        Detection("person", 1.7, (1.0, 1.0, 2.0, 2.0)),  # a score above 1 is clamped
        "not a detection",
    ]
    kept, dropped = checked_detections(dets, 320, 240, "fuzzy")
    assert [d.box for d in kept] == [(10.0, 10.0, 50.0, 100.0), (300.0, 200.0, 320.0, 240.0),
                                     (1.0, 1.0, 2.0, 2.0)]
    assert kept[2].score == 1.0
    assert len(dropped) == 5 and all(reason.startswith("fuzzy: ") for reason in dropped)
    assert checked_detections(None, 320, 240)[0] == []


def test_onnx_detector_keeps_each_boxs_score_for_every_class(tmp_path: Path) -> None:
    """A detection carries the model's score per class (its runner-up too), not only its best."""
    out = yolo_output([(32, 32, 20, 10, [0.7, 0.2]), (10, 30, 6, 6, [0.005, 0.6])], 2)
    detector = YoloOnnxDetector(constant_yolo_model(tmp_path / "m.onnx", out, names=NAMES))
    found = detector.detect(_image(32, 64))
    assert [d.attributes[CLASS_SCORES] for d in found] == [
        {"person": 0.7, "cup": 0.2},
        {"cup": 0.6},  # a share under CLASS_SCORE_FLOOR is noise: left out
    ]
    _, _, _, rows = decode_yolo_with_scores(out, 2, 0.25, 0.45, 100)
    np.testing.assert_allclose(rows, [[0.7, 0.2], [0.005, 0.6]], atol=1e-6)


def _flip_counts(tmp_path: Path, score: float, band: tuple[float, float] | None) -> dict[str, int]:
    model = constant_yolo_model(tmp_path / "m.onnx", yolo_output([(20, 20, 8, 8, [score, 0.0])], 2),
                                names=NAMES)
    detector = YoloOnnxDetector(model, test_time_flip=True, flip_band=band, score_threshold=0.1, recent=0)
    detector.detect(_image())
    return detector.passes


def test_mirror_pass_runs_when_a_candidate_scores_inside_the_band(tmp_path: Path) -> None:
    """A candidate at 0.5 lies in [0.3, 0.7): the frame is mirrored too."""
    assert _flip_counts(tmp_path, 0.5, (0.3, 0.7)) == {"single": 1, "mirror": 1}


def test_mirror_pass_is_skipped_when_every_candidate_is_outside_the_band(tmp_path: Path) -> None:
    """Candidates at 0.9 or 0.2 are settled by the single pass: no mirror pass."""
    assert _flip_counts(tmp_path, 0.9, (0.3, 0.7)) == {"single": 1, "mirror": 0}
    assert _flip_counts(tmp_path, 0.2, (0.3, 0.7)) == {"single": 1, "mirror": 0}


def test_without_a_band_every_frame_is_mirrored(tmp_path: Path) -> None:
    """flip_band None keeps the mirror pass on every frame."""
    assert _flip_counts(tmp_path, 0.9, None) == {"single": 1, "mirror": 1}


def test_a_band_in_the_wrong_order_is_refused(tmp_path: Path) -> None:
    """[0.7, 0.3] is no band: a clear configuration error."""
    model = constant_yolo_model(tmp_path / "m.onnx", yolo_output([(5, 5, 2, 2, [0.0, 0.9])], 2), names=NAMES)
    with pytest.raises(ModelConfigError, match="flip_band"):
        YoloOnnxDetector(model, test_time_flip=True, flip_band=(0.7, 0.3))


def test_a_caller_can_ask_for_or_skip_the_mirror_pass_on_one_frame(tmp_path: Path) -> None:
    """mirror=True mirrors a frame the band would skip; mirror=False skips one it would mirror."""
    output = yolo_output([(20, 20, 8, 8, [0.9, 0.0])], 2)
    model = constant_yolo_model(tmp_path / "m.onnx", output, names=NAMES)
    detector = YoloOnnxDetector(model, test_time_flip=True, flip_band=(0.3, 0.7), score_threshold=0.1)
    detector.detect(_image(), mirror=True)
    assert detector.passes == {"single": 1, "mirror": 1}
    single = detector.detect(_image(), mirror=False)  # not the remembered mirrored answer
    assert detector.passes == {"single": 1, "mirror": 1}  # the frame's single pass is not run again
    fresh = YoloOnnxDetector(model, test_time_flip=True, flip_band=(0.3, 0.7), score_threshold=0.1, recent=0)
    again = fresh.detect(_image(), mirror=False)
    assert [(d.label, d.box) for d in single] == [(d.label, d.box) for d in again]


def _band_detector(tmp_path: Path, scores: list[float]) -> YoloOnnxDetector:
    model = constant_yolo_model(tmp_path / "m.onnx", yolo_output([(20, 20, 8, 8, scores)], 2), names=NAMES)
    return YoloOnnxDetector(model, test_time_flip=True, flip_band=(0.3, 0.7), score_threshold=0.1)


def test_band_labels_skip_the_mirror_pass_for_a_band_candidate_of_another_class(tmp_path: Path) -> None:
    """A cup scoring 0.5 is in the band, but a caller deciding on people gets the single pass."""
    detector = _band_detector(tmp_path, [0.0, 0.5])
    detector.detect(_image(), band_labels=("person",))
    assert detector.passes == {"single": 1, "mirror": 0}
    detector.detect(_image())  # every class: the cup pays for the mirror pass (the single pass remembered)
    assert detector.passes == {"single": 1, "mirror": 1}


def test_band_labels_keep_the_mirror_pass_for_a_band_candidate_of_their_class(tmp_path: Path) -> None:
    """A person scoring 0.5 is in the band: a caller deciding on people still gets the mirror pass."""
    detector = _band_detector(tmp_path, [0.5, 0.0])
    detector.detect(_image(), band_labels=("person",))
    assert detector.passes == {"single": 1, "mirror": 1}


def test_band_labels_ask_nothing_of_an_explicit_mirror_choice(tmp_path: Path) -> None:
    """mirror=True still mirrors, whatever the labels: the band is only consulted when mirror is None."""
    detector = _band_detector(tmp_path, [0.0, 0.9])
    detector.detect(_image(), mirror=True, band_labels=("person",))
    assert detector.passes == {"single": 1, "mirror": 1}


def test_decoding_keeps_only_candidates_above_the_threshold_in_either_mode() -> None:
    """Low candidates are dropped before the finite check; kept ones are as before, multi-label too."""
    rows_in = [(10, 10, 4, 4, [0.9, 0.2]), (30, 30, 4, 4, [0.1, 0.05]), (50, 50, 4, 4, [0.4, 0.6])]
    out = yolo_output(rows_in, 2)
    boxes, scores, ids, rows = decode_yolo_with_scores(out, 2, 0.3, 0.45, 10)
    assert ids.tolist() == [0, 1] and np.allclose(scores, [0.9, 0.6]) and rows.shape == (2, 2)
    _, ml_scores, ml_ids, _ = decode_yolo_with_scores(out, 2, 0.3, 0.45, 10, multi_label=True)
    found = sorted(zip(ml_ids.tolist(), [round(float(v), 2) for v in ml_scores], strict=True))
    assert found == [(0, 0.4), (0, 0.9), (1, 0.6)]


@pytest.mark.parametrize("shape", [(32, 64, 3), (64, 64, 3), (31, 63, 3), (200, 90, 3), (1, 1, 3)])
def test_the_input_tensor_is_the_letterboxed_image_divided_by_255(tmp_path: Path,
                                                                  shape: tuple[int, ...]) -> None:
    """The input tensor is exactly letterbox, then float conversion, then division by 255."""
    output = yolo_output([(20, 20, 8, 8, [0.9, 0.0])], 2)
    model = constant_yolo_model(tmp_path / "m.onnx", output, names=NAMES)
    detector = YoloOnnxDetector(model)
    image = np.random.default_rng(3).integers(0, 256, shape, dtype=np.uint8)
    padded, box = letterbox(image, detector.input_height, detector.input_width)
    expected = padded.transpose(2, 0, 1)[None].astype(np.float32) / np.float32(255.0)
    tensor, found = detector.preprocess(image)
    assert found == box and tensor.flags["C_CONTIGUOUS"]
    np.testing.assert_array_equal(tensor, expected)


def test_nms_over_the_whole_overlap_matrix_keeps_what_the_box_by_box_pass_keeps(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Random boxes with tied scores and duplicates: the matrix pass and the box-by-box pass agree."""
    from missiontree.perception import yolo_layout

    rng = np.random.default_rng(3)
    for trial in range(200):
        n = int(rng.integers(1, 60))
        centres, sizes = rng.uniform(0, 100, (n, 2)), rng.uniform(2, 40, (n, 2))
        boxes = np.round(np.concatenate([centres - sizes / 2, centres + sizes / 2], axis=1) / 5) * 5
        scores = np.round(rng.uniform(0, 1, n), 1).astype(np.float32)
        ids = rng.integers(0, 3, n)
        matrix = nms(boxes, scores, ids, 0.45)
        monkeypatch.setattr(yolo_layout, "_NMS_MATRIX_MAX", 0)
        box_by_box = nms(boxes, scores, ids, 0.45)
        monkeypatch.undo()
        assert matrix.tolist() == box_by_box.tolist(), trial
