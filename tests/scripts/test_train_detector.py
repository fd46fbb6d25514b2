"""scripts/train_detector.py: widening a trained network keeps what it computes (needs the train extra)."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

torch = pytest.importorskip("torch", reason="the train extra (CPU torch) is not installed")
sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "scripts"))
import train_detector  # noqa: E402


def _trained_like(widths: tuple[int, ...]) -> train_detector.TinyDetector:
    """A network whose batch norms carry non-trivial statistics, as a trained one's do."""
    torch.manual_seed(3)
    model = train_detector.TinyDetector(5, widths=widths)
    with torch.no_grad():
        for module in model.modules():
            if isinstance(module, torch.nn.BatchNorm2d):
                module.running_mean.uniform_(-0.5, 0.5)
                module.running_var.uniform_(0.5, 2.0)
                module.weight.uniform_(0.5, 1.5)
                module.bias.uniform_(-0.2, 0.2)
    return model.eval()


def test_widening_without_noise_computes_the_same_outputs() -> None:
    narrow = _trained_like((8, 16, 24, 32))
    wide = train_detector.TinyDetector(5, widths=(12, 24, 40, 48))
    train_detector.widen(narrow, wide, seed=0, noise=0.0)
    x = torch.rand(2, 3, 64, 96)
    with torch.no_grad():
        before = train_detector.flatten_maps(narrow(x))
        after = train_detector.flatten_maps(wide.eval()(x))
    assert after.shape == before.shape
    assert torch.allclose(before, after, atol=1e-4)
    assert sum(p.numel() for p in wide.parameters()) > sum(p.numel() for p in narrow.parameters())


def test_the_noise_makes_copied_channels_differ() -> None:
    narrow = _trained_like((8, 16, 24, 32))
    wide = train_detector.TinyDetector(5, widths=(16, 16, 24, 32))
    train_detector.widen(narrow, wide, seed=0, noise=0.05)
    stem = wide.stem[0][0].weight
    copies = [c for c in range(8, 16) if not torch.equal(stem[c], stem[c % 8])]
    assert copies  # no new channel is an exact copy, so training can pull them apart
    assert torch.equal(stem[:8], narrow.stem[0][0].weight)  # the originals are untouched


def test_load_init_widens_a_narrower_checkpoint_and_loads_a_matching_one(tmp_path: Path) -> None:
    narrow = _trained_like((8, 16, 24, 32))
    path = tmp_path / "narrow.pt"
    torch.save(narrow.state_dict(), path)
    same = train_detector.TinyDetector(5, widths=(8, 16, 24, 32))
    train_detector.load_init(same, str(path), seed=0)
    assert all(torch.equal(a, b) for a, b in zip(same.state_dict().values(), narrow.state_dict().values(),
                                                 strict=True))
    wide = train_detector.TinyDetector(5, widths=(8, 32, 24, 32))
    train_detector.load_init(wide, str(path), seed=0)
    assert wide.down3[0][0].weight.shape[0] == 32


def test_a_checkpoint_with_refiners_widens_with_them(tmp_path: Path) -> None:
    torch.manual_seed(5)
    narrow = train_detector.TinyDetector(5, widths=(8, 16, 24, 32), refine=True)
    narrow.load_state_dict(_trained_like((8, 16, 24, 32)).state_dict(), strict=False)
    for refiner in narrow.refiners:  # trained refiners correct the scores
        torch.nn.init.normal_(refiner.body[-1].weight, std=0.1)
    narrow.eval()
    wide = train_detector.TinyDetector(5, widths=(8, 16, 40, 48), refine=True)
    train_detector.widen(narrow, wide, seed=0, noise=0.0)
    x = torch.rand(2, 3, 64, 96)
    with torch.no_grad():
        before = train_detector.flatten_maps(narrow(x))
        after = train_detector.flatten_maps(wide.eval()(x))
    assert torch.allclose(before, after, atol=1e-4)
    path = tmp_path / "refined.pt"
    torch.save(narrow.state_dict(), path)
    loaded = train_detector.TinyDetector(5, widths=(8, 16, 40, 48), refine=True)
    train_detector.load_init(loaded, str(path), seed=0)  # widened with a little noise
    assert loaded.refiners[2].body[0].weight.shape[1] == 48 + train_detector.Refiner.GEOMETRY + 5
    with torch.no_grad():
        assert torch.allclose(before, train_detector.flatten_maps(loaded.eval()(x)), atol=0.5)


def test_widening_to_a_narrower_network_is_refused() -> None:
    with pytest.raises(ValueError, match="cannot widen"):
        narrower = train_detector.TinyDetector(5, (8, 8, 24, 32))
        train_detector.widen(_trained_like((8, 16, 24, 32)), narrower, 0)


def test_refiners_start_with_no_correction_and_then_depend_on_the_box_place() -> None:
    plain = _trained_like((8, 16, 24, 32))
    refined = train_detector.TinyDetector(5, widths=(8, 16, 24, 32), refine=True)
    train_detector._add_refiners(refined, plain)
    x = torch.rand(2, 3, 64, 96)
    with torch.no_grad():
        before = train_detector.flatten_maps(plain(x))
        after = train_detector.flatten_maps(refined.eval()(x))
        assert torch.equal(before, after)  # a fresh refiner's last layer is zero
        for refiner in refined.refiners:
            torch.nn.init.normal_(refiner.body[-1].weight, std=0.1)
        changed = train_detector.flatten_maps(refined(x))
    assert torch.equal(changed[..., :4], before[..., :4])  # boxes are never touched
    assert not torch.allclose(changed[..., 4:], before[..., 4:])


def test_an_exported_model_loads_back_with_its_batch_norms_recovered(tmp_path: Path) -> None:
    pytest.importorskip("onnx", reason="the train extra (onnx) is not installed")
    model = _trained_like((8, 16, 24, 32))
    out = tmp_path / "model.onnx"
    train_detector.export(model, out, (64, 96), "test")  # folds each batch norm into its convolution
    loaded = train_detector.TinyDetector(5, widths=(8, 16, 24, 32))
    calibration = torch.rand(16, 3, 64, 96)
    train_detector.load_init(loaded, str(out), seed=0, calibration=calibration)
    with torch.no_grad():
        expected = train_detector.flatten_maps(model.eval()(calibration))
        assert torch.allclose(train_detector.flatten_maps(loaded.eval()(calibration)), expected, atol=1e-4)
        # In training mode the batch norms normalise with the batch's own statistics; on the
        # calibration batch those are the recovered ones, so the output is the same too.
        assert torch.allclose(train_detector.flatten_maps(loaded.train()(calibration)), expected, atol=1e-3)
    with pytest.raises(ValueError, match="other --widths"):
        other = train_detector.TinyDetector(5, widths=(8, 16, 24, 40))
        train_detector.load_init(other, str(out), 0, calibration)


def test_the_weight_average_starts_at_the_model_and_follows_it_by_its_decay() -> None:
    model = _trained_like((8, 16, 24, 32)).train()
    average = train_detector.weight_average(model, decay=0.75)
    average.update_parameters(model)  # the first update copies the model
    start = {k: v.clone() for k, v in average.module.state_dict().items()}
    norm = next(m for m in model.modules() if isinstance(m, torch.nn.BatchNorm2d))
    with torch.no_grad():
        model.stem[0][0].weight.add_(1.0)
        norm.running_mean.add_(2.0)  # batch-norm statistics are averaged too
    average.update_parameters(model)
    state = average.module.state_dict()
    assert torch.allclose(state["stem.0.0.weight"], start["stem.0.0.weight"] + 0.25)
    assert torch.allclose(state["stem.0.1.running_mean"], start["stem.0.1.running_mean"] + 0.5)
    assert torch.equal(state["down5.0.0.weight"], start["down5.0.0.weight"])  # unchanged weights stay


def test_cell_coverage_is_the_share_of_each_cell_an_object_shows_after_the_letterbox() -> None:
    """An object on camera rows 0-11, columns 16-31 shows 8 rows lower in the input: input rows 8-19."""
    instances = np.zeros((240, 320), np.int32)
    instances[0:12, 16:32] = 7
    cover = train_detector.cell_coverage(instances, np.array([7, 0]), (256, 320))
    level8 = cover[0, : 32 * 40].reshape(32, 40)
    assert level8[1, 2] == 255 and level8[1, 3] == 255  # input rows 8-15: wholly the object
    assert level8[0, 2] == 0 and level8[2, 2] == 128  # the grey band; half of rows 16-23
    assert level8[1, 4] == 0 and level8[1, 1] == 0
    assert not cover[1].any()  # row 0: no object (an ignored label)
    half = train_detector.cell_coverage(instances, np.array([7]), (128, 160))  # half scale, 4 grey rows
    assert half[0, : 16 * 20].reshape(16, 20)[0, 1] == 128  # input rows 4-9, columns 8-15: half the cell


def test_mirrored_cells_flip_coverage_as_the_image_is_flipped() -> None:
    instances = np.zeros((240, 320), np.int32)
    instances[40:120, 10:90] = 3
    cover = train_detector.cell_coverage(instances, np.array([3]), (256, 320))
    flipped = train_detector.cell_coverage(instances[:, ::-1], np.array([3]), (256, 320))
    assert np.array_equal(cover[:, train_detector.mirrored_cells((256, 320))], flipped)


def test_visible_assignment_teaches_a_hidden_object_only_where_it_shows() -> None:
    """A chair whose box centre lies behind a table claims its visible cells, not the table's."""
    hw = (256, 320)
    centres, strides = train_detector.make_grid(*hw)
    instances = np.zeros((240, 320), np.int32)
    instances[92:140, 80:128] = 1   # the chair: 48x48 pixels of camera (a stride-16 object)
    instances[110:180, 60:200] = 2  # the table in front hides the chair's lower part and centre
    labels = np.array([[1, 80, 100, 128, 148], [3, 60, 118, 200, 188]], np.float32)  # input pixels
    cover = train_detector.cell_coverage(instances, np.array([1, 2]), hw)
    plain, _, cls_plain, _ = train_detector.assign([labels], centres, strides, inside=True)
    seen, _, cls_seen, _ = train_detector.assign([labels], centres, strides, inside=True, coverage=[cover])
    chair_plain = plain[0] & (cls_plain[0] == 1)
    chair_seen = seen[0] & (cls_seen[0] == 1)
    assert chair_seen.any()
    assert bool((torch.from_numpy(cover[0].astype(np.float32)) >= 0.25 * 255)[chair_seen].all())
    assert bool((torch.from_numpy(cover[0].astype(np.float32)) < 0.25 * 255)[chair_plain].any())
    assert chair_seen.sum() < chair_plain.sum()


def test_visible_assignment_leaves_objects_in_full_view_as_they_were() -> None:
    hw = (256, 320)
    centres, strides = train_detector.make_grid(*hw)
    instances = np.zeros((240, 320), np.int32)
    instances[50:130, 30:90] = 4
    instances[150:200, 200:300] = 5
    labels = np.array([[2, 30, 58, 90, 138], [0, 200, 158, 300, 208]], np.float32)
    cover = train_detector.cell_coverage(instances, np.array([4, 5]), hw)
    plain = train_detector.assign([labels], centres, strides, inside=True)
    seen = train_detector.assign([labels], centres, strides, inside=True, coverage=[cover])
    assert all(torch.equal(a, b) for a, b in zip(plain, seen, strict=True))
