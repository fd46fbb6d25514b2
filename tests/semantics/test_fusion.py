"""Fusion keeps the semantic map true: an object taken away is removed, one moved is moved, not doubled.

The detector is stood in for by the simulator's instance mask (boxes of what each frame shows), so
these tests are about fusion, not detection; the world is changed by the scene-graph benchmark's
own helpers, as its dynamic phase does.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

from missiontree.backends.sim import create_robot
from missiontree.perception.projection import project
from missiontree.semantics.fusion import FusionParams, InstanceFusion
from missiontree.semantics.semantic_map import SemanticMap
from missiontree.types import Detection

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
import scene_graph_eval  # noqa: E402

SMALL = {"chair", "bottle", "cup", "backpack", "umbrella", "trash can", "potted plant", "laptop"}


def truth_detections(robot, frame) -> list[Detection]:
    """Boxes of the objects wholly in the frame, from the instance mask (the detector's stand-in)."""
    mask = robot.truth.instance_mask(frame.stamp)
    out = []
    for inst, info in robot.truth.instances.items():
        if info.kind != "object":
            continue
        rows, cols = np.nonzero(mask == inst)
        if len(rows) >= 120 and cols.min() > 1 and cols.max() < mask.shape[1] - 2:
            out.append(
                Detection(
                    info.label,
                    0.9,
                    (float(cols.min()), float(rows.min()), float(cols.max() + 1), float(rows.max() + 1)),
                    attributes={"name": info.name},
                )
            )
    return out


class Rig:
    """A robot turned to face a small object, and a fusion fed with its frames."""

    def __init__(self) -> None:
        self.robot = create_robot({"world": "office", "seed": 2})
        self.smap = SemanticMap()
        self.fusion = InstanceFusion(self.smap, FusionParams(miss_frames=5, small_min_frames=10))
        self.robot.spin_until(0.5)
        self.target = None
        for _ in range(40):  # turn in small steps until a small object is wholly in view
            frame = self.robot.rgbd()
            pose = self.robot.pose().pose
            found = [
                d
                for d in truth_detections(self.robot, frame)
                if d.label in SMALL
                and pose.distance_to(self.robot.truth.object(d.attributes["name"]).pose) < 3.5
            ]
            if found:
                self.target = self.robot.truth.object(found[0].attributes["name"])
                break
            self.robot.drive(0.0, 0.8)
            self.robot.spin_until(self.robot.now() + 0.25)
            self.robot.stop()
            self.robot.spin_until(self.robot.now() + 0.3)
        assert self.target is not None, "no small object came into view"

    def frames(self, count: int, detect: bool = True) -> None:
        done = 0
        while done < count:
            self.robot.spin_until(self.robot.now() + 0.1)
            frame = self.robot.rgbd()
            if frame.stamp <= self.fusion.last_stamp:
                continue
            detections = truth_detections(self.robot, frame) if detect else []
            projections = [p for p in (project(frame, d) for d in detections) if p is not None]
            self.fusion.process(frame, projections, detections)
            done += 1

    def instance_near(self, x: float, y: float, label: str):
        found = self.smap.near(x, y, 0.5, label=label)
        return found[0] if found else None

    def elsewhere_in_view(self) -> tuple[float, float]:
        """A free point beside the target, still in the camera's view."""
        pose = self.robot.pose().pose
        t = self.target
        bearing = math.atan2(t.pose.y - pose.y, t.pose.x - pose.x)
        for shift in (0.8, 1.0, 0.6):
            for side in (1.0, -1.0):
                x = t.pose.x + side * shift * -math.sin(bearing)
                y = t.pose.y + side * shift * math.cos(bearing)
                off = abs(math.remainder(math.atan2(y - pose.y, x - pose.x) - pose.yaw, 2 * math.pi))
                clear = all(
                    math.hypot(x - o.pose.x, y - o.pose.y) > 0.4
                    for o in self.robot.world.objects
                    if o is not t
                )
                if off < math.radians(25) and self.robot.world.clearance(x, y) > 0.2 and clear:
                    return x, y
        pytest.skip("no free spot beside the object in view")


@pytest.fixture
def rig():
    r = Rig()
    yield r
    r.robot.close()


def test_an_object_seen_ten_times_is_added(rig: Rig) -> None:
    """Nine frames are not enough (the NAIS voting), the tenth adds it, with its colour measured."""
    rig.frames(9)
    assert rig.instance_near(rig.target.pose.x, rig.target.pose.y, rig.target.label) is None
    rig.frames(2)
    inst = rig.instance_near(rig.target.pose.x, rig.target.pose.y, rig.target.label)
    assert inst is not None and inst.observations >= 10
    assert [c.kind for c in rig.smap.drain_changes()].count("added") >= 1


def test_an_undetected_object_still_there_is_doubted_not_removed(rig: Rig) -> None:
    """Frames with no detection while depth still shows the object: doubtful, lower confidence, kept."""
    rig.frames(12)
    inst = rig.instance_near(rig.target.pose.x, rig.target.pose.y, rig.target.label)
    before = inst.confidence
    rig.frames(10, detect=False)
    assert inst.id in rig.smap and inst.doubtful and inst.confidence < before


def test_an_object_taken_away_is_removed(rig: Rig) -> None:
    """Once its place is seen empty in miss_frames frames, the instance is removed with the reason."""
    rig.frames(12)
    inst = rig.instance_near(rig.target.pose.x, rig.target.pose.y, rig.target.label)
    rig.smap.drain_changes()
    scene_graph_eval.remove_object(rig.robot.world, rig.target.id)
    rig.frames(8)
    assert inst.id not in rig.smap
    removed = [c for c in rig.smap.drain_changes() if c.kind == "removed"]
    assert [c.id for c in removed] == [inst.id] and "seen empty" in removed[0].reason


def test_an_object_moved_in_view_is_moved_not_duplicated(rig: Rig) -> None:
    """Its old place seen empty and the same label and colour seen nearby: one instance, one moved change."""
    rig.frames(12)
    inst = rig.instance_near(rig.target.pose.x, rig.target.pose.y, rig.target.label)
    rig.smap.drain_changes()
    x, y = rig.elsewhere_in_view()
    scene_graph_eval.move_object(rig.robot.world, rig.target.id, x, y)
    rig.frames(20)
    assert len(rig.smap.by_label(rig.target.label)) == len(
        [
            o
            for o in rig.robot.world.objects
            if o.label == rig.target.label and rig.smap.near(o.pose.x, o.pose.y, 0.5)
        ]
    )
    moved = rig.smap.get(inst.id)
    assert moved is not None and moved.distance_to(x, y) < 0.5
    kinds = [c.kind for c in rig.smap.drain_changes() if c.id == inst.id]
    assert "moved" in kinds and "removed" not in kinds
