"""Train the shipped simulator detector and export it in the YOLOv8/YOLO11 ONNX layout.

Renders labelled views with the simulator's camera (scripts/detector_data.py), trains a small
single-stage anchor-free detector with CPU PyTorch, and writes an ONNX model whose one output is
``[1, 4 + classes, N]`` (box centre, width, height in input pixels, then sigmoid class scores) with
the class names in its metadata, so :class:`missiontree.perception.detectors.YoloOnnxDetector`
loads it like any Ultralytics export.

Needs the ``train`` extra (``.venv/bin/pip install -e '.[train]'``, which pins the CPU torch).
Reproducible from ``--seed``: the same seed renders the same images and initialises and shuffles
the same way (torch's CPU kernels are deterministic on one machine with fixed threads)::

    .venv/bin/python scripts/train_detector.py --seed 7 --out src/missiontree/data/models/sim_detector.onnx

The network (about 0.3 M parameters): a strided conv backbone with depthwise-separable residual
blocks to stride 32, a top-down feature pyramid, and a shared-weight-free head per level (strides
8, 16, 32) predicting class logits and a box (centre offset and log size per cell). Each object is
assigned to the cells around its centre on the level whose stride suits its size; classification
is binary cross-entropy with the IoU of the cell's predicted box as its target (at least 0.2; 0
elsewhere, nothing on the cells of objects too small to demand), so that scores rank boxes by how
well they fit (``--cls-target one``: target 1); boxes are trained with GIoU.
"""

from __future__ import annotations

import argparse
import functools
import json
import math
import sys
import time
from pathlib import Path

import cv2
import numpy as np

try:
    import torch
    from torch import nn
    from torch.nn import functional as F  # noqa: N812 (the conventional name)
except ImportError:  # pragma: no cover - depends on the extra
    sys.exit("training needs the train extra: .venv/bin/pip install -e '.[train]' (pins the CPU torch)")

sys.path.insert(0, str(Path(__file__).resolve().parent))
from detector_data import CLASSES, EVAL_FIRST_WORLD, MIN_PIXELS, View, dataset_views  # noqa: E402

from missiontree.perception.detectors import letterbox  # noqa: E402

STRIDES = (8, 16, 32)
#: Default input size of the network (height, width): the 320x240 camera image letterboxed at half
#: scale (160x120 plus 4 grey rows above and below). Half scale quarters the cost of training on the
#: shared 2-core CPU; objects smaller than MIN_PIXELS at full scale are not demanded. ``--input-hw
#: 256 320`` trains at full scale (8 grey rows above and below), which small and narrow objects need.
INPUT_HW = (128, 160)
#: Views rendered of each generated world.
VIEWS_PER_WORLD = 25
#: Share of a cell an object's visible pixels must cover for the cell to be taught that object
#: (``--assign visible``).
VISIBLE_CELL = 0.25


# -- the network ----------------------------------------------------------------------------------


def conv_bn(
    c_in: int, c_out: int, k: int = 3, s: int = 1, groups: int = 1, act: bool = True
) -> nn.Sequential:
    """Convolution, batch norm and (optionally) SiLU."""
    layers: list[nn.Module] = [
        nn.Conv2d(c_in, c_out, k, s, 0 if k == s else k // 2, groups=groups, bias=False),
        nn.BatchNorm2d(c_out),
    ]
    if act:
        layers.append(nn.SiLU())
    return nn.Sequential(*layers)


class SeparableBlock(nn.Module):
    """Residual depthwise 3x3 + pointwise 1x1 block."""

    def __init__(self, c: int) -> None:
        super().__init__()
        self.body = nn.Sequential(conv_bn(c, c, 3, groups=c), conv_bn(c, c, 1, act=False))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """Add the block's output to its input."""
        return F.silu(x + self.body(x))


class Refiner(nn.Module):
    """Re-scores one level's classes from the cell's features, its predicted box and its first scores.

    Objects here are prisms of a few colours whose classes differ mostly in size (a grey table and
    a grey sofa, a white bookshelf and a white refrigerator, a chair and a refrigerator close up).
    With the camera level at a fixed height, the size of a floor-standing object in metres follows
    from where its box lies relative to the horizon (the image's middle row): its height is
    the camera height times the box's height over the distance from the horizon to its bottom edge.
    The convolutions see only local patterns, so each cell is given its box's edges relative to
    the frame's centre; a small 1x1 network adds a correction to the class logits. Its last layer
    starts at zero, so a trained detector given a refiner first computes exactly what it did.
    """

    #: Geometry channels: box left, right, top and bottom edges relative to the frame's centre
    #: (in frame heights and widths), log width and log height (in frame heights).
    GEOMETRY = 6

    def __init__(self, channels: int, num_classes: int, hidden: int = 64) -> None:
        super().__init__()
        self.body = nn.Sequential(
            nn.Conv2d(channels + self.GEOMETRY + num_classes, hidden, 1),
            nn.SiLU(),
            nn.Conv2d(hidden, num_classes, 1),
        )
        nn.init.zeros_(self.body[-1].weight)
        nn.init.zeros_(self.body[-1].bias)

    def forward(self, features: torch.Tensor, out: torch.Tensor, stride: int) -> torch.Tensor:
        """``out`` (a head's raw [B, 4 + C, h, w] map) with corrected class logits."""
        h, w = out.shape[2], out.shape[3]
        height, width = float(h * stride), float(w * stride)
        raw = out.detach()
        rows, cols = torch.arange(h, dtype=raw.dtype), torch.arange(w, dtype=raw.dtype)
        ys, xs = torch.meshgrid(rows, cols, indexing="ij")
        centres = torch.stack([(xs + 0.5) * stride, (ys + 0.5) * stride], dim=-1)
        cx, cy, bw, bh = decode_cells(raw[:, :4].permute(0, 2, 3, 1), centres, float(stride)).unbind(-1)
        geometry = torch.stack([
            (cx - bw / 2 - width / 2) / width, (cx + bw / 2 - width / 2) / width,
            (cy - bh / 2 - height / 2) / height, (cy + bh / 2 - height / 2) / height,
            torch.log(bw / height), torch.log(bh / height),
        ], dim=1)
        delta = self.body(torch.cat([features, geometry, torch.sigmoid(raw[:, 4:])], dim=1))
        return torch.cat([out[:, :4], out[:, 4:] + delta], dim=1)


class TinyDetector(nn.Module):
    """A small anchor-free detector; ``forward`` returns raw per-level maps, ``export`` decodes."""

    def __init__(
        self, num_classes: int, widths: tuple[int, ...] = (16, 48, 96, 160), refine: bool = False
    ) -> None:
        super().__init__()
        w2, w3, w4, w5 = widths
        self.num_classes = num_classes
        # A 4x4 stride-4 "patchify" stem: rendered scenes need no fine texture at full resolution,
        # and it costs a fifth of two strided 3x3 convolutions.
        self.stem = nn.Sequential(conv_bn(3, w2, 4, 4), SeparableBlock(w2))
        self.down3 = nn.Sequential(conv_bn(w2, w3, 3, 2), SeparableBlock(w3), SeparableBlock(w3))
        self.down4 = nn.Sequential(conv_bn(w3, w4, 3, 2), SeparableBlock(w4), SeparableBlock(w4))
        self.down5 = nn.Sequential(conv_bn(w4, w5, 3, 2), SeparableBlock(w5))
        self.lat5 = conv_bn(w5, w4, 1)
        self.lat4 = conv_bn(w4, w3, 1)
        self.fuse4 = SeparableBlock(w4)
        self.fuse3 = SeparableBlock(w3)
        self.heads = nn.ModuleList(
            nn.Sequential(conv_bn(c, c, 3, groups=c), conv_bn(c, c, 1), nn.Conv2d(c, 4 + num_classes, 1))
            for c in (w3, w4, w5)
        )
        prior = -math.log((1 - 0.01) / 0.01)  # start every class score near 1 %
        for head in self.heads:
            nn.init.constant_(head[-1].bias[4:], prior)
            nn.init.zeros_(head[-1].bias[:4])
        self.refiners = nn.ModuleList(Refiner(c, num_classes) for c in (w3, w4, w5)) if refine else None

    def forward(self, x: torch.Tensor) -> list[torch.Tensor]:
        """Raw head maps, one [B, 4 + C, H/s, W/s] per stride."""
        p3 = self.down3(self.stem(x))
        p4 = self.down4(p3)
        p5 = self.down5(p4)
        f4 = self.fuse4(p4 + F.interpolate(self.lat5(p5), scale_factor=2.0, mode="nearest"))
        f3 = self.fuse3(p3 + F.interpolate(self.lat4(f4), scale_factor=2.0, mode="nearest"))
        if self.refiners is None:
            return [head(f) for head, f in zip(self.heads, (f3, f4, p5), strict=True)]
        maps = []
        for head, refiner, f, s in zip(self.heads, self.refiners, (f3, f4, p5), STRIDES, strict=True):
            features = head[1](head[0](f))
            maps.append(refiner(features, head[2](features), s))
        return maps


def make_grid(height: int, width: int) -> tuple[torch.Tensor, torch.Tensor]:
    """Cell centres (N x 2, input pixels) and strides (N) of every output cell, level by level."""
    centres, strides = [], []
    for s in STRIDES:
        ys, xs = torch.meshgrid(torch.arange(height // s), torch.arange(width // s), indexing="ij")
        centres.append(torch.stack([(xs.flatten() + 0.5) * s, (ys.flatten() + 0.5) * s], dim=1))
        strides.append(torch.full((xs.numel(),), float(s)))
    return torch.cat(centres).float(), torch.cat(strides)


def flatten_maps(maps: list[torch.Tensor]) -> torch.Tensor:
    """Concatenate per-level maps into [B, N, 4 + C]."""
    return torch.cat([m.flatten(2) for m in maps], dim=2).transpose(1, 2)


def decode_cells(raw: torch.Tensor, centres: torch.Tensor, strides: torch.Tensor | float) -> torch.Tensor:
    """Box (cx, cy, w, h in input pixels) from raw outputs, box channels last.

    The raw values are a centre offset and a log size, in cells; ``centres`` (..., 2) and ``strides``
    broadcast against ``raw[..., :2]``.
    """
    cxy = centres + torch.tanh(raw[..., 0:2]) * 2.0 * strides
    wh = torch.exp(raw[..., 2:4].clamp(-6.0, 6.0)) * 2.0 * strides
    return torch.cat([cxy, wh], dim=-1)


def decode_boxes(raw: torch.Tensor, centres: torch.Tensor, strides: torch.Tensor) -> torch.Tensor:
    """Boxes of flattened outputs [B, N, 4 + C] with the cells of :func:`make_grid`."""
    return decode_cells(raw, centres[None], strides[None, :, None])


class ExportWrapper(nn.Module):
    """The network with decoding, output ``[1, 4 + C, N]`` as a YOLOv8 export has."""

    def __init__(self, model: TinyDetector, height: int, width: int) -> None:
        super().__init__()
        self.model = model
        centres, strides = make_grid(height, width)
        self.register_buffer("centres", centres)
        self.register_buffer("strides", strides)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """Decoded boxes and sigmoid class scores, channels first."""
        raw = flatten_maps(self.model(x))
        boxes = decode_boxes(raw, self.centres, self.strides)
        return torch.cat([boxes, torch.sigmoid(raw[..., 4:])], dim=-1).transpose(1, 2)


def _layers(model: TinyDetector) -> list[tuple[nn.Conv2d, nn.BatchNorm2d | None, int | None, int | None]]:
    """Every convolution with its batch norm and the channel spaces it reads and writes.

    Spaces 0-3 are the widths at strides 4, 8, 16 and 32 (every tensor joined to another by an
    addition lives in one of them); None is the RGB input or the head's output.
    """
    layers: list[tuple[nn.Conv2d, nn.BatchNorm2d | None, int | None, int | None]] = []

    def conv(seq: nn.Sequential, c_in: int | None, c_out: int | None) -> None:
        layers.append((seq[0], seq[1], c_in, c_out))

    def block(b: SeparableBlock, space: int) -> None:
        conv(b.body[0], space, space)
        conv(b.body[1], space, space)

    conv(model.stem[0], None, 0)
    block(model.stem[1], 0)
    conv(model.down3[0], 0, 1)
    block(model.down3[1], 1)
    block(model.down3[2], 1)
    conv(model.down4[0], 1, 2)
    block(model.down4[1], 2)
    block(model.down4[2], 2)
    conv(model.down5[0], 2, 3)
    block(model.down5[1], 3)
    conv(model.lat5, 3, 2)
    conv(model.lat4, 2, 1)
    block(model.fuse4, 2)
    block(model.fuse3, 1)
    for head, space in zip(model.heads, (1, 2, 3), strict=True):
        conv(head[0], space, space)
        conv(head[1], space, space)
        layers.append((head[2], None, space, None))
    return layers


def widen(narrow: TinyDetector, wide: TinyDetector, seed: int, noise: float = 0.01) -> None:
    """Copy ``narrow``'s weights into the wider ``wide`` so that it computes the same function.

    Net2Net widening (Chen et al., 2016): each new channel of a width copies a random existing
    one; a layer reading a copied channel divides that channel's weights by its number of copies,
    so sums stay as they were. Small noise (``noise`` times each weight tensor's spread) on the
    copies breaks their symmetry, since identical channels would otherwise get identical gradients.
    """
    rng = np.random.default_rng(seed)
    old_widths, new_widths = _widths(narrow), _widths(wide)
    pick, copies = [], []
    for old, new in zip(old_widths, new_widths, strict=True):
        if new < old:
            raise ValueError(f"cannot widen {old_widths} to narrower {new_widths}")
        g = np.concatenate([np.arange(old), rng.integers(0, old, new - old)])
        pick.append(torch.from_numpy(g))
        copies.append(torch.from_numpy(np.bincount(g, minlength=old)).float())
    with torch.no_grad():
        pairs = zip(_layers(narrow), _layers(wide), strict=True)
        for (c_old, bn_old, s_in, s_out), (c_new, bn_new, _, _) in pairs:
            w = c_old.weight
            out_pick = pick[s_out] if s_out is not None else torch.arange(w.shape[0])
            w = w[out_pick]
            if c_old.groups == 1 and s_in is not None:
                w = w[:, pick[s_in]] / copies[s_in][pick[s_in]][None, :, None, None]
            fresh = torch.zeros(w.shape[0], dtype=torch.bool)
            if s_out is not None:
                fresh[old_widths[s_out]:] = True
            w = w + fresh[:, None, None, None] * torch.randn(w.shape, generator=torch.Generator().manual_seed(
                int(rng.integers(2**31)))) * noise * float(c_old.weight.std())
            c_new.weight.copy_(w)
            if c_old.bias is not None:
                c_new.bias.copy_(c_old.bias[out_pick])
            if bn_old is not None and bn_new is not None:
                for name in ("weight", "bias", "running_mean", "running_var"):
                    getattr(bn_new, name).copy_(getattr(bn_old, name)[out_pick])
                bn_new.num_batches_tracked.copy_(bn_old.num_batches_tracked)
        if narrow.refiners is None or wide.refiners is None:
            return
        for r_old, r_new, space in zip(narrow.refiners, wide.refiners, (1, 2, 3), strict=True):
            # A refiner reads its head's features (widened like the head), then geometry and scores.
            first, width = r_old.body[0].weight, old_widths[space]
            features = first[:, :width][:, pick[space]] / copies[space][pick[space]][None, :, None, None]
            r_new.body[0].weight.copy_(torch.cat([features, first[:, width:]], dim=1))
            r_new.body[0].bias.copy_(r_old.body[0].bias)
            r_new.body[2].load_state_dict(r_old.body[2].state_dict())


def load_onnx(model: TinyDetector, path: str, calibration: torch.Tensor) -> None:
    """Load the weights of an exported model (``path``, written by :func:`export`) into ``model``.

    The export folds each batch norm into the convolution before it, so the ONNX file holds one
    weight and one bias per convolution. Each is copied into its convolution, and the batch norm
    after it is set so that it computes the same thing in evaluation *and* normalises as it did in
    training: its running mean and variance become the statistics of the convolution's output on
    ``calibration`` (a batch of input images), and its scale and shift undo them exactly. The model
    then computes what the ONNX file computes, and training can go on from it.
    """
    import onnx
    from onnx import numpy_helper

    proto = onnx.load(path)
    arrays = {i.name: numpy_helper.to_array(i) for i in proto.graph.initializer}
    for node in proto.graph.node:  # the exporter shares equal tensors through Identity nodes
        if node.op_type == "Identity" and node.input[0] in arrays:
            arrays[node.output[0]] = arrays[node.input[0]]
    nodes = [n for n in proto.graph.node if n.op_type == "Conv"]
    order: list[nn.Conv2d] = []
    hooks = [m.register_forward_hook(lambda m, i, o: order.append(m))
             for m in model.modules() if isinstance(m, nn.Conv2d)]
    model.eval()
    with torch.no_grad():
        model(calibration[:1])
    for hook in hooks:
        hook.remove()
    if len(order) != len(nodes):
        raise ValueError(f"{path}: {len(nodes)} convolutions, the network has {len(order)}")
    norm_of = {id(conv): bn for conv, bn, _, _ in _layers(model)}
    eps = 1e-5
    with torch.no_grad():
        for conv, node in zip(order, nodes, strict=True):
            weight = torch.from_numpy(arrays[node.input[1]].copy())
            bias = torch.from_numpy(arrays[node.input[2]].copy())
            if weight.shape != conv.weight.shape:
                raise ValueError(f"{path}: a convolution of shape {list(weight.shape)} where the network "
                                 f"has {list(conv.weight.shape)} (other --widths?)")
            conv.weight.copy_(weight)
            bn = norm_of.get(id(conv))
            if bn is None:
                conv.bias.copy_(bias)
                continue
            bn.weight.fill_(1.0)
            bn.bias.copy_(bias)
            bn.running_mean.zero_()
            bn.running_var.fill_(1.0 - eps)
        # Now exact in evaluation; measure each convolution's raw output and re-express its norm.
        stats: dict[int, torch.Tensor] = {}

        def measure(m: nn.Module, i: tuple[torch.Tensor, ...], o: torch.Tensor) -> None:
            stats[id(m)] = torch.stack([o.mean((0, 2, 3)), o.var((0, 2, 3), unbiased=False)])

        hooks = [conv.register_forward_hook(measure) for conv in order if id(conv) in norm_of]
        model(calibration)
        for hook in hooks:
            hook.remove()
        for conv in order:
            bn = norm_of.get(id(conv))
            if bn is None:
                continue
            mean, var = stats[id(conv)]
            bn.running_mean.copy_(mean)
            bn.running_var.copy_(var)
            bn.weight.copy_((var + eps).sqrt())
            bn.bias.add_(mean)


def load_init(model: TinyDetector, path: str, seed: int, calibration: torch.Tensor | None = None) -> None:
    """Start from the weights in ``path``: as they are, or widened when they are a narrower network's.

    ``path`` is a ``.pt`` written by a run, or an exported ``.onnx`` (the shipped model), whose
    batch norms are recovered on ``calibration`` images (see :func:`load_onnx`). Weights without
    refiners start a model with refiners whose refiners compute no correction yet.
    """
    if path.endswith(".onnx"):
        if calibration is None:
            raise ValueError("starting from an .onnx model needs calibration images")
        try:
            load_onnx(model, path, calibration)
            return
        except ValueError:
            if model.refiners is None:
                raise
        plain = TinyDetector(model.num_classes, widths=_widths(model))
        load_onnx(plain, path, calibration)
        _add_refiners(model, plain)
        return
    state = torch.load(path)
    old = tuple(int(state[k].shape[0]) for k in ("stem.0.0.weight", "down3.0.0.weight", "down4.0.0.weight",
                                                 "down5.0.0.weight"))
    if any(k.startswith("refiners.") for k in state):
        if old == _widths(model) or model.refiners is None:
            model.load_state_dict(state)  # a clear error when the widths or the refiners do not fit
            return
        narrow = TinyDetector(model.num_classes, widths=old, refine=True)
        narrow.load_state_dict(state)
        widen(narrow, model, seed)
        print(f"widened {path} and its refiners from {list(old)} to {list(_widths(model))}", flush=True)
        return
    plain = model if model.refiners is None else TinyDetector(model.num_classes, widths=_widths(model))
    if _widths(plain) == old:
        plain.load_state_dict(state)
    else:
        narrow = TinyDetector(model.num_classes, widths=old)
        narrow.load_state_dict(state)
        widen(narrow, plain, seed)
        print(f"widened {path} from widths {list(old)} to {list(_widths(model))}", flush=True)
    if plain is not model:
        _add_refiners(model, plain)


def _add_refiners(model: TinyDetector, plain: TinyDetector) -> None:
    """Copy ``plain``'s weights into ``model``, whose refiners keep their fresh (no-correction) start."""
    missing, unexpected = model.load_state_dict(plain.state_dict(), strict=False)
    if unexpected or not all(k.startswith("refiners.") for k in missing):
        raise ValueError(f"weights do not fit the network: missing {missing}, unexpected {unexpected}")


def _widths(model: TinyDetector) -> tuple[int, ...]:
    """Channels at strides 4, 8, 16 and 32."""
    firsts = (model.stem[0], model.down3[0], model.down4[0], model.down5[0])
    return tuple(int(m[0].out_channels) for m in firsts)


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
    targets: list[np.ndarray],
    centres: torch.Tensor,
    strides: torch.Tensor,
    inside: bool = False,
    coverage: list[np.ndarray] | None = None,
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
    """Positive cells of each image and what they should predict.

    An object (class, x1, y1, x2, y2 in input pixels) goes to the level whose stride is nearest
    a quarter of its larger side, and to the next level in that direction when it lies between
    two; on a level it claims the cells whose centre lies within 1.5 strides of its centre
    (at least the nearest one) — with ``inside``, only those whose centre also lies inside the
    object's box, so that a narrow object (a person, a bottle) is not predicted from cells beside
    it. A cell claimed twice goes to the smaller object. An object with class -1 (too small to
    label) makes its cells *ignored*: no loss there either way.

    With ``coverage`` (per image, the share of each cell that each object's visible pixels cover,
    [objects, N] in 0-255, from :func:`cell_coverage`), an object partly hidden behind another
    claims only those of its cells that show it (a quarter of the cell or more; failing that, the
    ones showing the most of it), not cells that show the thing in front; a cell claimed twice
    goes to the object covering more of it, then to the smaller. Objects in full view claim the
    cells they did. Without it, a chair whose box centre lies on the table in front is taught from
    the table's pixels, and the chair's own visible part is taught as background.

    Returns:
        (positive mask [B, N], ignored mask [B, N], class id [B, N], target box xyxy [B, N, 4]).
    """
    batch, n = len(targets), len(centres)
    positive = torch.zeros(batch, n, dtype=torch.bool)
    ignored = torch.zeros(batch, n, dtype=torch.bool)
    cls = torch.zeros(batch, n, dtype=torch.long)
    boxes = torch.zeros(batch, n, 4)
    best_area = torch.full((batch, n), float("inf"))
    best_cover = torch.zeros(batch, n)
    log_strides = np.log2(np.array(STRIDES, float))
    for b, objects in enumerate(targets):
        covers = None if coverage is None else torch.from_numpy(coverage[b].astype(np.float32) / 255.0)
        for k, (c, x1, y1, x2, y2) in enumerate(objects.tolist()):
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
                if covers is None:
                    claim = near & (area < best_area[b])
                else:
                    cover = torch.where(near, covers[k], 0.0)
                    if (cover >= VISIBLE_CELL).any():
                        near = cover >= VISIBLE_CELL
                    elif cover.max() > 0:
                        near = cover == cover.max()
                    cover = torch.where(near, cover, 0.0)
                    more = (cover > best_cover[b]) | ((cover == best_cover[b]) & (area < best_area[b]))
                    claim = near & more
                    best_cover[b, claim] = cover[claim]
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
    coverage: list[np.ndarray] | None = None,
    focus: float = 0.0,
) -> tuple[torch.Tensor, dict[str, float]]:
    """Classification (BCE, IoU-valued targets) plus GIoU box loss, per positive cell.

    With ``focus`` > 0 each cell's classification term is scaled by ``|target - score| ** focus``
    (quality focal loss, Li et al. 2020, GFL): the many cells already scored right weigh little
    and the hard ones (a look-alike class, a fragment) weigh more.
    """
    positive, ignored, cls, target_boxes = assign(targets, centres, strides, inside, coverage)
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
    if focus > 0:
        weight = weight * (score_target - torch.sigmoid(logits)).abs().detach().pow(focus)
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


def cell_coverage(instances: np.ndarray, ids: np.ndarray, input_hw: tuple[int, int]) -> np.ndarray:
    """Share of every output cell (:func:`make_grid`'s order) that each object's visible pixels cover.

    Args:
        instances: The view's instance mask (camera pixels).
        ids: Instance ids of the objects, one row of the result each (0 for a row with no object).
        input_hw: Network input; the mask is letterboxed into it as the image is.

    Returns:
        [len(ids), N] uint8, 255 = the object fills the cell.
    """
    height, width = input_hw
    framed, _ = letterbox(instances.astype(np.float32), height, width,  # ids are exact in float32
                          interpolation=cv2.INTER_NEAREST, pad_value=-1.0)
    shown = (framed[None] == np.asarray(ids, np.float32)[:, None, None]).astype(np.float32)
    shown[np.asarray(ids) == 0] = 0.0
    levels = [shown.reshape(len(ids), height // s, s, width // s, s).mean((2, 4)).reshape(len(ids), -1)
              if len(ids) else np.zeros((0, (height // s) * (width // s))) for s in STRIDES]
    return np.round(np.concatenate(levels, axis=1) * 255.0).astype(np.uint8)


@functools.lru_cache(maxsize=4)
def mirrored_cells(input_hw: tuple[int, int]) -> np.ndarray:
    """For every cell of :func:`make_grid`, the index of the cell at its mirror image (horizontal flip)."""
    index, first = [], 0
    for s in STRIDES:
        rows, cols = input_hw[0] // s, input_hw[1] // s
        grid = np.arange(rows * cols).reshape(rows, cols)[:, ::-1]
        index.append(grid.flatten() + first)
        first += rows * cols
    mirror = np.concatenate(index)
    mirror.setflags(write=False)  # cached: shared by every caller
    return mirror


def batch_tensors(
    images: np.ndarray,
    labels: list[np.ndarray],
    index: np.ndarray,
    rng: np.random.Generator,
    coverage: list[np.ndarray] | None = None,
) -> tuple[torch.Tensor, list[np.ndarray], list[np.ndarray] | None]:
    """A training batch: random horizontal flips and brightness/contrast jitter.

    ``coverage`` (per image, from :func:`cell_coverage`) is flipped with its image.
    """
    batch = images[index].astype(np.float32) / 255.0
    targets = [labels[i].copy() for i in index]
    covers = None if coverage is None else [coverage[i] for i in index]
    width = batch.shape[2]
    mirror = mirrored_cells(tuple(batch.shape[1:3])) if coverage is not None else None
    for k in range(len(index)):
        if rng.random() < 0.5:
            batch[k] = batch[k, :, ::-1]
            x1 = targets[k][:, 1].copy()
            targets[k][:, 1] = width - targets[k][:, 3]
            targets[k][:, 3] = width - x1
            if covers is not None:
                covers[k] = covers[k][:, mirror]
        gain, bias = rng.uniform(0.75, 1.25), rng.uniform(-0.08, 0.08)
        batch[k] = np.clip(batch[k] * gain + bias, 0.0, 1.0)
    return torch.from_numpy(np.ascontiguousarray(batch.transpose(0, 3, 1, 2))), targets, covers


# -- training and export --------------------------------------------------------------------------


def training_views(
    count: int,
    seed: int,
    first_world: int,
    input_hw: tuple[int, int],
    empty_share: float = 0.0,
    with_coverage: bool = False,
) -> tuple[np.ndarray, list[np.ndarray], list[np.ndarray] | None]:
    """Render ``count`` labelled views from worlds ``first_world``... and letterbox them for the network.

    Objects too small to demand keep their boxes with class -1 (ignored cells). With
    ``with_coverage``, also each label row's :func:`cell_coverage` (zero for the ignored rows).
    """
    started = time.perf_counter()
    images = np.empty((count, *input_hw, 3), np.uint8)
    labels: list[np.ndarray] = []
    coverage: list[np.ndarray] | None = [] if with_coverage else None
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
        if coverage is not None:
            ids = np.concatenate([view.kept_ids, np.zeros(len(ignored), np.int64)])
            coverage.append(cell_coverage(view.instances, ids, input_hw))
    render_s = time.perf_counter() - started
    print(f"rendered {len(images)} views of worlds {first_world}... in {render_s:.0f} s; objects per class: "
          + ", ".join(f"{c}={n}" for c, n in zip(CLASSES, counts, strict=True))
          + f"; ignored (under {MIN_PIXELS} px): {small}", flush=True)
    return images, labels, coverage


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
    visible = args.assign == "visible"
    images, labels, coverage = training_views(args.images, args.seed, args.first_world, input_hw,
                                              args.empty_rooms, visible)
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
    average = weight_average(model, args.ema) if args.ema else None
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
            del images, labels, coverage
            first = args.first_world + epoch * worlds_per_set
            images, labels, coverage = training_views(args.images, args.seed + epoch, first, input_hw,
                                                      args.empty_rooms, visible)
        order = rng.permutation(len(images))
        sums = {"loss": 0.0, "cls": 0.0, "box": 0.0}
        for step in range(steps_per_epoch):
            index = order[step * args.batch : (step + 1) * args.batch]
            x, targets, covers = batch_tensors(images, labels, index, rng, coverage)
            raw = flatten_maps(model(x))
            loss, parts = detection_loss(raw, targets, centres, strides, inside=args.assign != "centre",
                                         iou_targets=args.cls_target == "iou", coverage=covers,
                                         focus=args.focus)
            optimiser.zero_grad()
            loss.backward()
            torch.nn.utils.clip_grad_norm_(trainable, 10.0)
            optimiser.step()
            schedule.step()
            if average is not None:
                average.update_parameters(model)
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
    final = model if average is None else average.module
    torch.save(final.state_dict(), Path(args.out).with_suffix(".pt"))
    export(final, Path(args.out), input_hw, training_note(args))
    print(json.dumps({"parameters": params, "images": len(images), "epochs": args.epochs, "seed": args.seed,
                      "render_s": round(render_s, 1), "total_s": round(time.perf_counter() - started, 1),
                      "out": args.out}))


def weight_average(model: TinyDetector, decay: float) -> torch.optim.swa_utils.AveragedModel:
    """An exponential moving average of ``model``'s weights and batch-norm statistics (``--ema``).

    Updated after every optimiser step, it is what the run saves and exports: the average of about
    the last 1 / (1 - decay) steps' weights, which smooths out the single steps' noise (as
    Ultralytics' ModelEMA does; torch's ``AveragedModel``). Its first update copies the model, so a
    run from ``--init`` averages from those weights on. On the simulator detector after stage 15 it
    scored as the plain stage did (src/missiontree/data/models/README.md).
    """
    from torch.optim.swa_utils import AveragedModel, get_ema_multi_avg_fn

    return AveragedModel(model, multi_avg_fn=get_ema_multi_avg_fn(decay), use_buffers=True)


def training_note(args: argparse.Namespace) -> str:
    """The training command's settings, for the exported model's ``training`` metadata."""
    return (f"seed={args.seed} images={args.images} epochs={args.epochs} "
            f"first_world={args.first_world} widths={args.widths} lr={args.lr} init={args.init} "
            f"cls_target={args.cls_target} assign={args.assign} input_hw={list(args.input_hw)} "
            f"refine={args.refine} train={args.train} fresh_views={args.fresh_views} "
            f"empty_rooms={args.empty_rooms} ema={args.ema} focus={args.focus}")


def export(model: TinyDetector, out: Path, input_hw: tuple[int, int], training: str) -> None:
    """Write the ONNX model with Ultralytics-style metadata (names, stride, imgsz, task).

    Args:
        model: The network (put in evaluation mode; its batch norms fold into the convolutions).
        out: The ``.onnx`` file to write.
        input_hw: Network input (height, width).
        training: How the weights were made, kept in the ``training`` metadata.
    """
    import onnx

    model.eval()
    wrapper = ExportWrapper(model, *input_hw).eval()
    out.parent.mkdir(parents=True, exist_ok=True)
    dummy = torch.zeros(1, 3, *input_hw)
    torch.onnx.export(wrapper, (dummy,), str(out), input_names=["images"], output_names=["output0"],
                      opset_version=17, dynamo=False)
    proto = onnx.load(str(out))
    metadata = {
        "names": str(dict(enumerate(CLASSES))),
        "stride": str(max(STRIDES)),
        "imgsz": str(list(input_hw)),
        "task": "detect",
        "description": "missiontree simulator detector (scripts/train_detector.py)",
        "training": training,
    }
    onnx.helper.set_model_props(proto, metadata)
    onnx.save(proto, str(out))
    print(f"wrote {out} ({out.stat().st_size / 1e6:.2f} MB)", flush=True)


def main(argv: list[str] | None = None) -> None:
    """Parse the command line and train."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seed", type=int, default=7, help="seed of rendering, init and shuffling")
    parser.add_argument("--images", type=int, default=2400, help="views to render")
    parser.add_argument("--first-world", type=int, default=0,
                        help="seed of the first generated world (evaluation uses seeds from 10000)")
    parser.add_argument("--epochs", type=int, default=24)
    parser.add_argument("--batch", type=int, default=32)
    parser.add_argument("--lr", type=float, default=4e-3)
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--stop-epoch", type=int, default=None,
                        help="stop after this many epochs of the schedule (reproduces a run cut short)")
    parser.add_argument("--init", default=None, help="start from these weights (a .pt written by a run)")
    parser.add_argument("--cls-target", choices=["iou", "one"], default="iou",
                        help="score target of an object's cells: its predicted box's IoU, or 1")
    parser.add_argument("--assign", choices=["centre", "inside", "visible"], default="centre",
                        help="positive cells: near the object's centre, or near it and inside its box, or "
                        "those of these that show the object (not what hides it; see assign)")
    parser.add_argument("--focus", type=float, default=0.0, metavar="BETA",
                        help="quality focal loss: scale each cell's class loss by |target - score|^BETA "
                        "(GFL uses 2; 0: plain binary cross-entropy)")
    parser.add_argument("--max-minutes", type=float, default=40.0,
                        help="stop at the end of the epoch that passes this much wall time")
    parser.add_argument("--widths", type=int, nargs=4, default=[16, 48, 96, 160],
                        help="channels at strides 4, 8, 16, 32")
    parser.add_argument("--fresh-views", action="store_true",
                        help="render --images new views of new worlds for every epoch instead of reusing "
                        "one set (the network memorises a set it sees several times)")
    parser.add_argument("--empty-rooms", type=float, default=0.0, metavar="SHARE",
                        help="share of the worlds rendered bare (no objects, no people), so that floors and "
                        "walls stay negatives")
    parser.add_argument("--refine", action="store_true",
                        help="give each level a refiner that re-scores classes from the box's place in the "
                        "frame (see Refiner)")
    parser.add_argument("--train", choices=["all", "refiners"], default="all",
                        help="train every weight, or only the refiners (the rest frozen as --init left it)")
    parser.add_argument("--ema", type=float, default=0.0, metavar="DECAY",
                        help="save and export an exponential moving average of the weights with this decay "
                        "per step (0.999: about the last 1000 steps) instead of the last step's (0: off)")
    parser.add_argument("--input-hw", type=int, nargs=2, default=list(INPUT_HW), metavar=("H", "W"),
                        help="network input (height, width), multiples of 32: 128 160 is half scale, "
                        "256 320 full scale")
    parser.add_argument("--out", default="src/missiontree/data/models/sim_detector.onnx")
    train(parser.parse_args(argv))


if __name__ == "__main__":
    main()
