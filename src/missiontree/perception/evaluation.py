"""Detector scoring: average precision per class and mAP at an IoU threshold (PASCAL VOC style).

A detection is a true positive when it overlaps a not-yet-matched ground-truth box of its class
by at least the IoU threshold (best-scoring detections match first, each ground-truth box at most
once); otherwise it is a false positive, unless it overlaps a ground-truth box marked *ignored*
(too small or hidden to demand, VOC's "difficult"), when it counts neither way. AP is the area
under the precision-recall curve with precision made monotone (all-point interpolation, as VOC
2010+ computes it). mAP@0.5 averages AP over the classes that have ground truth.
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

import numpy as np

from missiontree.perception.detectors import iou_matrix
from missiontree.types import Detection


@dataclass(frozen=True, slots=True)
class GroundTruth:
    """One object really visible in an image: its class and box (x1, y1, x2, y2) in pixels.

    ``ignored`` marks an object too small or hidden to demand: missing it costs nothing, and a
    detection on it is not a false positive.
    """

    label: str
    box: tuple[float, float, float, float]
    ignored: bool = False


def average_precision(recall: np.ndarray, precision: np.ndarray) -> float:
    """Area under a precision-recall curve, precision made non-increasing (all-point interpolation).

    Args:
        recall: Recall after each detection, in score order (non-decreasing).
        precision: Precision after each detection, in the same order.
    """
    r = np.concatenate([[0.0], recall, [1.0]])
    p = np.concatenate([[0.0], precision, [0.0]])
    p = np.maximum.accumulate(p[::-1])[::-1]
    steps = np.nonzero(r[1:] != r[:-1])[0]
    return float(np.sum((r[steps + 1] - r[steps]) * p[steps + 1]))


@dataclass
class APAccumulator:
    """Collects detections and ground truth image by image, then scores them per class.

    Attributes:
        iou_threshold: Overlap a detection needs with a ground-truth box to count as found.
    """

    iou_threshold: float = 0.5
    _scored: dict[str, list[tuple[float, bool]]] = field(default_factory=lambda: defaultdict(list))
    _truth_count: dict[str, int] = field(default_factory=lambda: defaultdict(int))

    def add(self, detections: Sequence[Detection], truth: Iterable[GroundTruth]) -> None:
        """Score one image's detections against its ground truth."""
        truth_by_label: dict[str, list[GroundTruth]] = defaultdict(list)
        for t in truth:
            truth_by_label[t.label].append(t)
            if not t.ignored:
                self._truth_count[t.label] += 1
        dets_by_label: dict[str, list[Detection]] = defaultdict(list)
        for d in detections:
            dets_by_label[d.label].append(d)
        for label, dets in dets_by_label.items():
            dets = sorted(dets, key=lambda d: -d.score)
            gts = truth_by_label.get(label, [])
            if not gts:
                self._scored[label].extend((d.score, False) for d in dets)
                continue
            ious = iou_matrix(np.array([d.box for d in dets], float), np.array([g.box for g in gts], float))
            ignored = np.array([g.ignored for g in gts], dtype=bool)
            matched = np.zeros(len(gts), dtype=bool)
            for i, d in enumerate(dets):
                candidates = np.where(matched | ignored, -1.0, ious[i])
                j = int(candidates.argmax())
                if candidates[j] >= self.iou_threshold:
                    matched[j] = True
                    self._scored[label].append((d.score, True))
                elif not (ignored & (ious[i] >= self.iou_threshold)).any():
                    self._scored[label].append((d.score, False))

    def per_class(self) -> dict[str, float]:
        """AP of every class with ground truth (a class never present is left out)."""
        result: dict[str, float] = {}
        for label in sorted(self._truth_count):
            scored = sorted(self._scored.get(label, []), key=lambda s: -s[0])
            hits = np.array([h for _, h in scored], dtype=bool)
            if len(hits) == 0:
                result[label] = 0.0
                continue
            tp = np.cumsum(hits)
            fp = np.cumsum(~hits)
            recall = tp / self._truth_count[label]
            precision = tp / np.maximum(tp + fp, 1)
            result[label] = average_precision(recall, precision)
        return result

    def mean_ap(self) -> float:
        """Mean AP over the classes with ground truth; 0 when there is none."""
        aps = self.per_class()
        return float(np.mean(list(aps.values()))) if aps else 0.0

    def recall(self) -> float:
        """Share of the demanded ground-truth boxes, all classes together, that some detection found."""
        demanded = sum(self._truth_count.values())
        found = sum(hit for scored in self._scored.values() for _, hit in scored)
        return found / demanded if demanded else 0.0

    def truth_counts(self) -> dict[str, int]:
        """How many ground-truth boxes of each class were seen."""
        return dict(sorted(self._truth_count.items()))
