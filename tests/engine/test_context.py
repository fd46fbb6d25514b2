"""MissionContext: the run's markers stay bounded however long the run."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from missiontree.engine import context as context_module
from missiontree.engine.context import MissionContext


def _context(clock: list[float]) -> MissionContext:
    return MissionContext(robot=SimpleNamespace(now=lambda: clock[0]))  # type: ignore[arg-type]


def test_a_repeated_marker_is_kept_once_with_its_first_time() -> None:
    """A patrol's goal marked on every lap adds one marker per waypoint, not one per lap."""
    clock = [0.0]
    context = _context(clock)
    for lap in range(50):
        clock[0] = float(lap)
        for k in range(3):
            context.mark("goal", float(k), 1.0, f"P{k}")
    assert [(m.label, m.stamp) for m in context.markers] == [("P0", 0.0), ("P1", 0.0), ("P2", 0.0)]
    context.mark("alarm", 0.0, 1.0, "P0")  # another kind at the same spot is a new marker
    context.mark("goal", 0.5, 1.0, "P0")  # the same label elsewhere too
    assert len(context.markers) == 5
    assert context.markers_dropped == 0


def test_markers_are_bounded_oldest_dropped_first(monkeypatch: pytest.MonkeyPatch) -> None:
    """One alarm per encounter for hours: the list stops at MAX_MARKERS, the newest kept."""
    monkeypatch.setattr(context_module, "MAX_MARKERS", 10)
    clock = [0.0]
    context = _context(clock)
    for k in range(25):
        clock[0] = float(k)
        context.mark("alarm", float(k), 0.0, f"alarm {k}")
    assert len(context.markers) == 10
    assert [m.label for m in context.markers] == [f"alarm {k}" for k in range(15, 25)]
    assert context.markers_dropped == 15
    context.mark("alarm", 3.0, 0.0, "alarm 3")  # a dropped marker may come back
    assert context.markers[-1].label == "alarm 3" and len(context.markers) == 10


def test_the_real_bound_holds_for_a_long_run() -> None:
    clock = [0.0]
    context = _context(clock)
    for k in range(context_module.MAX_MARKERS + 500):
        context.mark("alarm", k * 0.1, 0.0, f"alarm {k}")
    assert len(context.markers) == context_module.MAX_MARKERS
    assert context.markers_dropped == 500
