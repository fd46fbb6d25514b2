"""benchmarks/detector_quality.py: merged-label diagnostics count one object once; visibility kinds."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
import detector_quality  # noqa: E402

from missiontree.perception.evaluation import APAccumulator, GroundTruth
from missiontree.types import Detection


def test_look_alike_labels_of_one_object_merge_into_one_hit() -> None:
    found = [Detection(label="tv", score=0.8, box=(10, 10, 50, 40)),
             Detection(label="table", score=0.6, box=(11, 10, 50, 41)),
             Detection(label="cup", score=0.9, box=(100, 100, 110, 112))]
    truth = [GroundTruth("table", (10, 10, 50, 40)), GroundTruth("cup", (100, 100, 110, 112))]
    dets, gts = detector_quality.merged(found, truth, lambda k: detector_quality.LOOK_ALIKE.get(k, k), 0.45)
    # the tv box becomes the table's hit, and the table box, now its duplicate, is suppressed
    assert [(d.label, d.score) for d in dets] == [("cup", 0.9), ("table", 0.8)]
    assert [g.label for g in gts] == ["table", "cup"]
    scores = APAccumulator(0.5)
    scores.add(dets, gts)
    assert scores.mean_ap() == 1.0


def test_class_agnostic_merge_keeps_separate_objects() -> None:
    found = [Detection(label="chair", score=0.7, box=(0, 0, 20, 40)),
             Detection(label="sofa", score=0.5, box=(60, 0, 120, 30))]
    truth = [GroundTruth("sofa", (60, 0, 120, 30))]
    dets, gts = detector_quality.merged(found, truth, lambda _: "object", 0.45)
    assert len(dets) == 2 and {d.label for d in dets} == {"object"} and gts[0].label == "object"


def test_visibility_kinds_take_hidden_first_then_the_frame_edge_then_size() -> None:
    kept = np.array([[0, 100, 50, 200, 150],    # large, whole, but more than half hidden
                     [0, 0, 50, 60, 150],       # touches the left edge
                     [4, 150, 100, 170, 120],   # 20x20 px: small
                     [1, 100, 100, 150, 160],   # 50x60 px, whole and unhidden
                     [2, 200, 120, 320, 180]])  # touches the right edge (x2 is the frame's width)
    hidden = np.array([True, False, False, False, False])
    assert list(detector_quality.visibility_of(kept, hidden)) == [
        "more_than_half_hidden", "cut_by_frame_edge", "small", "whole_medium_or_large", "cut_by_frame_edge"]
