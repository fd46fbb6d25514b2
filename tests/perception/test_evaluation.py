from __future__ import annotations

import numpy as np
import pytest

from missiontree.perception.evaluation import APAccumulator, GroundTruth, average_precision
from missiontree.types import Detection


def _det(label: str, score: float, box: tuple[float, float, float, float]) -> Detection:
    return Detection(label=label, score=score, box=box)


def test_perfect_detections_score_one() -> None:
    """Every object found exactly, nothing else: AP 1 for each class."""
    acc = APAccumulator()
    acc.add([_det("cup", 0.9, (0, 0, 10, 10)), _det("person", 0.8, (20, 20, 40, 60))],
            [GroundTruth("cup", (0, 0, 10, 10)), GroundTruth("person", (20, 20, 40, 60))])
    assert acc.per_class() == {"cup": 1.0, "person": 1.0}
    assert acc.mean_ap() == 1.0


def test_missed_object_halves_recall_and_ap() -> None:
    """Finding one of two cups with no false positive gives AP 0.5."""
    acc = APAccumulator()
    acc.add([_det("cup", 0.9, (0, 0, 10, 10))],
            [GroundTruth("cup", (0, 0, 10, 10)), GroundTruth("cup", (50, 50, 60, 60))])
    assert acc.per_class()["cup"] == pytest.approx(0.5)


def test_recall_counts_found_objects_over_every_class_and_skips_ignored_ones() -> None:
    """Two of four demanded objects found (a wrong box and an ignored object aside): recall 0.5."""
    acc = APAccumulator()
    acc.add([_det("cup", 0.9, (0, 0, 10, 10)), _det("person", 0.3, (20, 20, 40, 60)),
             _det("person", 0.8, (200, 200, 220, 240)), _det("chair", 0.7, (70, 70, 90, 90))],
            [GroundTruth("cup", (0, 0, 10, 10)), GroundTruth("cup", (50, 50, 60, 60)),
             GroundTruth("person", (20, 20, 40, 60)), GroundTruth("chair", (100, 0, 130, 40)),
             GroundTruth("chair", (70, 70, 90, 90), ignored=True)])
    assert acc.recall() == pytest.approx(0.5)
    assert APAccumulator().recall() == 0.0


def test_false_positive_ranked_first_costs_precision() -> None:
    """A wrong box scored above the right one: precision 1/2 at full recall, AP 0.5."""
    acc = APAccumulator()
    acc.add([_det("cup", 0.9, (100, 100, 110, 110)), _det("cup", 0.5, (0, 0, 10, 10))],
            [GroundTruth("cup", (0, 0, 10, 10))])
    assert acc.per_class()["cup"] == pytest.approx(0.5)


def test_false_positive_ranked_last_costs_nothing() -> None:
    """A wrong box scored below every right one leaves AP at 1 (it comes after full recall)."""
    acc = APAccumulator()
    acc.add([_det("cup", 0.9, (0, 0, 10, 10)), _det("cup", 0.1, (100, 100, 110, 110))],
            [GroundTruth("cup", (0, 0, 10, 10))])
    assert acc.per_class()["cup"] == 1.0


def test_duplicate_detection_of_one_object_is_a_false_positive() -> None:
    """Each ground-truth box matches once; a second box on it counts as false."""
    acc = APAccumulator()
    acc.add([_det("cup", 0.9, (0, 0, 10, 10)), _det("cup", 0.8, (0, 0, 10, 9)),
             _det("cup", 0.7, (50, 50, 60, 60))],
            [GroundTruth("cup", (0, 0, 10, 10)), GroundTruth("cup", (50, 50, 60, 60))])
    # ranks: TP (r .5, p 1), FP (r .5, p .5), TP (r 1, p 2/3) -> 0.5 * 1 + 0.5 * 2/3
    assert acc.per_class()["cup"] == pytest.approx(0.5 + 1 / 3)


def test_box_below_the_iou_threshold_does_not_count() -> None:
    """A box overlapping the object by IoU 1/3 misses at 0.5 and hits at 0.3."""
    dets = [_det("cup", 0.9, (5, 0, 15, 10))]
    truth = [GroundTruth("cup", (0, 0, 10, 10))]
    strict, loose = APAccumulator(0.5), APAccumulator(0.3)
    strict.add(dets, truth)
    loose.add(dets, truth)
    assert strict.per_class()["cup"] == 0.0
    assert loose.per_class()["cup"] == 1.0


def test_wrong_label_is_a_miss_and_a_false_positive() -> None:
    """A right box with the wrong class finds nothing; a class without ground truth is not averaged."""
    acc = APAccumulator()
    acc.add([_det("bottle", 0.9, (0, 0, 10, 10))], [GroundTruth("cup", (0, 0, 10, 10))])
    assert acc.per_class() == {"cup": 0.0}
    assert acc.mean_ap() == 0.0


def test_images_are_matched_separately() -> None:
    """A detection in one image never matches ground truth of another."""
    acc = APAccumulator()
    acc.add([], [GroundTruth("cup", (0, 0, 10, 10))])
    acc.add([_det("cup", 0.9, (0, 0, 10, 10))], [])
    assert acc.per_class()["cup"] == 0.0
    assert acc.truth_counts() == {"cup": 1}


def test_average_precision_of_a_known_curve() -> None:
    """The interpolated area of a hand-made curve: precision 1 to recall 0.4, 0.5 to recall 0.8."""
    recall = np.array([0.2, 0.4, 0.4, 0.6, 0.8])
    precision = np.array([1.0, 1.0, 2 / 3, 0.5, 0.5])
    assert average_precision(recall, precision) == pytest.approx(0.4 * 1.0 + 0.4 * 0.5)


def test_detection_on_an_ignored_object_counts_neither_way() -> None:
    """A box on an ignored (too small) object is no false positive, and missing it is no miss."""
    acc = APAccumulator()
    acc.add([_det("cup", 0.9, (50, 50, 54, 54)), _det("cup", 0.5, (0, 0, 10, 10))],
            [GroundTruth("cup", (0, 0, 10, 10)), GroundTruth("cup", (50, 50, 54, 54), ignored=True),
             GroundTruth("cup", (80, 80, 83, 83), ignored=True)])
    assert acc.per_class()["cup"] == 1.0
    assert acc.truth_counts() == {"cup": 1}
