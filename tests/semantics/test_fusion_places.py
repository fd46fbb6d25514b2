"""Fusion rules that weigh where boxes were seen from: views from two places, two neighbours in one box.

Same hand-made frames as ``test_fusion_views``: a camera 0.4 m above the floor, an exact depth image.
"""

from __future__ import annotations

import numpy as np

from missiontree.perception.projection import Projection
from missiontree.semantics.fusion import FusionParams, InstanceFusion
from missiontree.semantics.fusion_state import Track
from missiontree.semantics.semantic_map import SemanticMap
from missiontree.types import CameraIntrinsics, Detection, Pose2D, RGBDFrame

K = CameraIntrinsics(width=320, height=240, fx=228.5, fy=228.5, cx=159.5, cy=119.5)
CAMERA_HEIGHT = 0.4


def room_depth(face: float | None = None) -> np.ndarray:
    """Floor below the horizon, a wall 6 m ahead; with ``face``, a 1 m wide flat face at that depth."""
    rows = np.arange(K.height, dtype=float)[:, None] + 0.5
    below = rows - K.cy
    depth = np.where(below > 0, CAMERA_HEIGHT * K.fy / np.maximum(below, 1e-6), 6.0)
    depth = np.broadcast_to(np.minimum(depth, 6.0), (K.height, K.width)).astype(np.float32).copy()
    if face is not None:
        lateral = (K.cx - (np.arange(K.width, dtype=float) + 0.5)) * face / K.fx
        height = CAMERA_HEIGHT - (rows - K.cy) * face / K.fy
        on = (height >= 0.0) & (height <= 0.8)
        depth[np.ix_(on[:, 0], np.abs(lateral) <= 0.5)] = face
    return depth


def frame(stamp: float, depth: np.ndarray) -> RGBDFrame:
    """A grey frame from the origin looking along +x."""
    colour = np.full((K.height, K.width, 3), 128, np.uint8)
    return RGBDFrame(stamp, colour, depth, K, Pose2D(0.0, 0.0, 0.0), CAMERA_HEIGHT)

PLANT = (0.45, 0.45, 0.9)


def plant(stamp: float, camera_y: float, y: float = 0.0) -> Projection:
    """A potted plant 3.4 m ahead, placed at (3.4, ``y``), boxed whole from a camera at (0, ``camera_y``)."""
    box = (K.cx - 15, 80.0, K.cx + 15, 150.0)
    det = Detection("potted plant", 0.9, box)
    return Projection(
        "potted plant", 0.9, box, (3.4, y, 0.45), 3.4, 3.4, PLANT, stamp, Pose2D(0.0, camera_y, 0.0), det
    )


def test_views_from_two_places_that_agree_confirm_in_fewer_frames() -> None:
    """Five frames from two places 0.6 m apart placing one spot confirm a plant: 10 are not needed."""
    fusion = InstanceFusion(SemanticMap(), FusionParams(min_bounded_share=0))
    for k, cam in enumerate((0.0, 0.0, 0.0, 0.6, 0.6)):
        fusion.process(frame(1.0 + k, room_depth()), [plant(1.0 + k, cam)])
    assert [i.label for i in fusion.map] == ["potted plant"]


def test_frames_from_one_place_still_need_min_frames() -> None:
    """Nine frames from one place leave the plant a candidate: one place's frames repeat one view."""
    fusion = InstanceFusion(SemanticMap(), FusionParams(min_bounded_share=0))
    for k in range(9):
        fusion.process(frame(1.0 + k, room_depth()), [plant(1.0 + k, 0.0)])
    assert len(fusion.map) == 0 and fusion.voting.candidates[0].frames == 9


def test_two_places_that_disagree_do_not_shorten_the_wait() -> None:
    """Views from two places that scatter the plant over 0.3 m (depth on others) still need 10 frames."""
    fusion = InstanceFusion(SemanticMap(), FusionParams(min_bounded_share=0))
    for k, (cam, y) in enumerate(((0.0, 0.0), (0.6, 0.3), (0.0, 0.15), (0.6, 0.0), (0.0, 0.3), (0.6, 0.15))):
        fusion.process(frame(1.0 + k, room_depth()), [plant(1.0 + k, cam, y)])
    assert len(fusion.map) == 0


def test_a_box_round_two_small_neighbours_does_not_merge_them() -> None:
    """Two 0.45 m plants 0.84 m apart, one wide box holding both centres: both stay."""
    smap = SemanticMap()
    fusion = InstanceFusion(smap)
    ids = []
    for y in (-0.42, 0.42):
        inst = smap.add("potted plant", (3.0, y, 0.45), 0.0, size=PLANT, colour="green", observations=20)
        fusion.tracks[inst.id] = Track(sizes=[PLANT] * 10, xs=[(3.0, y, 0.45)] * 10)
        ids.append(inst.id)
    box = (K.cx - 70, 80.0, K.cx + 70, 170.0)
    det = Detection("potted plant", 0.9, box)
    wide = Projection(
        "potted plant", 0.9, box, (3.0, 0.0, 0.45), 2.8, 2.8, (1.2, 1.2, 0.9), 1.0, Pose2D(0, 0, 0), det
    )
    fusion.process(frame(1.0, room_depth(2.8)), [wide])
    assert sorted(i.id for i in smap) == sorted(ids)


def test_apart_rule_off_merges_them_as_before() -> None:
    """With ``apart_share`` None the same box merges the two plants (the rule is what keeps them apart)."""
    smap = SemanticMap()
    fusion = InstanceFusion(smap, FusionParams(apart_share=None))
    for y in (-0.42, 0.42):
        inst = smap.add("potted plant", (3.0, y, 0.45), 0.0, size=PLANT, colour="green", observations=20)
        fusion.tracks[inst.id] = Track(sizes=[PLANT] * 10, xs=[(3.0, y, 0.45)] * 10)
    box = (K.cx - 70, 80.0, K.cx + 70, 170.0)
    det = Detection("potted plant", 0.9, box)
    wide = Projection(
        "potted plant", 0.9, box, (3.0, 0.0, 0.45), 2.8, 2.8, (1.2, 1.2, 0.9), 1.0, Pose2D(0, 0, 0), det
    )
    fusion.process(frame(1.0, room_depth(2.8)), [wide])
    assert len(smap) == 1
