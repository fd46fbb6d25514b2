"""Frontiers on small hand-made grids."""

from __future__ import annotations

import numpy as np
import pytest

from missiontree.mapping.frontiers import find_frontiers, frontier_mask
from missiontree.types import OccupancyGrid, Pose2D


def grid_of(rows: list[str], resolution: float = 0.1) -> OccupancyGrid:
    """A grid drawn as text, top line = highest y: '.' free, '#' occupied, '?' unknown."""
    table = {".": 0, "#": 100, "?": -1}
    data = np.array([[table[ch] for ch in line] for line in reversed(rows)], np.int8)
    return OccupancyGrid(0.0, resolution, Pose2D(0.0, 0.0), data)


def test_free_cells_touching_unknown_form_one_frontier_with_its_centroid() -> None:
    """A room open on its right side: the column of free cells next to the unknown is the frontier."""
    g = grid_of([
        "#######??",
        "#.....#??",
        "#......??",
        "#......??",
        "#......??",
        "#.....#??",
        "#######??",
    ])
    frontiers = find_frontiers(g, min_size_cells=2)
    assert len(frontiers) == 1
    f = frontiers[0]
    assert f.size == 3
    assert sorted(map(tuple, f.cells.tolist())) == [(2, 6), (3, 6), (4, 6)]
    assert f.centroid == pytest.approx((0.65, 0.35))
    assert f.goal == pytest.approx((0.65, 0.35))


def test_unknown_next_to_walls_only_is_no_frontier() -> None:
    """Unknown space behind a wall is not reachable from free space: no frontier."""
    g = grid_of([
        "???????",
        "#######",
        "#.....#",
        "#######",
    ])
    assert find_frontiers(g, min_size_cells=1) == []
    assert not frontier_mask(g).any()


def test_unknown_touching_only_diagonally_makes_no_frontier_cell() -> None:
    """A free cell counts only when an unknown cell is one of its four neighbours."""
    g = grid_of([
        "####",
        "#?##",
        "##.#",
        "####",
    ])
    assert not frontier_mask(g).any()


def test_frontier_cells_touching_diagonally_form_one_frontier() -> None:
    """Frontier cells join into one cluster through a diagonal contact (eight-connectivity)."""
    g = grid_of([
        "#?##",
        "#.?#",
        "##.#",
        "####",
    ])
    assert frontier_mask(g).sum() == 2
    frontiers = find_frontiers(g, min_size_cells=1)
    assert len(frontiers) == 1 and frontiers[0].size == 2


def test_small_frontiers_are_dropped_and_large_ones_sorted_first() -> None:
    """min_size_cells filters noise; the list is largest first."""
    g = grid_of([
        "??????????",
        "?........?",
        "#........#",
        "#........#",
        "##########",
    ])
    frontiers = find_frontiers(g, min_size_cells=1)
    sizes = [f.size for f in frontiers]
    assert sizes == sorted(sizes, reverse=True)
    assert find_frontiers(g, min_size_cells=100) == []


def test_border_of_the_grid_counts_as_unknown() -> None:
    """A free cell on the map's edge is a frontier: the map is still growing there."""
    g = grid_of([
        "....",
        "....",
    ])
    assert frontier_mask(g).all()


def test_long_frontiers_are_split_into_pieces() -> None:
    """max_size_cells cuts a long frontier into pieces along it, each at most that long."""
    g = grid_of(["?" * 30, "." * 30, "#" * 30])
    whole = find_frontiers(g, min_size_cells=1)
    pieces = find_frontiers(g, min_size_cells=1, max_size_cells=10)
    assert len(whole) == 1 and len(pieces) >= 3
    assert all(p.size <= 10 for p in pieces)
    assert sum(p.size for p in pieces) == whole[0].size
    xs = sorted(p.centroid[0] for p in pieces)
    assert xs[0] < 1.0 < xs[-1] and xs[-1] > 2.0


def test_goal_is_on_the_frontier_when_the_centroid_is_not() -> None:
    """A curved (L-shaped) frontier: its centroid lies off the frontier, its goal on a frontier cell."""
    g = grid_of([
        "?????",
        "????.",
        "????.",
        ".....",
        ".....",
    ])
    f = max(find_frontiers(g, min_size_cells=1), key=lambda fr: fr.size)
    r, c = g.world_to_cell(*f.goal)
    assert frontier_mask(g)[r, c]


def test_bad_sizes_are_refused() -> None:
    """Sizes below one cell, or a split smaller than the minimum, raise ValueError."""
    g = grid_of(["..", ".."])
    with pytest.raises(ValueError):
        find_frontiers(g, min_size_cells=0)
    with pytest.raises(ValueError):
        find_frontiers(g, min_size_cells=5, max_size_cells=3)
