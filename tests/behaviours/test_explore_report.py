"""What an ending exploration says about the small unknown it left as not worth a trip."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

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


def test_the_map_files_are_written_again_only_when_the_map_changed(tmp_path: Path,
                                                                 monkeypatch: pytest.MonkeyPatch) -> None:
    """Saving the same cells twice writes map.pgm once (a later stamp too); a changed cell writes again."""
    import missiontree.behaviours.explore_report as explore_report
    from missiontree.behaviours.explore import Explore
    from missiontree.engine.context import MissionContext

    writes: list[Path] = []
    real = explore_report.write_map

    def counting(grid: OccupancyGrid, directory: Path, name: str = "map") -> tuple[Path, Path]:
        writes.append(Path(directory))
        return real(grid, directory, name)

    monkeypatch.setattr(explore_report, "write_map", counting)
    leaf = Explore("explore")
    leaf.setup(context=MissionContext(robot=None, run_dir=tmp_path))  # type: ignore[arg-type]
    grid = long_room_with_a_pocket()
    report = exploration_report(None, "stopped", 0, grid, None, None)
    explore_report.save_exploration(leaf, grid, report)
    explore_report.save_exploration(leaf, OccupancyGrid(5.0, grid.resolution, grid.origin, grid.data.copy()),
                                    report)
    assert len(writes) == 1 and (tmp_path / "map.pgm").is_file()
    grid.data[3, 3] = 100  # the same array changed in place
    explore_report.save_exploration(leaf, grid, report)
    assert len(writes) == 2
    (tmp_path / "map.pgm").unlink()  # a file gone is written again
    explore_report.save_exploration(leaf, grid, report)
    assert len(writes) == 3 and (tmp_path / "map.pgm").is_file()
