"""The fleet benchmark's idleness: the time since each waypoint's last visit, averaged and at its worst."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))

from fleet_eval import idleness  # noqa: E402


def test_idleness_is_measured_from_when_every_waypoint_was_first_visited() -> None:
    """A visited at 0, 10, 20; B at 5 and 15; end 20: window [5, 20], worst the 10 s gaps, average 5 s."""
    found = idleness({"A": [0.0, 10.0, 20.0], "B": [5.0, 15.0]}, ["A", "B"], 20.0)
    assert found is not None
    assert found["window_s"] == pytest.approx(15.0)
    assert found["worst"] == pytest.approx(10.0)
    # A: from 5 (idle 5) to 10 (idle 10), then 0..10 → (7.5*5 + 5*10)/15; B: 0..10 then 0..5
    a = (5 * 7.5 + 10 * 5) / 15
    b = (10 * 5 + 5 * 2.5) / 15
    assert found["avg"] == pytest.approx((a + b) / 2)


def test_a_waypoint_never_visited_gives_no_idleness() -> None:
    """Some waypoint never reached: None, not a number."""
    assert idleness({"A": [1.0]}, ["A", "B"], 10.0) is None


def test_the_open_wait_at_the_end_counts_for_the_worst() -> None:
    """Last visit at 2 s, run ends at 30 s: the worst idleness is 28 s."""
    found = idleness({"A": [1.0, 2.0]}, ["A"], 30.0)
    assert found is not None and found["worst"] == pytest.approx(28.0)
