"""The search benchmark's why: phases from the tick log, and the cause of a miss from the true trace."""

from __future__ import annotations

import json
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from missiontree.types import OccupancyGrid, Pose2D

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
from search_why import diagnose, phases  # noqa: E402


def _world(wall_at_x: float | None = None) -> SimpleNamespace:
    """A 10 x 4 m free floor at 5 cm, with a full-height wall across at ``wall_at_x`` when given."""
    data = np.zeros((80, 200), np.int8)
    if wall_at_x is not None:
        data[:, int(wall_at_x / 0.05)] = 100
    return SimpleNamespace(grid=OccupancyGrid(0.0, 0.05, Pose2D(0.0, 0.0), data))


TARGET = SimpleNamespace(pose=Pose2D(6.0, 2.0))


def _line(**event: object) -> str:
    return json.dumps(event)


def test_phases_count_each_leafs_running_time_and_what_locate_was_doing() -> None:
    """Locate running 0-10 s (6 s to a frontier, 4 s looking), approach 10-14 s."""
    log = "\n".join([
        _line(event="tick", t=0.0, changed=[{"node": "a/locate", "status": "RUNNING"}]),
        _line(event="explore_goal", t=0.0, kind="frontier"),
        _line(event="explore_reached", t=6.0),
        _line(event="tick", t=10.0, changed=[{"node": "a/locate", "status": "SUCCESS"},
                                            {"node": "a/approach", "status": "RUNNING"}]),
        _line(event="tick", t=14.0, changed=[{"node": "a/approach", "status": "SUCCESS"}]),
    ])
    got = phases(log)
    assert got["locate"] == 10.0 and got["approach"] == 4.0
    assert got["locate:to frontier"] == 6.0 and got["locate:looking"] == 4.0


def test_a_target_never_faced_within_range_is_never_in_view() -> None:
    """The robot drove past 5 m away, or facing away: the cause is 'never in view'."""
    trace = [[t, 1.0, 2.0, 3.14] for t in range(10)]  # 5 m away, facing away
    why = diagnose(trace, _world(), TARGET, [], found=False)
    assert why["cause"] == "never in view" and why["in_view_s"] is None


def test_a_wall_between_keeps_the_target_out_of_view() -> None:
    """Facing it 3 m away through a wall is not in view; without the wall it is, then no candidate."""
    trace = [[0.0, 3.0, 2.0, 0.0]]
    assert diagnose(trace, _world(wall_at_x=4.5), TARGET, [], found=False)["cause"] == "never in view"
    why = diagnose(trace, _world(), TARGET, [], found=False)
    assert why["cause"] == "in view, never a candidate" and why["in_view_s"] == 0.0


def test_a_candidate_of_the_target_rejected_is_named_with_its_kind() -> None:
    """A candidate 0.3 m from the target, then rejected as unreached: the cause says so."""
    events = [
        {"event": "search_candidate", "t": 5.0, "id": "b1", "x": 6.2, "y": 2.2},
        {"event": "candidate_rejected", "t": 9.0, "object": "b1", "x": 6.2, "y": 2.2, "kind": "unreached",
         "reason": "no pose reached"},
    ]
    why = diagnose([[0.0, 3.0, 2.0, 0.0]], _world(), TARGET, events, found=False)
    assert why["cause"] == "candidate rejected: unreached" and why["candidate_s"] == 5.0
