"""The shipped simulator detector's network: a small anchor-free detector, widening, loading, export.

The network (about 0.5 M parameters at the shipped widths): a strided conv backbone with
depthwise-separable residual blocks to stride 32, a top-down feature pyramid, and a head per level
(strides 8, 16, 32) predicting class logits and a box (centre offset and log size per cell), with
optional *refiners* that re-score classes from where the box lies in the frame. :func:`export`
writes the YOLOv8/YOLO11 ONNX layout (one output ``[1, 4 + classes, N]``: box centre, width,
height in input pixels, then sigmoid class scores; class names in the metadata), so
:class:`missiontree.perception.detectors.YoloOnnxDetector` loads it like any Ultralytics export.
:func:`load_init` starts training from a run's ``.pt`` or from an exported ``.onnx`` (the shipped
model), widening narrower weights without changing what they compute (Net2Net).

Needs the ``train`` extra (``.venv/bin/pip install -e '.[train]'``, which pins the CPU torch).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import torch
from torch import nn
from torch.nn import functional as F  # noqa: N812 (the conventional name)

from tools.detector.data import CLASSES

#: Strides of the three output levels.
STRIDES = (8, 16, 32)


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
        "description": "missiontree simulator detector (tools/detector/train.py)",
        "training": training,
    }
    onnx.helper.set_model_props(proto, metadata)
    onnx.save(proto, str(out))
    print(f"wrote {out} ({out.stat().st_size / 1e6:.2f} MB)", flush=True)

