"""Train the shipped simulator detector: render labelled views, train on CPU, export ONNX.

Renders labelled views with the simulator's camera (:mod:`tools.detector.data`), trains the small
anchor-free detector of :mod:`tools.detector.network` with CPU PyTorch, and writes the ONNX model
(YOLOv8/YOLO11 layout) and, beside it, the ``.pt`` of its weights, from which a next stage starts
(``--init``). Run from the repository's root, with the ``train`` extra installed
(``.venv/bin/pip install -e '.[train]'``, which pins the CPU torch)::

    .venv/bin/python -m tools.detector.train --seed 7 --out /tmp/sim_detector/1.onnx

Reproducible from ``--seed``: the same seed renders the same images and initialises and shuffles
the same way (torch's CPU kernels are deterministic on one machine with fixed threads). The
shipped model's stages are listed in src/missiontree/data/models/README.md.

Each object is assigned to the cells around its centre on the level whose stride suits its size
(``--assign inside``: only cells inside its box); classification is binary cross-entropy with the
IoU of the cell's predicted box as its target (at least 0.2; 0 elsewhere, nothing on the cells of
objects too small to demand), so that scores rank boxes by how well they fit (``--cls-target
one``: target 1); boxes are trained with GIoU.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

try:
    import torch
    from torch.nn import functional as F  # noqa: N812 (the conventional name)
except ImportError:  # pragma: no cover - depends on the extra
    sys.exit("training needs the train extra: .venv/bin/pip install -e '.[train]' (pins the CPU torch)")

from missiontree.perception.detectors import letterbox
from tools.detector.data import CLASSES, EVAL_FIRST_WORLD, MIN_PIXELS, View, dataset_views
from tools.detector.network import (
    STRIDES,
    TinyDetector,
    decode_boxes,
    export,
    flatten_maps,
    load_init,
    make_grid,
)

#: Default input size of the network (height, width): the 320x240 camera image letterboxed at half
#: scale (160x120 plus 4 grey rows above and below). Half scale quarters the cost of training on a
#: 2-core CPU; objects smaller than MIN_PIXELS at full scale are not demanded. ``--input-hw 256
#: 320`` trains at full scale (8 grey rows above and below), which small and narrow objects need
#: (the shipped model's later stages).
INPUT_HW = (128, 160)
#: Views rendered of each generated world.
VIEWS_PER_WORLD = 25


# -- assignment and loss -------------------------------------------------------------------------


def box_xyxy(b: torch.Tensor) -> torch.Tensor:
    """cx, cy, w, h → x1, y1, x2, y2."""
    return torch.cat([b[..., :2] - b[..., 2:] / 2, b[..., :2] + b[..., 2:] / 2], dim=-1)


def giou(a: torch.Tensor, b: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """IoU and generalised IoU of matching xyxy boxes."""
    lt, rb = torch.max(a[:, :2], b[:, :2]), torch.min(a[:, 2:], b[:, 2:])
    inter = (rb - lt).clamp(min=0).prod(1)
    area_a, area_b = (a[:, 2:] - a[:, :2]).prod(1), (b[:, 2:] - b[:, :2]).prod(1)
    union = area_a + area_b - inter + 1e-7
    iou = inter / union
    hull = (torch.max(a[:, 2:], b[:, 2:]) - torch.min(a[:, :2], b[:, :2])).prod(1) + 1e-7
    return iou, iou - (hull - union) / hull


def assign(
    targets: list[np.ndarray], centres: torch.Tensor, strides: torch.Tensor, inside: bool = False
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
    """Positive cells of each image and what they should predict.

    An object (class, x1, y1, x2, y2 in input pixels) goes to the level whose stride is nearest
    a quarter of its larger side, and to the next level in that direction when it lies between
    two; on a level it claims the cells whose centre lies within 1.5 strides of its centre
    (at least the nearest one) — with ``inside``, only those whose centre also lies inside the
    object's box, so that a narrow object (a person, a bottle) is not predicted from cells beside
    it. A cell claimed twice goes to the smaller object. An object with class -1 (too small to
    label) makes its cells *ignored*: no loss there either way.

    Returns:
        (positive mask [B, N], ignored mask [B, N], class id [B, N], target box xyxy [B, N, 4]).
    """
    batch, n = len(targets), len(centres)
    positive = torch.zeros(batch, n, dtype=torch.bool)
    ignored = torch.zeros(batch, n, dtype=torch.bool)
    cls = torch.zeros(batch, n, dtype=torch.long)
    boxes = torch.zeros(batch, n, 4)
    best_area = torch.full((batch, n), float("inf"))
    log_strides = np.log2(np.array(STRIDES, float))
    for b, objects in enumerate(targets):
        for c, x1, y1, x2, y2 in objects.tolist():
            size = max(x2 - x1, y2 - y1)
            ideal = math.log2(max(size, 1.0) / 4.0)
            levels = np.argsort(np.abs(log_strides - ideal))[:2]
            if abs(log_strides[levels[1]] - ideal) > 1.0:
                levels = levels[:1]
            cx, cy = (x1 + x2) / 2, (y1 + y2) / 2
            area = float((x2 - x1) * (y2 - y1))
            for level in levels:
                s = STRIDES[int(level)]
                on_level = strides == s
                dist = torch.max((centres[:, 0] - cx).abs(), (centres[:, 1] - cy).abs())
                near = on_level & (dist <= 1.5 * s)
                if inside and c >= 0:
                    near = near & (centres[:, 0] >= x1) & (centres[:, 0] <= x2)
                    near = near & (centres[:, 1] >= y1) & (centres[:, 1] <= y2)
                if not near.any():
                    near = on_level & (dist == dist[on_level].min())
                if c < 0:
                    ignored[b, near] = True
                    continue
                claim = near & (area < best_area[b])
                positive[b, claim] = True
                cls[b, claim] = int(c)
                boxes[b, claim] = torch.tensor([x1, y1, x2, y2], dtype=torch.float32)
                best_area[b, claim] = area
    return positive, ignored & ~positive, cls, boxes


def detection_loss(
    raw: torch.Tensor,
    targets: list[np.ndarray],
    centres: torch.Tensor,
    strides: torch.Tensor,
    inside: bool = False,
    iou_targets: bool = True,
) -> tuple[torch.Tensor, dict[str, float]]:
    """Classification (BCE, IoU-valued targets) plus GIoU box loss, per positive cell."""
    positive, ignored, cls, target_boxes = assign(targets, centres, strides, inside)
    logits = raw[..., 4:]
    score_target = torch.zeros_like(logits)
    num_pos = max(int(positive.sum()), 1)
    box_loss = raw.sum() * 0.0
    if positive.any():
        pred = box_xyxy(decode_boxes(raw, centres, strides)[positive])
        iou, g = giou(pred, target_boxes[positive])
        box_loss = (1.0 - g).sum() / num_pos
        score_target[positive, cls[positive]] = iou.detach().clamp(min=0.2) if iou_targets else 1.0
    weight = (~ignored).float()[..., None].expand_as(logits)
    cls_loss = F.binary_cross_entropy_with_logits(logits, score_target, weight, reduction="sum") / num_pos
    total = cls_loss + 5.0 * box_loss
    return total, {"cls": float(cls_loss.detach()), "box": float(box_loss.detach())}


# -- data -----------------------------------------------------------------------------------------


def to_input(
    images: np.ndarray, labels: list[np.ndarray], input_hw: tuple[int, int] = INPUT_HW
) -> tuple[np.ndarray, list[np.ndarray]]:
    """Letterbox camera images into ``input_hw`` exactly as the runtime does; move their boxes alike."""
    out = np.empty((len(images), *input_hw, 3), np.uint8)
    moved = []
    for k, (image, objects) in enumerate(zip(images, labels, strict=True)):
        out[k], box = letterbox(image, *input_hw)
        shifted = objects.copy()
        shifted[:, [1, 3]] = shifted[:, [1, 3]] * box.scale + box.pad_x
        shifted[:, [2, 4]] = shifted[:, [2, 4]] * box.scale + box.pad_y
        moved.append(shifted)
    return out, moved


def batch_tensors(
    images: np.ndarray, labels: list[np.ndarray], index: np.ndarray, rng: np.random.Generator
) -> tuple[torch.Tensor, list[np.ndarray]]:
    """A training batch: random horizontal flips and brightness/contrast jitter."""
    batch = images[index].astype(np.float32) / 255.0
    targets = [labels[i].copy() for i in index]
    width = batch.shape[2]
    for k in range(len(index)):
        if rng.random() < 0.5:
            batch[k] = batch[k, :, ::-1]
            x1 = targets[k][:, 1].copy()
            targets[k][:, 1] = width - targets[k][:, 3]
            targets[k][:, 3] = width - x1
        gain, bias = rng.uniform(0.75, 1.25), rng.uniform(-0.08, 0.08)
        batch[k] = np.clip(batch[k] * gain + bias, 0.0, 1.0)
    return torch.from_numpy(np.ascontiguousarray(batch.transpose(0, 3, 1, 2))), targets


# -- training -------------------------------------------------------------------------------------


def training_views(
    count: int, seed: int, first_world: int, input_hw: tuple[int, int], empty_share: float = 0.0
) -> tuple[np.ndarray, list[np.ndarray]]:
    """Render ``count`` labelled views from worlds ``first_world``... and letterbox them for the network.

    Objects too small to demand keep their boxes with class -1 (ignored cells).
    """
    started = time.perf_counter()
    images = np.empty((count, *input_hw, 3), np.uint8)
    labels: list[np.ndarray] = []
    counts = np.zeros(len(CLASSES), np.int64)
    small = 0
    view: View
    for k, view in enumerate(dataset_views(count, seed=seed, first_world=first_world,
                                           views_per_world=VIEWS_PER_WORLD, empty_share=empty_share)):
        counts += np.bincount(view.kept[:, 0].astype(int), minlength=len(CLASSES))
        small += len(view.ignored)
        ignored = view.ignored.copy()
        ignored[:, 0] = -1
        rows = np.concatenate([view.kept, ignored])
        (images[k:k + 1], moved) = to_input(view.color[None], [rows], input_hw)
        labels.append(moved[0])
    render_s = time.perf_counter() - started
    print(f"rendered {len(images)} views of worlds {first_world}... in {render_s:.0f} s; objects per class: "
          + ", ".join(f"{c}={n}" for c, n in zip(CLASSES, counts, strict=True))
          + f"; ignored (under {MIN_PIXELS} px): {small}", flush=True)
    return images, labels


def train(args: argparse.Namespace) -> None:
    """Render, train, export; print progress and a JSON summary line."""
    torch.manual_seed(args.seed)
    torch.set_num_threads(args.threads)
    rng = np.random.default_rng(args.seed)
    started = time.perf_counter()
    input_hw = (args.input_hw[0], args.input_hw[1])
    worlds_per_set = math.ceil(args.images / VIEWS_PER_WORLD)
    sets = args.epochs if args.fresh_views else 1
    if args.first_world + sets * worlds_per_set > EVAL_FIRST_WORLD:
        sys.exit(f"worlds {args.first_world}..{args.first_world + sets * worlds_per_set - 1} would reach the "
                 f"benchmark's (from {EVAL_FIRST_WORLD}); give a lower --first-world")
    images, labels = training_views(args.images, args.seed, args.first_world, input_hw, args.empty_rooms)
    render_s = time.perf_counter() - started
    model = TinyDetector(len(CLASSES), widths=tuple(args.widths), refine=args.refine)
    if args.init:
        calibration = torch.from_numpy(images[:64].transpose(0, 3, 1, 2).astype(np.float32) / 255.0)
        load_init(model, args.init, args.seed, calibration)
        print(f"starting from {args.init}", flush=True)
    params = sum(p.numel() for p in model.parameters())
    print(f"model: {params} parameters", flush=True)
    centres, strides = make_grid(*input_hw)
    steps_per_epoch = math.ceil(len(images) / args.batch)
    total_steps = steps_per_epoch * args.epochs
    if args.train == "refiners":
        if model.refiners is None:
            sys.exit("--train refiners needs --refine")
        for name, p in model.named_parameters():
            p.requires_grad_(name.startswith("refiners."))
    trainable = [p for p in model.parameters() if p.requires_grad]
    print(f"training {sum(p.numel() for p in trainable)} of them", flush=True)
    optimiser = torch.optim.AdamW(trainable, lr=args.lr, weight_decay=5e-4)
    schedule = torch.optim.lr_scheduler.OneCycleLR(
        optimiser, max_lr=args.lr, total_steps=total_steps, pct_start=0.1
    )
    # With only the refiners trained, the frozen network's batch norms keep their statistics.
    model.train(args.train == "all")
    deadline = started + args.max_minutes * 60.0
    for epoch in range(args.epochs):
        if args.stop_epoch is not None and epoch >= args.stop_epoch:
            print(f"stopping after {epoch} of {args.epochs} epochs (--stop-epoch)", flush=True)
            break
        if time.perf_counter() > deadline:
            print(f"stopping after {epoch} epochs: --max-minutes {args.max_minutes} reached (the result "
                  f"then depends on the machine's speed, not only on the seed)", flush=True)
            break
        if args.fresh_views and epoch > 0:
            del images, labels
            first = args.first_world + epoch * worlds_per_set
            images, labels = training_views(args.images, args.seed + epoch, first, input_hw, args.empty_rooms)
        order = rng.permutation(len(images))
        sums = {"loss": 0.0, "cls": 0.0, "box": 0.0}
        for step in range(steps_per_epoch):
            index = order[step * args.batch : (step + 1) * args.batch]
            x, targets = batch_tensors(images, labels, index, rng)
            raw = flatten_maps(model(x))
            loss, parts = detection_loss(raw, targets, centres, strides, inside=args.assign == "inside",
                                         iou_targets=args.cls_target == "iou")
            optimiser.zero_grad()
            loss.backward()
            torch.nn.utils.clip_grad_norm_(trainable, 10.0)
            optimiser.step()
            schedule.step()
            sums["loss"] += float(loss.detach())
            sums["cls"] += parts["cls"]
            sums["box"] += parts["box"]
            if (step + 1) % 25 == 0:
                done = epoch * steps_per_epoch + step + 1
                print(f"  step {done}/{total_steps} loss {float(loss.detach()):.3f} "
                      f"({time.perf_counter() - started:.0f} s)", flush=True)
        means = {k: v / steps_per_epoch for k, v in sums.items()}
        print(f"epoch {epoch + 1}/{args.epochs} loss {means['loss']:.3f} cls {means['cls']:.3f} "
              f"box {means['box']:.3f} ({time.perf_counter() - started:.0f} s)", flush=True)
    torch.save(model.state_dict(), Path(args.out).with_suffix(".pt"))
    export(model, Path(args.out), input_hw, training_note(args))
    print(json.dumps({"parameters": params, "images": len(images), "epochs": args.epochs, "seed": args.seed,
                      "render_s": round(render_s, 1), "total_s": round(time.perf_counter() - started, 1),
                      "out": args.out}))


def training_note(args: argparse.Namespace) -> str:
    """The training command's settings, for the exported model's ``training`` metadata."""
    return (f"seed={args.seed} images={args.images} epochs={args.epochs} "
            f"first_world={args.first_world} widths={args.widths} lr={args.lr} init={args.init} "
            f"cls_target={args.cls_target} assign={args.assign} input_hw={list(args.input_hw)} "
            f"refine={args.refine} train={args.train} fresh_views={args.fresh_views} "
            f"empty_rooms={args.empty_rooms}")


def parser() -> argparse.ArgumentParser:
    """The command line: the options the shipped model's stages used."""
    p = argparse.ArgumentParser(description=(__doc__ or "").split("\n\n")[0])
    p.add_argument("--seed", type=int, default=7, help="seed of rendering, init and shuffling")
    p.add_argument("--images", type=int, default=2400, help="views to render")
    p.add_argument("--first-world", type=int, default=0,
                   help=f"seed of the first generated world (evaluation uses seeds from {EVAL_FIRST_WORLD})")
    p.add_argument("--epochs", type=int, default=24)
    p.add_argument("--batch", type=int, default=32)
    p.add_argument("--lr", type=float, default=4e-3)
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--stop-epoch", type=int, default=None,
                   help="stop after this many epochs of the schedule (reproduces a run cut short)")
    p.add_argument("--init", default=None, help="start from these weights (a run's .pt or an exported .onnx)")
    p.add_argument("--cls-target", choices=["iou", "one"], default="iou",
                   help="score target of an object's cells: its predicted box's IoU, or 1")
    p.add_argument("--assign", choices=["centre", "inside"], default="centre",
                   help="positive cells: near the object's centre, or near it and inside its box")
    p.add_argument("--max-minutes", type=float, default=40.0,
                   help="stop at the end of the epoch that passes this much wall time")
    p.add_argument("--widths", type=int, nargs=4, default=[16, 48, 96, 160],
                   help="channels at strides 4, 8, 16, 32")
    p.add_argument("--fresh-views", action="store_true",
                   help="render --images new views of new worlds for every epoch instead of reusing "
                   "one set (the network memorises a set it sees several times)")
    p.add_argument("--empty-rooms", type=float, default=0.0, metavar="SHARE",
                   help="share of the worlds rendered bare (no objects, no people), so that floors and "
                   "walls stay negatives")
    p.add_argument("--refine", action="store_true",
                   help="give each level a refiner that re-scores classes from the box's place in the "
                   "frame (see network.Refiner)")
    p.add_argument("--train", choices=["all", "refiners"], default="all",
                   help="train every weight, or only the refiners (the rest frozen as --init left it)")
    p.add_argument("--input-hw", type=int, nargs=2, default=list(INPUT_HW), metavar=("H", "W"),
                   help="network input (height, width), multiples of 32: 128 160 is half scale, "
                   "256 320 full scale")
    p.add_argument("--out", required=True,
                   help="the .onnx to write (its weights go beside it as .pt); the shipped model is "
                   "src/missiontree/data/models/sim_detector.onnx")
    return p


def main(argv: list[str] | None = None) -> None:
    """Parse the command line and train."""
    train(parser().parse_args(argv))


if __name__ == "__main__":
    main()
