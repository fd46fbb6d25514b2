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


def test_coverage_counts_the_reachable_cells_a_map_reads_free() -> None:
    """Half the reachable cells read free, the rest unknown: coverage 0.5."""
    import numpy as np
    from fleet_explore_search import coverage

    from missiontree.types import OccupancyGrid, Pose2D

    cells = (np.array([0.5, 1.5, 2.5, 3.5]), np.array([0.5, 0.5, 0.5, 0.5]))
    grid = OccupancyGrid(0.0, 1.0, Pose2D(0.0, 0.0, 0.0), np.array([[0, 0, -1, 100]], np.int8))
    assert coverage(cells, grid) == pytest.approx(0.5)


def test_the_two_to_one_ratio_is_taken_per_world_where_both_reached_90() -> None:
    """Ratios 0.5 and 0.7 from two worlds; a world one robot never covered gives none."""
    from fleet_explore_search import explore_summary

    rows = [{"runs": {1: {"t90_s": 100.0, "status": "SUCCESS"}, 2: {"t90_s": 50.0, "status": "SUCCESS"}}},
            {"runs": {1: {"t90_s": 200.0, "status": "SUCCESS"}, 2: {"t90_s": 140.0, "status": "SUCCESS"}}},
            {"runs": {1: {"t90_s": None, "status": "FAILURE"}, 2: {"t90_s": 90.0, "status": "SUCCESS"}}}]
    for row in rows:
        for run in row["runs"].values():
            run["cpu_s"] = 1.0
    found = explore_summary(rows, (1, 2))
    assert found["ratio_to_1"][2] == {"median": 0.6, "min": 0.5, "max": 0.7, "n": 2}
    assert found["reached_90"] == {1: "2/3", 2: "3/3"}


def test_the_search_ratio_takes_only_cases_both_found_and_absent_cases_are_scored_apart() -> None:
    """One case found by both (ratio 0.4), one by two robots only, one absent case answered right."""
    from fleet_explore_search import search_summary

    def run(found: bool, t: float | None, absent_right: bool = False) -> dict[str, object]:
        return {"found": found, "t_found_s": t, "false_found": False, "absent_right": absent_right,
                "cpu_s": 1.0}

    rows = [{"absent": False, "runs": {1: run(True, 100.0), 2: run(True, 40.0)}},
            {"absent": False, "runs": {1: run(False, None), 2: run(True, 80.0)}},
            {"absent": True, "runs": {1: run(False, None, True), 2: run(False, None, True)}}]
    found = search_summary(rows, (1, 2))
    assert found["ratio_to_1"][2]["median"] == pytest.approx(0.4) and found["ratio_to_1"][2]["n"] == 1
    assert found["found"][2]["ok"] == 2 and found["found"][1]["ok"] == 1
    assert found["absent_right"][2] == "1/1"
