"""Fusion's evidence rules on hand-made frames: floor seen through a place, unexplained depth, cut boxes.

A camera 0.4 m above the floor looks along +x at a floor that runs to a wall 6 m away; the depth
image is computed exactly, so each rule is checked on its own.
"""

from __future__ import annotations

import numpy as np

from missiontree.perception.projection import Projection
from missiontree.semantics.fusion import FusionParams, InstanceFusion
from missiontree.semantics.semantic_map import SemanticMap
from missiontree.types import CameraIntrinsics, Detection, Pose2D, RGBDFrame

K = CameraIntrinsics(width=320, height=240, fx=228.5, fy=228.5, cx=159.5, cy=119.5)
CAMERA_HEIGHT = 0.4


def floor_depth() -> np.ndarray:
    """Depth of an empty room: floor below the horizon, a wall 6 m ahead above it."""
    rows = np.arange(K.height, dtype=float)[:, None] + 0.5
    below = rows - K.cy
    depth = np.where(below > 0, CAMERA_HEIGHT * K.fy / np.maximum(below, 1e-6), 6.0)
    return np.broadcast_to(np.minimum(depth, 6.0), (K.height, K.width)).astype(np.float32).copy()


def frame(stamp: float, depth: np.ndarray) -> RGBDFrame:
    colour = np.full((K.height, K.width, 3), 128, np.uint8)
    return RGBDFrame(stamp, colour, depth, K, Pose2D(0.0, 0.0, 0.0), CAMERA_HEIGHT)


def fusion_with_cup(**params: float) -> tuple[InstanceFusion, str]:
    smap = SemanticMap()
    fusion = InstanceFusion(smap, FusionParams(**params))  # type: ignore[arg-type]
    inst = smap.add("cup", (1.2, 0.0, 0.05), 0.0, size=(0.09, 0.09, 0.11), colour="red", observations=10)
    return fusion, inst.id


def test_a_floor_object_taken_away_is_seen_gone_though_the_floor_behind_it_is_near() -> None:
    """From 1.2 m the rays past a cup's place meet the floor within its far side: still, empty."""
    fusion, cup = fusion_with_cup(miss_frames=4)
    depth = floor_depth()
    for k in range(3):
        fusion.process(frame(1.0 + k, depth), [])
    assert cup in fusion.map and fusion.map.get(cup).doubtful  # type: ignore[union-attr]
    fusion.process(frame(5.0, depth), [])
    assert cup not in fusion.map
    assert fusion.params.miss_frames == 4


def test_something_else_at_the_place_removes_only_after_many_frames() -> None:
    """Depth shows an object where the cup was and no cup is detected: doubtful, removed only much later."""
    fusion, cup = fusion_with_cup(miss_frames=3, present_miss_frames=8, present_min_pixels=20)
    depth = floor_depth()
    u0, u1 = int(K.cx - 30), int(K.cx + 30)
    depth[int(K.cy) : K.height, u0:u1] = 1.2  # a box standing at the cup's place, taller than it
    for k in range(7):
        fusion.process(frame(1.0 + k, depth), [])
    inst = fusion.map.get(cup)
    assert inst is not None and inst.doubtful
    fusion.process(frame(9.0, depth), [])
    assert cup not in fusion.map
    removed = [c for c in fusion.map.drain_changes() if c.kind == "removed"]
    assert removed and "something else" in removed[0].reason


def test_views_too_small_for_the_detector_never_remove_what_stands_there() -> None:
    """The cup 21 px tall (1.2 m away), depth showing something at its place: no detection says nothing.

    Below ``present_min_pixels`` the detector misses a cup that is there; such views leave it doubtful
    but count nothing towards its removal. Closer (0.9 m, 28 px) the same views remove it.
    """
    fusion, cup = fusion_with_cup(miss_frames=3, present_miss_frames=8)
    depth = floor_depth()
    depth[int(K.cy) : K.height, int(K.cx - 30) : int(K.cx + 30)] = 1.2
    for k in range(40):
        fusion.process(frame(1.0 + k, depth), [])
    inst = fusion.map.get(cup)
    assert inst is not None and inst.doubtful
    near = InstanceFusion(SemanticMap(), FusionParams(present_miss_frames=8))
    close = near.map.add("cup", (0.9, 0.0, 0.05), 0.0, size=(0.09, 0.09, 0.11), colour="red", observations=10)
    depth = floor_depth()
    depth[int(K.cy) : K.height, int(K.cx - 40) : int(K.cx + 40)] = 0.9
    for k in range(9):
        near.process(frame(1.0 + k, depth), [])
    assert close.id not in near.map


def test_a_detection_resets_the_unexplained_count() -> None:
    """A cup detected now and then is not removed however many frames miss it in between."""
    fusion, cup = fusion_with_cup(miss_frames=3, present_miss_frames=5)
    depth = floor_depth()
    depth[int(K.cy) : K.height, int(K.cx - 30) : int(K.cx + 30)] = 1.2
    box = (K.cx - 12, K.cy + 60, K.cx + 12, K.cy + 85)
    for k in range(20):
        projections = []
        if k % 4 == 3:
            det = Detection("cup", 0.9, box)
            projections = [
                Projection(
                    "cup",
                    0.9,
                    box,
                    (1.2, 0.0, 0.05),
                    1.2,
                    1.2,
                    (0.09, 0.09, 0.11),
                    1.0 + k,
                    Pose2D(0, 0, 0),
                    det,
                )
            ]
        fusion.process(frame(1.0 + k, depth), projections)
    assert cup in fusion.map


def test_a_box_cut_by_the_image_border_does_not_move_the_instance() -> None:
    """Uncut views place the instance; views whose box touches the border count but do not move it."""
    smap = SemanticMap()
    fusion = InstanceFusion(smap, FusionParams(min_elevation=0.0, min_bounded_share=0))
    depth = floor_depth()

    def proj(stamp: float, box: tuple[float, float, float, float], x: float) -> Projection:
        det = Detection("sofa", 0.95, box)
        return Projection(
            "sofa", 0.95, box, (x, 0.0, 0.4), x, x, (1.8, 1.8, 0.8), stamp, Pose2D(0, 0, 0), det
        )

    for k in range(10):
        fusion.process(frame(1.0 + k, depth), [proj(1.0 + k, (60, 80, 260, 160), 3.0)])
    (inst,) = smap.by_label("sofa")
    assert abs(inst.position[0] - 3.0) < 1e-6
    for k in range(10):
        fusion.process(frame(20.0 + k, depth), [proj(20.0 + k, (0, 80, 150, 160), 3.4)])
    after = smap.get(inst.id)
    assert after is not None and abs(after.position[0] - 3.0) < 1e-6 and after.observations == 20


def cup_projection(stamp: float) -> Projection:
    box = (K.cx - 12, K.cy + 60, K.cx + 12, K.cy + 85)
    det = Detection("cup", 0.9, box)
    return Projection(
        "cup", 0.9, box, (1.2, 0.0, 0.05), 1.2, 1.2, (0.09, 0.09, 0.11), stamp, Pose2D(0, 0, 0), det
    )


def test_a_candidate_the_verifier_turns_down_does_not_become_an_instance() -> None:
    """Ten frames of a cup the verifier says is no cup: nothing added, the rejection counted."""
    asked: list[str] = []

    def verifier(frame: RGBDFrame, detection: Detection) -> bool | None:
        asked.append(detection.label)
        return False

    fusion = InstanceFusion(SemanticMap(), FusionParams(small_min_frames=10, min_bounded_share=0), verifier)
    for k in range(25):
        fusion.process(frame(1.0 + k, floor_depth()), [cup_projection(1.0 + k)])
    assert len(fusion.map) == 0 and fusion.rejected["cup"] == 2 and asked == ["cup", "cup"]


def test_a_verifier_that_agrees_or_cannot_tell_lets_the_candidate_in() -> None:
    for answer in (True, None):
        fusion = InstanceFusion(SemanticMap(), FusionParams(min_bounded_share=0), lambda f, d, a=answer: a)
        for k in range(10):
            fusion.process(frame(1.0 + k, floor_depth()), [cup_projection(1.0 + k)])
        assert [i.label for i in fusion.map] == ["cup"] and not fusion.rejected


def test_one_object_named_two_ways_is_kept_once_but_a_cup_on_a_table_is_not_merged() -> None:
    """A tv also seen as a table at the same place: the more often seen name stays; a cup on a table stays."""
    fusion = InstanceFusion(SemanticMap())
    add = fusion.map.add
    tv = add("tv", (2.0, 0.3, 0.3), 0.0, size=(1.1, 1.1, 0.6), colour="black", observations=40)
    table = add("table", (2.1, 0.35, 0.3), 0.0, size=(1.0, 1.0, 0.55), colour="black", observations=12)
    desk = add("table", (5.0, 5.0, 0.37), 0.0, size=(1.2, 1.2, 0.75), colour="brown", observations=30)
    cup = add("cup", (5.05, 5.0, 0.8), 0.0, size=(0.09, 0.09, 0.11), colour="red", observations=15)
    chair = add("chair", (5.0, 5.55, 0.45), 0.0, size=(0.5, 0.5, 0.9), colour="red", observations=5)
    same_desk = add("table", (5.2, 5.05, 0.37), 0.0, size=(1.2, 1.2, 0.75), colour="grey", observations=9)
    fusion.merge_overlapping(1.0)
    assert set(i.id for i in fusion.map) == {tv.id, desk.id, cup.id, chair.id}
    reasons = {c.id: c.reason for c in fusion.map.drain_changes() if c.kind == "removed"}
    assert "seen as a tv" in reasons[table.id] and same_desk.id in reasons
