"""Average the weights of several fine-tuned simulator detectors into one model (a "model soup").

Runs of scripts/train_detector.py that start from the same weights and differ in seed, worlds,
learning rate or loss end near one another; the mean of their weights (Wortsman et al., 2022,
"Model soups") usually scores better than each of them and costs nothing at inference: it is one
network of the same size. Batch-norm statistics are averaged with the weights, as the weight
average of ``--ema`` does.

Needs the ``train`` extra (``.venv/bin/pip install -e '.[train]'``)::

    .venv/bin/python scripts/soup_detector.py --out /tmp/sim_detector/soup.onnx a.pt b.pt c.pt

The ``.pt`` files are the ones train_detector.py writes beside each ``--out``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

try:
    import torch
except ImportError:  # pragma: no cover - depends on the extra
    sys.exit("the soup needs the train extra: .venv/bin/pip install -e '.[train]' (pins the CPU torch)")

sys.path.insert(0, str(Path(__file__).resolve().parent))
from train_detector import CLASSES, TinyDetector, export  # noqa: E402


def average_states(states: list[dict[str, torch.Tensor]]) -> dict[str, torch.Tensor]:
    """The element-wise mean of state dicts of one network; integer counters take the largest.

    Raises:
        ValueError: The state dicts are not of the same network (keys or shapes differ).
    """
    if not states:
        raise ValueError("no weights to average")
    keys = list(states[0])
    for k, state in enumerate(states[1:], start=2):
        if list(state) != keys:
            raise ValueError(f"weights {k} have other tensors than weights 1 (another network?)")
        for key in keys:
            if state[key].shape != states[0][key].shape:
                raise ValueError(f"weights {k}: {key} is {list(state[key].shape)}, weights 1 have "
                                 f"{list(states[0][key].shape)} (other --widths?)")
    soup = {}
    for key in keys:
        stacked = torch.stack([s[key] for s in states])
        soup[key] = stacked.float().mean(0) if stacked.is_floating_point() else stacked.max(0).values
    return soup


def network_of(state: dict[str, torch.Tensor]) -> TinyDetector:
    """A :class:`TinyDetector` shaped like ``state`` (its widths and refiners), holding it."""
    widths = tuple(int(state[k].shape[0]) for k in ("stem.0.0.weight", "down3.0.0.weight", "down4.0.0.weight",
                                                    "down5.0.0.weight"))
    model = TinyDetector(len(CLASSES), widths=widths, refine=any(k.startswith("refiners.") for k in state))
    model.load_state_dict(state)
    return model


def main(argv: list[str] | None = None) -> None:
    """Average the given weights and export the soup."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("weights", nargs="+", help=".pt files written by scripts/train_detector.py")
    parser.add_argument("--out", required=True, help="the .onnx to write (its .pt is written beside it)")
    parser.add_argument("--input-hw", type=int, nargs=2, default=[256, 320], metavar=("H", "W"))
    args = parser.parse_args(argv)
    states = [torch.load(path) for path in args.weights]
    try:
        soup = average_states(states)
    except ValueError as exc:
        sys.exit(f"soup_detector: {exc}")
    model = network_of(soup)
    out = Path(args.out)
    torch.save(model.state_dict(), out.with_suffix(".pt"))
    names = " ".join(Path(p).name for p in args.weights)
    export(model, out, (args.input_hw[0], args.input_hw[1]), f"soup (mean of the weights) of {names}")


if __name__ == "__main__":
    main()
