"""The builder keeps the places seen a few times but not confirmed: where a second look is due."""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "perception"))
from test_fusion import Rig, truth_detections  # noqa: E402

from missiontree.semantics.builder import BuilderParams, SceneBuilder  # noqa: E402


def feed(rig: Rig, builder: SceneBuilder, count: int) -> None:
    done, last = 0, -1.0
    while done < count:
        rig.robot.spin_until(rig.robot.now() + 0.1)
        frame = rig.robot.rgbd()
        if frame.stamp <= last:
            continue
        last = frame.stamp
        builder.add_frame(frame, truth_detections(rig.robot, frame))
        done += 1


def test_a_candidate_seen_briefly_is_doubtful_until_confirmed() -> None:
    """A few frames leave the object's place doubtful; enough frames confirm it and the doubt goes."""
    rig = Rig()
    try:
        builder = SceneBuilder(BuilderParams())
        feed(rig, builder, 3)
        t = rig.target
        assert not builder.scene.map.near(t.pose.x, t.pose.y, 0.5, label=t.label)
        doubtful = [(x, y) for label, x, y in builder.scene.doubtful if label == t.label]
        assert any(abs(x - t.pose.x) < 0.5 and abs(y - t.pose.y) < 0.5 for x, y in doubtful)
        feed(rig, builder, 20)
        assert builder.scene.map.near(t.pose.x, t.pose.y, 0.5, label=t.label)
        assert not [p for p in builder.scene.doubtful if p[0] == t.label and abs(p[1] - t.pose.x) < 0.5]
    finally:
        rig.robot.close()


def test_a_candidate_inside_a_known_instance_is_not_doubtful() -> None:
    """A box of another label inside a known object's footprint is that object named another way."""
    from types import SimpleNamespace

    builder = SceneBuilder(BuilderParams())
    builder.scene.map.add("laptop", (1.0, 1.0, 0.1), 0.0, size=(0.36, 0.36, 0.25))
    inside = SimpleNamespace(label="bottle", x=1.15, y=1.05, frames=6)
    beside = SimpleNamespace(label="bottle", x=1.6, y=1.0, frames=6)
    builder.fusion.unconfirmed = lambda min_frames=3: [inside, beside]  # type: ignore[method-assign]
    builder._note_doubtful()
    assert builder.scene.doubtful == [("bottle", 1.6, 1.0)]
