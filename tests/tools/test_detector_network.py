"""tools/detector/network.py: widening and loading keep what a network computes (needs the train extra)."""

from __future__ import annotations

from pathlib import Path

import pytest

torch = pytest.importorskip("torch", reason="the train extra (CPU torch) is not installed")
from tools.detector import network as network  # noqa: E402


def _trained_like(widths: tuple[int, ...]) -> network.TinyDetector:
    """A network whose batch norms carry non-trivial statistics, as a trained one's do."""
    torch.manual_seed(3)
    model = network.TinyDetector(5, widths=widths)
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
    wide = network.TinyDetector(5, widths=(12, 24, 40, 48))
    network.widen(narrow, wide, seed=0, noise=0.0)
    x = torch.rand(2, 3, 64, 96)
    with torch.no_grad():
        before = network.flatten_maps(narrow(x))
        after = network.flatten_maps(wide.eval()(x))
    assert after.shape == before.shape
    assert torch.allclose(before, after, atol=1e-4)
    assert sum(p.numel() for p in wide.parameters()) > sum(p.numel() for p in narrow.parameters())


def test_the_noise_makes_copied_channels_differ() -> None:
    narrow = _trained_like((8, 16, 24, 32))
    wide = network.TinyDetector(5, widths=(16, 16, 24, 32))
    network.widen(narrow, wide, seed=0, noise=0.05)
    stem = wide.stem[0][0].weight
    copies = [c for c in range(8, 16) if not torch.equal(stem[c], stem[c % 8])]
    assert copies  # no new channel is an exact copy, so training can pull them apart
    assert torch.equal(stem[:8], narrow.stem[0][0].weight)  # the originals are untouched


def test_load_init_widens_a_narrower_checkpoint_and_loads_a_matching_one(tmp_path: Path) -> None:
    narrow = _trained_like((8, 16, 24, 32))
    path = tmp_path / "narrow.pt"
    torch.save(narrow.state_dict(), path)
    same = network.TinyDetector(5, widths=(8, 16, 24, 32))
    network.load_init(same, str(path), seed=0)
    assert all(torch.equal(a, b) for a, b in zip(same.state_dict().values(), narrow.state_dict().values(),
                                                 strict=True))
    wide = network.TinyDetector(5, widths=(8, 32, 24, 32))
    network.load_init(wide, str(path), seed=0)
    assert wide.down3[0][0].weight.shape[0] == 32


def test_a_checkpoint_with_refiners_widens_with_them(tmp_path: Path) -> None:
    torch.manual_seed(5)
    narrow = network.TinyDetector(5, widths=(8, 16, 24, 32), refine=True)
    narrow.load_state_dict(_trained_like((8, 16, 24, 32)).state_dict(), strict=False)
    for refiner in narrow.refiners:  # trained refiners correct the scores
        torch.nn.init.normal_(refiner.body[-1].weight, std=0.1)
    narrow.eval()
    wide = network.TinyDetector(5, widths=(8, 16, 40, 48), refine=True)
    network.widen(narrow, wide, seed=0, noise=0.0)
    x = torch.rand(2, 3, 64, 96)
    with torch.no_grad():
        before = network.flatten_maps(narrow(x))
        after = network.flatten_maps(wide.eval()(x))
    assert torch.allclose(before, after, atol=1e-4)
    path = tmp_path / "refined.pt"
    torch.save(narrow.state_dict(), path)
    loaded = network.TinyDetector(5, widths=(8, 16, 40, 48), refine=True)
    network.load_init(loaded, str(path), seed=0)  # widened with a little noise
    assert loaded.refiners[2].body[0].weight.shape[1] == 48 + network.Refiner.GEOMETRY + 5
    with torch.no_grad():
        assert torch.allclose(before, network.flatten_maps(loaded.eval()(x)), atol=0.5)


def test_widening_to_a_narrower_network_is_refused() -> None:
    with pytest.raises(ValueError, match="cannot widen"):
        narrower = network.TinyDetector(5, (8, 8, 24, 32))
        network.widen(_trained_like((8, 16, 24, 32)), narrower, 0)


def test_refiners_start_with_no_correction_and_then_depend_on_the_box_place() -> None:
    plain = _trained_like((8, 16, 24, 32))
    refined = network.TinyDetector(5, widths=(8, 16, 24, 32), refine=True)
    network._add_refiners(refined, plain)
    x = torch.rand(2, 3, 64, 96)
    with torch.no_grad():
        before = network.flatten_maps(plain(x))
        after = network.flatten_maps(refined.eval()(x))
        assert torch.equal(before, after)  # a fresh refiner's last layer is zero
        for refiner in refined.refiners:
            torch.nn.init.normal_(refiner.body[-1].weight, std=0.1)
        changed = network.flatten_maps(refined(x))
    assert torch.equal(changed[..., :4], before[..., :4])  # boxes are never touched
    assert not torch.allclose(changed[..., 4:], before[..., 4:])


def test_an_exported_model_loads_back_with_its_batch_norms_recovered(tmp_path: Path) -> None:
    pytest.importorskip("onnx", reason="the train extra (onnx) is not installed")
    model = _trained_like((8, 16, 24, 32))
    out = tmp_path / "model.onnx"
    network.export(model, out, (64, 96), "test")  # folds each batch norm into its convolution
    loaded = network.TinyDetector(5, widths=(8, 16, 24, 32))
    calibration = torch.rand(16, 3, 64, 96)
    network.load_init(loaded, str(out), seed=0, calibration=calibration)
    with torch.no_grad():
        expected = network.flatten_maps(model.eval()(calibration))
        assert torch.allclose(network.flatten_maps(loaded.eval()(calibration)), expected, atol=1e-4)
        # In training mode the batch norms normalise with the batch's own statistics; on the
        # calibration batch those are the recovered ones, so the output is the same too.
        assert torch.allclose(network.flatten_maps(loaded.train()(calibration)), expected, atol=1e-3)
    with pytest.raises(ValueError, match="other --widths"):
        other = network.TinyDetector(5, widths=(8, 16, 24, 40))
        network.load_init(other, str(out), 0, calibration)
