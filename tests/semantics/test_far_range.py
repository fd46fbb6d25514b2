"""Objects seen only from 5-6 m (across a large room) reach the graph, and are not removed from afar."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import yaml

from missiontree.perception.projection import project
from missiontree.perception.tracking import NaisFilterParams
from missiontree.semantics.fusion import FusionParams, InstanceFusion
from missiontree.types import CameraIntrinsics, Detection, Pose2D, RGBDFrame

K = CameraIntrinsics(320, 240, 277.0, 277.0, 159.5, 119.5)
TREE = Path(__file__).resolve().parents[2] / "trees" / "map_scene.yaml"
#: A 0.5 m wide, 0.9 m high chair 5.5 m ahead of a camera 0.4 m high, on the image (pixels).
CHAIR_BOX = (147.0, 94.0, 172.0, 140.0)


def chair_frame(stamp: float, shown: bool = True) -> RGBDFrame:
    """A frame of a room 9 m deep; with ``shown``, a chair 5.5 m ahead in the middle of the image."""
    depth = np.full((240, 320), 9.0, dtype=np.float32)
    if shown:
        x1, y1, x2, y2 = (int(v) for v in CHAIR_BOX)
        depth[y1:y2, x1:x2] = 5.5
    return RGBDFrame(
        stamp=stamp,
        color=np.full((240, 320, 3), 120, dtype=np.uint8),
        depth=depth,
        intrinsics=K,
        camera_pose=Pose2D(0.0, 0.0, 0.0),
        camera_height=0.4,
    )


def tree_max_range() -> float:
    """``max_range`` the shipped map_scene tree gives its BuildSceneGraph leaf."""
    root = yaml.safe_load(TREE.read_text())["root"]
    for child in root["Parallel"]["children"]:
        if "BuildSceneGraph" in child:
            return float(child["BuildSceneGraph"].get("max_range", 4.5))
    raise AssertionError("no BuildSceneGraph in the tree")


def fuse_far_chair(max_range: float, frames: int = 12) -> InstanceFusion:
    """A fusion with ``max_range`` fed ``frames`` frames of the chair 5.5 m away."""
    fusion = InstanceFusion(params=FusionParams(filters=NaisFilterParams(max_range=max_range)))
    for i in range(frames):
        frame = chair_frame(1.0 + 0.2 * i)
        p = project(frame, Detection("chair", 0.9, CHAIR_BOX))
        assert p is not None
        fusion.process(frame, [p])
    return fusion


def test_the_shipped_tree_places_a_chair_seen_only_from_five_and_a_half_metres() -> None:
    """With the tree's range a chair seen only from 5.5 m is confirmed; with the paper's 4.5 m it is not."""
    assert [i.label for i in fuse_far_chair(tree_max_range()).map] == ["chair"]
    assert list(fuse_far_chair(4.5).map) == []


def test_a_far_instance_is_not_judged_absent_beyond_the_expected_range() -> None:
    """Frames without the far chair do not remove it: misses count only within ``expect_range``."""
    fusion = fuse_far_chair(6.0)
    for i in range(20):
        fusion.process(chair_frame(10.0 + 0.2 * i, shown=False), [])
    assert [i.label for i in fusion.map] == ["chair"]
