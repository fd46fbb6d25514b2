"""What an ending exploration says about the small unknown it left as not worth a trip."""

from __future__ import annotations

import numpy as np

from missiontree.behaviours.explore_report import exploration_report, said, slivers_text
from missiontree.mapping.exploration import ExplorationPlanner, straight_line_lengths
from missiontree.types import OccupancyGrid, Pose2D


def long_room_with_a_pocket() -> OccupancyGrid:
    """A known walled room 30 x 3 m at 0.1 m with a 0.7 x 0.7 m unknown pocket in its west corner."""
    data = np.full((31, 300), 100, np.int8)
    data[1:30, 1:299] = 0
    data[1:8, 1:8] = -1
    data[8, 1:5] = 100
    return OccupancyGrid(0.0, 0.1, Pose2D(0.0, 0.0), data)


def test_an_explored_end_names_the_slivers_it_left_with_their_area() -> None:
    """The report lists the pocket left far away, and the outcome line says its count and m^2."""
    grid = long_room_with_a_pocket()
    planner = ExplorationPlanner(strategy="gain", path_lengths=straight_line_lengths)
    assert planner.candidates(grid, (25.0, 1.5)) == []
    report = exploration_report(planner, "explored", 3, grid, None, None)
    assert len(report["slivers_left"]) == 1 and 0.45 < report["slivers_m2"] < 0.55
    assert "1 small unknown sliver left as not worth a trip, 0.5 m^2" in said(report)
    assert slivers_text(planner) == ", 1 small unknown sliver left (0.5 m^2)"
