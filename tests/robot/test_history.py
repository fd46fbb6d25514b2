"""The stamped history's span: the stamps it holds, oldest and newest."""

from __future__ import annotations

from missiontree.robot.history import StampedHistory


def test_span_is_none_when_empty_then_the_oldest_and_newest_stamps_held() -> None:
    """span() follows what the horizon keeps, so a caller never reads the private deque."""
    history: StampedHistory[str] = StampedHistory(horizon=1.0)
    assert history.span() is None
    for stamp in (0.0, 0.5, 1.2, 1.8):
        history.push(stamp, f"scan at {stamp}")
    assert history.span() == (1.2, 1.8)  # 0.0 and 0.5 fell out of the 1 s horizon
