"""An instance nearer than the depth camera measures is not judged absent from a frame without depth."""

from __future__ import annotations

import numpy as np

from missiontree.semantics.absence import NEAR_LIMIT
from missiontree.semantics.fusion import InstanceFusion
from missiontree.types import CameraIntrinsics, Pose2D, RGBDFrame

K = CameraIntrinsics(320, 240, 277.0, 277.0, 159.5, 119.5)


def blank_frame(stamp: float) -> RGBDFrame:
    """A frame whose depth image holds no return at all (NaN everywhere)."""
    return RGBDFrame(
        stamp=stamp,
        color=np.full((240, 320, 3), 120, dtype=np.uint8),
        depth=np.full((240, 320), np.nan, dtype=np.float32),
        intrinsics=K,
        camera_pose=Pose2D(0.0, 0.0, 0.0),
        camera_height=0.3,
    )


def judged_frames(distance: float, frames: int = 12) -> bool:
    """Whether a backpack ``distance`` m before the camera survives ``frames`` frames without depth."""
    fusion = InstanceFusion()
    inst = fusion.map.add("backpack", (distance, 0.0, 0.22), 0.0, size=(0.3, 0.3, 0.45), observations=20)
    for i in range(frames):
        fusion.absence.judge_unseen(blank_frame(1.0 + i), set(), [])
    return inst.id in fusion.map


def test_an_instance_too_close_for_depth_is_kept() -> None:
    # near face 0.15 m from the camera: the depth camera cannot see it, which is not "its place seen empty"
    assert 0.3 - 0.15 < NEAR_LIMIT
    assert judged_frames(0.3)


def test_an_instance_in_range_without_depth_is_still_removed() -> None:
    # 2 m away, no return at its place: nothing is there (seen empty), removed as before
    assert not judged_frames(2.0)


def test_the_near_limit_is_a_parameter() -> None:
    fusion = InstanceFusion()
    fusion.absence.near_limit = 0.0  # a camera that measures from 0 m: the old judgement
    inst = fusion.map.add("backpack", (0.3, 0.0, 0.22), 0.0, size=(0.3, 0.3, 0.45), observations=20)
    for i in range(12):
        fusion.absence.judge_unseen(blank_frame(1.0 + i), set(), [])
    assert inst.id not in fusion.map
