"""ViewGate: the scene graph's detector looks at new views, not at every frame of a still camera."""

from __future__ import annotations

from missiontree.semantics.view_gate import ViewGate
from missiontree.types import Pose2D


def test_without_rules_every_frame_passes() -> None:
    """With no period and no view rule, every frame is looked at."""
    gate = ViewGate()
    for k in range(5):
        assert gate.due(0.2 * k, Pose2D(0, 0, 0))
        gate.take(0.2 * k, Pose2D(0, 0, 0))


def test_the_period_caps_the_rate() -> None:
    """A frame sooner than ``period`` after the last one passed is skipped; one period later passes."""
    gate = ViewGate(period=0.4)
    gate.take(0.0, Pose2D(0, 0, 0))
    assert not gate.due(0.2, Pose2D(1, 0, 0))
    assert gate.due(0.4, Pose2D(1, 0, 0))


def test_a_still_camera_is_looked_at_only_every_still_period() -> None:
    """With a view rule, a frame from the same place and heading waits for ``still_period``."""
    gate = ViewGate(move=0.2, turn=10.0, still_period=1.0)
    gate.take(0.0, Pose2D(0, 0, 0))
    assert not gate.due(0.2, Pose2D(0.05, 0, 0.05))
    assert gate.due(1.0, Pose2D(0.05, 0, 0.05))


def test_moving_or_turning_enough_is_a_new_view() -> None:
    """Moving ``move`` metres or turning ``turn`` degrees (across the +-pi seam too) is a new view."""
    gate = ViewGate(move=0.2, turn=10.0)
    gate.take(0.0, Pose2D(0, 0, 3.1))
    assert gate.due(0.2, Pose2D(0.25, 0, 3.1))
    assert gate.due(0.2, Pose2D(0, 0, -3.0))  # 0.18 rad (10.4 degrees) the short way round
    assert not gate.due(0.2, Pose2D(0.1, 0, 3.05))
