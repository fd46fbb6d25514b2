"""tools/detector/train.py: the training command trains, exports a loadable model, and repeats from its seed.

The runs train on a handful of tiny images for a step or two (needs the train extra's CPU torch).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

torch = pytest.importorskip("torch", reason="the train extra (CPU torch) is not installed")
pytest.importorskip("onnx", reason="the train extra (onnx) is not installed")
from missiontree.perception.detectors import YoloOnnxDetector  # noqa: E402
from tools.detector import train  # noqa: E402
from tools.detector.data import CLASSES  # noqa: E402
from tools.detector.network import STRIDES, TinyDetector, flatten_maps, make_grid  # noqa: E402

#: Four views at a 64x96 input through a narrow network: two steps of two images.
TINY = ["--images", "4", "--batch", "2", "--epochs", "1", "--input-hw", "64", "96",
        "--widths", "8", "16", "24", "32", "--threads", "1"]


def _run(tmp_path: Path, name: str, *extra: str, capsys: pytest.CaptureFixture[str]) -> dict[str, object]:
    train.main([*TINY, *extra, "--out", str(tmp_path / f"{name}.onnx")])
    return json.loads(capsys.readouterr().out.strip().splitlines()[-1])


def test_a_tiny_run_exports_a_model_the_runtime_detector_loads(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    summary = _run(tmp_path, "tiny", "--seed", "3", capsys=capsys)
    assert summary["images"] == 4 and summary["seed"] == 3
    assert (tmp_path / "tiny.pt").is_file()  # the next stage's --init
    detector = YoloOnnxDetector(tmp_path / "tiny.onnx", score_threshold=0.0, threads=1)
    assert detector.labels == CLASSES  # the class names travel in the metadata
    assert (detector.input_height, detector.input_width) == (64, 96)
    found = detector.detect(np.full((240, 320, 3), 128, np.uint8))
    assert found and all(d.label in CLASSES for d in found)


def test_the_same_seed_trains_the_same_weights_and_another_seed_does_not(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    _run(tmp_path, "a", "--seed", "5", capsys=capsys)
    _run(tmp_path, "b", "--seed", "5", capsys=capsys)
    _run(tmp_path, "c", "--seed", "6", capsys=capsys)
    a, b, c = (torch.load(tmp_path / f"{n}.pt") for n in "abc")
    assert all(torch.equal(a[k], b[k]) for k in a)
    assert not all(torch.equal(a[k], c[k]) for k in a)


def test_a_stage_starts_from_the_previous_stages_weights_and_refiners_can_train_alone(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    _run(tmp_path, "first", "--seed", "1", capsys=capsys)
    first = torch.load(tmp_path / "first.pt")
    _run(tmp_path, "second", "--seed", "2", "--init", str(tmp_path / "first.pt"), "--refine",
         "--train", "refiners", capsys=capsys)
    second = torch.load(tmp_path / "second.pt")
    assert any(k.startswith("refiners.") for k in second)
    # only the refiners were trained: every other weight (and batch-norm statistic) is the first stage's
    assert all(torch.equal(first[k], second[k]) for k in first)
    assert not all(torch.equal(v, torch.zeros_like(v)) for k, v in second.items() if k.endswith("2.weight")
                   and k.startswith("refiners."))


def test_training_worlds_may_not_reach_the_benchmarks(tmp_path: Path) -> None:
    with pytest.raises(SystemExit, match="lower --first-world"):
        train.main([*TINY, "--first-world", "10000", "--out", str(tmp_path / "never.onnx")])
    assert not list(tmp_path.iterdir())  # refused before rendering or writing anything


def test_inside_assignment_keeps_a_narrow_objects_cells_within_its_box() -> None:
    centres, strides = make_grid(64, 96)
    person = np.array([[0, 40, 8, 46, 56]], np.float32)  # 6 px wide, 48 px tall
    near, _, _, _ = train.assign([person], centres, strides, inside=False)
    inside, _, cls, boxes = train.assign([person], centres, strides, inside=True)
    assert inside[0].sum() >= 1 and inside[0].sum() < near[0].sum()
    xs, ys = centres[inside[0], 0], centres[inside[0], 1]
    assert bool(((xs >= 40) & (xs <= 46) & (ys >= 8) & (ys <= 56)).all())
    assert bool((cls[0][inside[0]] == 0).all())
    assert torch.equal(boxes[0][inside[0]][0], torch.tensor([40.0, 8.0, 46.0, 56.0]))


def test_an_object_too_small_to_demand_makes_its_cells_ignored_not_negative() -> None:
    centres, strides = make_grid(64, 96)
    positive, ignored, _, _ = train.assign([np.array([[-1, 10, 10, 14, 14]], np.float32)], centres, strides)
    assert not positive.any() and ignored[0].any()
    assert set(strides[ignored[0]].tolist()) <= set(float(s) for s in STRIDES)


def test_a_few_steps_on_one_batch_lower_its_loss() -> None:
    """The loss and its gradients point the right way: a network overfits two images in a few steps."""
    torch.manual_seed(0)
    model = TinyDetector(len(CLASSES), widths=(8, 16, 24, 32))
    centres, strides = make_grid(64, 96)
    images = torch.rand(2, 3, 64, 96)
    targets = [np.array([[1, 20, 10, 44, 50]], np.float32), np.array([[0, 60, 4, 72, 60]], np.float32)]
    optimiser = torch.optim.AdamW(model.parameters(), lr=1e-2)
    losses = []
    for _ in range(15):
        raw = flatten_maps(model(images))
        loss, parts = train.detection_loss(raw, targets, centres, strides, inside=True)
        optimiser.zero_grad()
        loss.backward()
        optimiser.step()
        losses.append(float(loss.detach()))
        assert parts["box"] > 0
    assert losses[-1] < 0.7 * losses[0]
