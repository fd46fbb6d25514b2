"""The YOLOv8/YOLO11 layout's geometry: letterboxing, class-wise NMS and decoding the raw output.

Pure numpy and OpenCV, no model runtime: what the Ultralytics runtime does around a model in the
standard export layout (one output ``[1, 4 + classes, N]``), used by
:class:`~missiontree.perception.detectors.YoloOnnxDetector` and by the tools that train and check it.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

#: Grey used for letterbox padding, as in Ultralytics' LetterBox.
PAD_VALUE = 114

#: Most candidates :func:`nms` compares all at once (an N x N matrix); more go box by box.
_NMS_MATRIX_MAX = 400


@dataclass(frozen=True, slots=True)
class Letterbox:
    """How an image was fitted into the model's input: ``input = image * scale + (pad_x, pad_y)``."""

    scale: float
    pad_x: float
    pad_y: float

    def to_image(self, boxes: np.ndarray, width: int, height: int) -> np.ndarray:
        """Map Nx4 xyxy boxes from input pixels back to image pixels, clipped to the image."""
        out = boxes.astype(np.float32, copy=True)
        out[:, [0, 2]] = (out[:, [0, 2]] - self.pad_x) / self.scale
        out[:, [1, 3]] = (out[:, [1, 3]] - self.pad_y) / self.scale
        out[:, [0, 2]] = out[:, [0, 2]].clip(0, width)
        out[:, [1, 3]] = out[:, [1, 3]].clip(0, height)
        return out


def letterbox(
    image: np.ndarray,
    height: int,
    width: int,
    *,
    interpolation: int | None = None,
    pad_value: float = PAD_VALUE,
) -> tuple[np.ndarray, Letterbox]:
    """Resize ``image`` to fit ``height`` x ``width`` keeping its aspect ratio; pad the rest with grey.

    The image is centred, as Ultralytics does for inference (half the padding on each side).
    ``interpolation`` and ``pad_value`` let a label image (an instance mask: nearest neighbour,
    padded with an id no object has) be fitted exactly as its colour image is.

    Returns:
        The padded ``height`` x ``width`` image (of ``image``'s channels and dtype) and the
        :class:`Letterbox` that undoes it.
    """
    h, w = image.shape[:2]
    scale = min(height / h, width / w)
    new_w, new_h = round(w * scale), round(h * scale)
    if (new_w, new_h) != (w, h):
        if interpolation is None:
            interpolation = cv2.INTER_AREA if scale < 1 else cv2.INTER_LINEAR
        image = cv2.resize(image, (new_w, new_h), interpolation=interpolation)
    pad_x, pad_y = (width - new_w) / 2.0, (height - new_h) / 2.0
    left, top = round(pad_x - 0.1), round(pad_y - 0.1)
    out = np.full((height, width, *image.shape[2:]), pad_value, dtype=image.dtype)
    out[top : top + new_h, left : left + new_w] = image
    return out, Letterbox(scale=scale, pad_x=float(left), pad_y=float(top))


def iou_matrix(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Intersection over union of every xyxy box in ``a`` (Nx4) with every box in ``b`` (Mx4)."""
    x1 = np.maximum(a[:, None, 0], b[None, :, 0])
    y1 = np.maximum(a[:, None, 1], b[None, :, 1])
    x2 = np.minimum(a[:, None, 2], b[None, :, 2])
    y2 = np.minimum(a[:, None, 3], b[None, :, 3])
    inter = (x2 - x1).clip(0) * (y2 - y1).clip(0)
    area_a = (a[:, 2] - a[:, 0]).clip(0) * (a[:, 3] - a[:, 1]).clip(0)
    area_b = (b[:, 2] - b[:, 0]).clip(0) * (b[:, 3] - b[:, 1]).clip(0)
    union = area_a[:, None] + area_b[None, :] - inter
    return np.where(union > 0, inter / np.maximum(union, 1e-9), 0.0)


def nms(boxes: np.ndarray, scores: np.ndarray, class_ids: np.ndarray, iou_threshold: float) -> np.ndarray:
    """Class-wise non-maximum suppression.

    A box is dropped when a higher-scoring box *of the same class* overlaps it by more than
    ``iou_threshold``; boxes of different classes never suppress each other.

    Args:
        boxes: Nx4 xyxy boxes.
        scores: N scores.
        class_ids: N integer class ids.
        iou_threshold: Overlap above which the weaker box goes.

    Returns:
        Indices of the kept boxes, best score first.
    """
    order = np.argsort(-scores, kind="stable")
    if len(order) == 0:
        return order
    # Shift each class into its own region of the plane, so one pass never mixes classes.
    offset = class_ids.astype(np.float32)[:, None] * (float(np.abs(boxes).max()) + 1.0) * 2.0
    shifted = boxes.astype(np.float32) + offset
    if len(order) <= _NMS_MATRIX_MAX:
        # Every pair's overlap at once (the same numbers box by box), then the greedy pass over it:
        # a frame's few tens of candidates cost one matrix, not one numpy round per kept box.
        ranked = shifted[order]
        suppresses = iou_matrix(ranked, ranked) > iou_threshold
        alive = np.ones(len(order), dtype=bool)
        kept: list[int] = []
        for i in range(len(order)):
            if alive[i]:
                kept.append(i)
                alive &= ~suppresses[i]
        return order[np.asarray(kept, dtype=np.int64)].astype(np.int64)
    keep: list[int] = []
    while len(order):
        best = order[0]
        keep.append(int(best))
        if len(order) == 1:
            break
        overlaps = iou_matrix(shifted[best : best + 1], shifted[order[1:]])[0]
        order = order[1:][overlaps <= iou_threshold]
    return np.asarray(keep, dtype=np.int64)


def decode_yolo(
    output: np.ndarray,
    num_classes: int,
    score_threshold: float,
    iou_threshold: float,
    max_detections: int,
    multi_label: bool = False,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Turn a raw ``[1, 4 + classes, N]`` output into kept boxes, scores and class ids.

    As :func:`decode_yolo_with_scores`, without the per-class score rows.
    """
    boxes, scores, class_ids, _ = decode_yolo_with_scores(
        output, num_classes, score_threshold, iou_threshold, max_detections, multi_label
    )
    return boxes, scores, class_ids


def decode_yolo_with_scores(
    output: np.ndarray,
    num_classes: int,
    score_threshold: float,
    iou_threshold: float,
    max_detections: int,
    multi_label: bool = False,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Turn a raw ``[1, 4 + classes, N]`` output into kept boxes, scores, class ids and score rows.

    Each candidate box is reported under its best class; with ``multi_label``, under every class
    scoring above ``score_threshold`` (as Ultralytics' ``non_max_suppression(multi_label=True)``
    decodes for ``val``), so that a box the model finds ambiguous (a white bookshelf seen end-on
    or a refrigerator) yields one detection per plausible class, each with its own score.

    The score rows are each kept box's whole score vector (K x classes): the model's evidence for
    every class, not only the one it is reported under (a grey bin the model calls a backpack may
    give "trash can" a real share); the fusion pools them over views.

    Returns:
        (boxes Kx4 xyxy in input pixels, scores K, class ids K, class scores KxC), best score first.
    """
    preds = output[0].T  # N x (4 + C)
    # Only candidates with a class above the threshold can be kept: the others are dropped first,
    # so the checks below read tens of rows, not thousands (a NaN score never passes).
    with np.errstate(invalid="ignore"):
        preds = preds[(preds[:, 4 : 4 + num_classes] > score_threshold).any(axis=1)]
    # A candidate with a non-finite number (a broken export, an fp16 overflow) is no candidate: NMS
    # on a NaN box would suppress or keep others at random.
    preds = preds[np.isfinite(preds[:, : 4 + num_classes]).all(axis=1)]
    class_scores = preds[:, 4 : 4 + num_classes]
    if multi_label:
        rows, class_ids = np.nonzero(class_scores > score_threshold)
        preds, scores = preds[rows], class_scores[rows, class_ids]
    else:
        class_ids = class_scores.argmax(axis=1)
        scores = class_scores[np.arange(len(preds)), class_ids]
        chosen = scores > score_threshold
        preds, class_ids, scores = preds[chosen], class_ids[chosen], scores[chosen]
    cx, cy, w, h = preds[:, 0], preds[:, 1], preds[:, 2], preds[:, 3]
    boxes = np.stack([cx - w / 2, cy - h / 2, cx + w / 2, cy + h / 2], axis=1)
    keep = nms(boxes, scores, class_ids, iou_threshold)[:max_detections]
    rows = preds[keep, 4 : 4 + num_classes].astype(np.float32)
    return boxes[keep], scores[keep].astype(np.float32), class_ids[keep], rows
