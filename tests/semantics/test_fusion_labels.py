"""Class evidence over views: an instance the detector names a class its measured size rules out.

Hand-made observations: an instance confirmed as a "backpack" whose boxes also gave another class
some score, and the surface its views outlined (map cells, as several views of a depth camera
count them). The flat test frame adds no surface of its own near the instance (its depth is the
floor and a wall 6 m away).
"""

from __future__ import annotations

from collections import Counter

import numpy as np

from missiontree.perception.detectors import CLASS_SCORES
from missiontree.perception.footprint import footprint_sides, size_likelihood
from missiontree.perception.projection import Projection
from missiontree.semantics.fusion import FusionParams, InstanceFusion
from missiontree.semantics.semantic_map import SemanticMap
from missiontree.types import CameraIntrinsics, Detection, Pose2D, RGBDFrame

K = CameraIntrinsics(width=320, height=240, fx=228.5, fy=228.5, cx=159.5, cy=119.5)
CELL = 0.05
PLACE = (2.0, 0.0)


def frame(stamp: float) -> RGBDFrame:
    rows = np.arange(K.height, dtype=float)[:, None] + 0.5
    below = rows - K.cy
    depth = np.where(below > 0, 0.4 * K.fy / np.maximum(below, 1e-6), 6.0)
    depth = np.broadcast_to(np.minimum(depth, 6.0), (K.height, K.width)).astype(np.float32).copy()
    return RGBDFrame(stamp, np.full((K.height, K.width, 3), 128, np.uint8), depth, K, Pose2D(0, 0, 0), 0.4)


def outline(width: float, depth: float, views: int = 3) -> Counter[tuple[int, int]]:
    """Cells of a ``width`` x ``depth`` footprint's front and side faces, each seen ``views`` times."""
    x0, y0 = PLACE[0] - depth / 2, PLACE[1] - width / 2
    points = [(x0, y0 + t) for t in np.arange(0.0, width + 1e-6, CELL)]
    points += [(x0 + t, y0) for t in np.arange(0.0, depth + 1e-6, CELL)]
    cells: Counter[tuple[int, int]] = Counter()
    for x, y in points:
        cells[(int(np.floor(x / CELL)), int(np.floor(y / CELL)))] = views
    return cells


def projection(stamp: float, label: str, scores: dict[str, float]) -> Projection:
    box = (K.cx - 20, K.cy - 10, K.cx + 20, K.cy + 40)
    det = Detection(label, scores[label], box, attributes={CLASS_SCORES: scores})
    return Projection(
        label, scores[label], box, (*PLACE, 0.25), 1.8, 1.8, (0.45, 0.45, 0.5), stamp, Pose2D(0, 0, 0), det
    )


def seen_backpack(width: float, depth: float, evidence: dict[str, float]) -> tuple[InstanceFusion, str]:
    """A confirmed "backpack" at PLACE seen 12 times, with ``evidence`` and a width x depth outline."""
    smap = SemanticMap()
    fusion = InstanceFusion(smap, FusionParams(min_bounded_share=0))
    inst = smap.add("backpack", (*PLACE, 0.25), 0.0, size=(0.45, 0.45, 0.5), colour="grey", observations=12)
    track = fusion.track(inst.id)
    track.evidence.update(evidence)
    track.cells.update(outline(width, depth))
    track.sizes = [(0.45, 0.45, 0.5)] * 12
    track.xs = [(*PLACE, 0.25)] * 12
    return fusion, inst.id


BIN_SCORES = {"backpack": 0.8, "table": 0.05, "trash can": 0.02}


def test_a_backpack_deeper_than_any_takes_the_runner_up_that_fits() -> None:
    """0.35 m deep is no backpack: the runner-up with score mass that fits (a trash can) takes over."""
    fusion, old = seen_backpack(0.35, 0.35, {"backpack": 9.6, "table": 0.66, "trash can": 0.23})
    fusion.process(frame(1.0), [projection(1.0, "backpack", BIN_SCORES)])
    assert old not in fusion.map
    assert [i.label for i in fusion.map] == ["trash can"]
    (bin_,) = fusion.map.by_label("trash can")
    assert bin_.observations == 13 and bin_.colour == "grey"
    changes = fusion.map.drain_changes()
    assert any(c.kind == "removed" and "relabelled a trash can" in c.reason for c in changes)
    # later boxes still called "backpack" refine it: no new backpack candidate, no duplicate
    for k in range(2, 15):
        fusion.process(frame(float(k)), [projection(float(k), "backpack", BIN_SCORES)])
    assert [i.label for i in fusion.map] == ["trash can"]
    assert fusion.map.get(bin_.id).observations == 26  # type: ignore[union-attr]
    assert fusion.labels_of(bin_) == {"trash can", "backpack"}


def test_a_real_backpack_keeps_its_label() -> None:
    """A 0.32 x 0.2 footprint fits a backpack: its label stays whatever the runner-ups score."""
    fusion, old = seen_backpack(0.32, 0.2, {"backpack": 9.6, "table": 0.66, "trash can": 0.23})
    fusion.process(frame(1.0), [projection(1.0, "backpack", BIN_SCORES)])
    assert [i.id for i in fusion.map] == [old]


def test_no_runner_up_with_score_mass_keeps_the_label() -> None:
    """Too deep for a backpack, but no other class had real score mass: nothing to take over."""
    fusion, old = seen_backpack(0.35, 0.35, {"backpack": 9.6, "trash can": 0.02})
    fusion.process(frame(1.0), [projection(1.0, "backpack", {"backpack": 0.8})])
    assert [i.id for i in fusion.map] == [old]


def test_relabelling_can_be_turned_off() -> None:
    """``runner_up_share=0`` keeps the detector's label."""
    fusion, old = seen_backpack(0.35, 0.35, {"backpack": 9.6, "table": 0.66, "trash can": 0.23})
    fusion.params = FusionParams(min_bounded_share=0, runner_up_share=0)
    fusion.process(frame(1.0), [projection(1.0, "backpack", BIN_SCORES)])
    assert [i.id for i in fusion.map] == [old]


def test_one_face_seen_never_overstates_the_depth() -> None:
    """Only the front face outlined (a thin rectangle): the footprint's shorter side stays small."""
    cells = Counter({k: n for k, n in outline(0.35, 0.0).items()})
    sides = footprint_sides(cells, PLACE, 0.6, CELL)
    assert sides is not None and sides[1] < 0.06 and sides[0] >= 0.3


def test_size_likelihood_prefers_the_class_of_narrower_sizes() -> None:
    """A 0.35 m deep, 0.5 m high object: no backpack; a trash can explains it better than a table."""
    assert size_likelihood("backpack", 0.35, 0.5) == 0.0
    assert size_likelihood("backpack", 0.2, 0.45)
    bin_, table = size_likelihood("trash can", 0.35, 0.5), size_likelihood("table", 0.35, 0.5)
    assert bin_ and table and bin_ > 4 * table
    assert size_likelihood("sink", 0.35, 0.5) is None  # sizes not known: not judged


def test_an_early_runner_up_gives_way_to_one_that_explains_the_views_better() -> None:
    """A table, the only runner-up at first, becomes a trash can once the bin's own scores add up."""
    fusion, _ = seen_backpack(0.35, 0.35, {"backpack": 9.6, "table": 0.3, "trash can": 0.02})
    fusion.process(frame(1.0), [projection(1.0, "backpack", {"backpack": 0.8})])
    assert [i.label for i in fusion.map] == ["table"]
    scores = {"backpack": 0.8, "trash can": 0.1}
    for k in range(2, 5):
        fusion.process(frame(float(k)), [projection(float(k), "backpack", scores)])
    assert [i.label for i in fusion.map] == ["trash can"]
    (bin_,) = fusion.map.by_label("trash can")
    assert fusion.labels_of(bin_) == {"trash can", "table", "backpack"}


def test_a_large_instance_is_not_judged_by_its_surface_cells() -> None:
    """A tv's cells hold the cabinet beside it (1 m "deep"): a large instance keeps the detector's label."""
    smap = SemanticMap()
    fusion = InstanceFusion(smap, FusionParams(min_bounded_share=0))
    inst = smap.add("tv", (*PLACE, 0.3), 0.0, size=(1.1, 1.1, 0.6), colour="black", observations=12)
    track = fusion.track(inst.id)
    track.evidence.update({"tv": 9.6, "table": 0.7})
    track.cells.update(outline(1.0, 1.0))
    track.sizes = [(1.1, 1.1, 0.6)] * 12
    track.xs = [(*PLACE, 0.3)] * 12
    fusion.process(frame(1.0), [projection(1.0, "tv", {"tv": 0.8, "table": 0.05})])
    assert [i.id for i in fusion.map] == [inst.id]


def test_a_box_of_the_old_label_covering_a_relabelled_instance_is_no_miss() -> None:
    """The bin is still boxed as a "backpack" where depth places nothing: it was seen, not missed."""
    fusion, _ = seen_backpack(0.35, 0.35, {"backpack": 9.6, "table": 0.66, "trash can": 0.23})
    fusion.process(frame(1.0), [projection(1.0, "backpack", BIN_SCORES)])
    (bin_,) = fusion.map.by_label("trash can")
    box = projection(2.0, "backpack", BIN_SCORES).detection
    for k in range(2, 10):
        fusion.process(frame(float(k)), [], [box])
    kept = fusion.map.get(bin_.id)
    assert kept is not None and kept.misses == 0 and not kept.doubtful


def test_what_stands_behind_a_small_instance_does_not_deepen_its_footprint() -> None:
    """A cabinet face 0.42 m behind a backpack's centre is outside its footprint: still a backpack."""
    fusion, old = seen_backpack(0.32, 0.2, {"backpack": 9.6, "table": 0.66, "trash can": 0.23})
    row = int(np.floor((PLACE[0] + 0.42) / CELL))
    cabinet = {(row, int(np.floor(y / CELL))): 3 for y in np.arange(-0.3, 0.3, CELL)}
    fusion.track(old).cells.update(cabinet)
    fusion.process(frame(1.0), [projection(1.0, "backpack", BIN_SCORES)])
    assert [i.id for i in fusion.map] == [old]
