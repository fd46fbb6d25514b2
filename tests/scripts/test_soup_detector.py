"""scripts/soup_detector.py: the mean of several trained networks' weights (needs the train extra)."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

torch = pytest.importorskip("torch", reason="the train extra (CPU torch) is not installed")
sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "scripts"))
import soup_detector  # noqa: E402
import train_detector  # noqa: E402


def _network(seed: int, widths: tuple[int, ...] = (8, 16, 24, 32)) -> train_detector.TinyDetector:
    torch.manual_seed(seed)
    model = train_detector.TinyDetector(len(train_detector.CLASSES), widths=widths, refine=True)
    with torch.no_grad():
        for p in model.parameters():
            p.add_(torch.randn_like(p) * 0.1)
        for module in model.modules():
            if isinstance(module, torch.nn.BatchNorm2d):
                module.running_mean.uniform_(-0.5, 0.5)
                module.num_batches_tracked.fill_(seed)
    return model


def test_the_soup_is_the_mean_of_the_weights_and_statistics() -> None:
    a, b = _network(1).state_dict(), _network(2).state_dict()
    soup = soup_detector.average_states([a, b])
    key = "down4.1.body.0.1.running_mean"
    assert torch.allclose(soup[key], (a[key] + b[key]) / 2)
    assert torch.allclose(soup["heads.0.2.weight"], (a["heads.0.2.weight"] + b["heads.0.2.weight"]) / 2)
    assert int(soup["stem.0.1.num_batches_tracked"]) == 2  # counters are not averaged


def test_a_soup_of_one_network_computes_what_it_computes() -> None:
    model = _network(3).eval()
    again = soup_detector.network_of(soup_detector.average_states([model.state_dict()] * 3)).eval()
    x = torch.rand(1, 3, 64, 96)
    with torch.no_grad():
        assert torch.allclose(train_detector.flatten_maps(again(x)), train_detector.flatten_maps(model(x)),
                              atol=1e-5)


def test_networks_of_other_widths_do_not_mix() -> None:
    with pytest.raises(ValueError, match="other --widths"):
        soup_detector.average_states([_network(1).state_dict(), _network(1, (8, 16, 24, 40)).state_dict()])
