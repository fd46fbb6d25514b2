"""Ranking exploration goals: gain against path cost, nearest, scan points, blacklist, wall gaps."""

from __future__ import annotations

import numpy as np
import pytest

from missiontree.mapping.exploration import ExplorationPlanner, straight_line_lengths, visible_unknown_area
from missiontree.types import OccupancyGrid, Pose2D

RES = 0.1


def grid(data: np.ndarray) -> OccupancyGrid:
    return OccupancyGrid(0.0, RES, Pose2D(0.0, 0.0), data)


def two_openings() -> np.ndarray:
    """A known room (x 3-5 m, y 0-2 m) between a small unknown pocket (x 2-3) and a large unknown (x 5-12)."""
    data = np.full((20, 120), -1, np.int8)
    data[:, 30:50] = 0
    data[0, :] = 100
    data[-1, :] = 100
    data[:, 19] = 100          # the pocket's back wall at x 1.9
    return data


def planner(strategy: str, **kw: object) -> ExplorationPlanner:
    return ExplorationPlanner(strategy=strategy, path_lengths=straight_line_lengths, footprint_radius=0.2,
                              sensor_range=4.0, **kw)  # type: ignore[arg-type]


def test_gain_prefers_the_frontier_that_reveals_more_and_nearest_the_closer_one() -> None:
    """Nearer the small west pocket: nearest goes west, gain's best score east to the large unknown."""
    g = grid(two_openings())
    robot = (3.5, 1.0)
    best_gain = planner("gain", order="score").candidates(g, robot)[0]
    best_near = planner("nearest").candidates(g, robot)[0]
    assert best_gain.target[0] > 4.5 and best_gain.gain_m2 > 3.0
    assert best_near.target[0] < 3.5
    assert best_near.path_m < best_gain.path_m


def test_the_tour_takes_the_pocket_beside_the_robot_before_the_large_unknown() -> None:
    """With order tour the pocket 0.25 m away comes first: putting it off costs the trip back."""
    g = grid(two_openings())
    first, second = planner("gain", order="tour").candidates(g, (3.5, 1.0))[:2]
    assert first.target[0] < 3.5 and second.target[0] > 4.5
    assert first.score < second.score       # the one-step ranking would have gone east first


def test_walls_stop_the_gain_rays() -> None:
    """Unknown space behind a known wall adds nothing to the gain."""
    data = np.full((80, 80), -1, np.int8)
    data[:, :50] = 0                      # free up to x 5 m, unknown beyond
    at = np.array([[3.0, 4.0]])           # every ray stays inside the grid
    open_gain = visible_unknown_area(grid(data), at, 2.5)[0]
    data[:, 50] = 100                     # a wall at x 5 m
    walled_gain = visible_unknown_area(grid(data), at, 2.5)[0]
    assert open_gain > 1.0 and walled_gain == pytest.approx(0.0)


def test_a_blacklisted_frontier_is_not_offered_again() -> None:
    """give_up() removes the goal and the frontier place it stood for from the candidates."""
    g = grid(two_openings())
    p = planner("nearest")
    first = p.candidates(g, (3.5, 1.0))[0]
    p.give_up(first.x, first.y, "no path", first.target)
    rest = p.candidates(g, (3.5, 1.0))
    assert all(np.hypot(c.target[0] - first.target[0], c.target[1] - first.target[1]) > 0.75 for c in rest)
    assert p.blacklist[0].reason == "no path"


def test_unreachable_goals_are_no_candidates() -> None:
    """A goal the path-length function calls unreachable (None) is dropped."""
    g = grid(two_openings())
    p = ExplorationPlanner(strategy="gain", path_lengths=lambda grid, s, goals, r: [None] * len(goals))
    assert p.candidates(g, (3.5, 1.0)) == []


def test_a_one_cell_gap_in_a_wall_is_no_frontier() -> None:
    """A wall seen with a one-cell unknown hole does not make a frontier onto the unknown behind it."""
    data = np.full((30, 40), -1, np.int8)
    data[:, :20] = 0
    data[:, 20] = 100
    data[:, :2] = 100
    data[:2, :21] = 100
    data[-2:, :21] = 100
    data[15, 20] = -1   # a gap the beams missed
    p = planner("gain", min_frontier_m=0.1, min_gain_m2=0.0)
    assert p.candidates(grid(data), (1.0, 1.5)) == []


def test_scan_points_are_visited_once_largest_first() -> None:
    """The scan-point strategy offers the largest region first and not again once visited."""
    data = np.full((22, 63), 100, np.int8)
    data[1:21, 1:41] = 0
    data[1:21, 42:62] = 0
    data[9:13, 41] = 0
    p = planner("scan_points", erosion_m=0.3)
    first = p.candidates(grid(data), (1.0, 1.0))
    assert len(first) == 2 and first[0].size > first[1].size
    p.visit(first[0].x, first[0].y)
    again = p.candidates(grid(data), (1.0, 1.0))
    assert [(c.x, c.y) for c in again] == [(first[1].x, first[1].y)]


def test_unknown_strategy_is_refused() -> None:
    """A strategy name outside gain, nearest, scan_points raises ValueError listing them."""
    with pytest.raises(ValueError, match="gain, nearest, scan_points"):
        ExplorationPlanner(strategy="random")


def test_a_frontier_onto_a_room_opens_onto_space_and_one_onto_a_box_inside_does_not() -> None:
    """The unknown past a corridor's open end fits the robot; the unknown inside a seen box does not."""
    data = np.full((40, 120), -1, np.int8)
    data[:, 20:80] = 0                 # known free x 2-8 m, unknown beyond x 8 (a room not seen yet)
    data[0, 20:80] = data[-1, 20:80] = 100
    data[:, 19] = 100
    data[14:21, 40:64] = 100           # a box 2.4 x 0.7 m whose inside (0.5 m wide) was never seen ...
    data[15:20, 41:63] = -1
    data[15:20, 40] = 0                # ... but through its open near side (a frontier into it)
    p = planner("gain", reach_radius=0.27)
    g = grid(data)
    assert p.opens_onto_space(g, (7.95, 1.05))
    box = [c for c in p.candidates(g, (3.0, 1.0), ignore_blacklist=True) if 3.5 < c.target[0] < 4.5]
    assert box  # the box's inside is a frontier worth a trip by its gain ...
    assert not p.opens_onto_space(g, box[0].target)   # ... but nothing the robot fits into


def pocket_room() -> np.ndarray:
    """A known walled room (4 x 3 m) with a 0.7 x 0.7 m unknown pocket in a corner behind a cabinet."""
    data = np.zeros((30, 40), np.int8)
    data[0, :] = data[-1, :] = data[:, 0] = data[:, -1] = 100
    data[1:8, 1:8] = -1                    # the pocket, seen by no beam (0.49 m^2)
    data[8, 1:5] = 100                     # the cabinet's side, open towards the east
    return data


def test_a_small_pocket_is_explored_once_nothing_larger_is_left() -> None:
    """Under the size thresholds a reachable pocket is still offered, once nothing larger is left."""
    g = grid(pocket_room())
    p = planner("gain", min_frontier_m=0.5, min_unknown_m2=1.0, min_gain_m2=1.0)
    offered = p.candidates(g, (3.0, 2.0))
    assert offered and offered[0].target[0] < 1.0 and offered[0].target[1] < 1.0
    assert p.min_unknown_m2 == 1.0 and p.min_gain_m2 == 1.0      # the thresholds are restored


def test_a_speck_between_beams_is_no_candidate_even_at_the_end() -> None:
    """A two-cell unknown speck inside seen floor is below even the small thresholds."""
    data = pocket_room()
    data[1:8, 1:8] = 0
    data[15, 20:22] = -1
    assert planner("gain", min_unknown_m2=1.0, min_gain_m2=1.0).candidates(grid(data), (3.0, 2.0)) == []


def room_in_a_large_unknown() -> np.ndarray:
    """A 30 x 20 m grid, unknown but for a room (x 10-14 m, y 8-11 m) with a doorway east at x 14."""
    data = np.full((200, 300), -1, np.int8)
    data[80:110, 100:140] = 0
    data[78:80, 98:142] = 100          # walls two cells thick (no gain ray slips through a corner)
    data[110:112, 98:142] = 100
    data[78:112, 98:100] = 100
    data[78:90, 140:142] = 100
    data[100:112, 140:142] = 100
    return data


def test_the_window_is_the_known_box_with_a_margin_snapped_to_its_step() -> None:
    """known_window keeps the known cells' box padded by the margin, edges snapped out, origin moved."""
    from missiontree.mapping.exploration import known_window

    w = known_window(grid(room_in_a_large_unknown()), margin_m=1.0, step_m=2.0)
    # known rows 78-111 and cols 98-141; padded by 10 cells, snapped to 20: rows 60-140, cols 80-160
    assert w.data.shape == (80, 80)
    assert (w.origin.x, w.origin.y) == pytest.approx((8.0, 6.0))
    assert (w.data >= 0).sum() == (room_in_a_large_unknown() >= 0).sum()


def test_ranking_on_the_window_offers_the_same_goals_and_measures_paths_on_the_window() -> None:
    """The window gives the goals of the whole grid, and the path search sees only the window."""
    g = grid(room_in_a_large_unknown())
    shapes: list[tuple[int, ...]] = []

    def lengths(grid_: OccupancyGrid, start: tuple[float, float], goals: object, r: float) -> list:
        shapes.append(grid_.data.shape)
        return straight_line_lengths(grid_, start, goals, r)  # type: ignore[arg-type]

    whole = planner("gain", window_margin_m=100.0).candidates(g, (12.0, 9.5))
    cut = ExplorationPlanner(strategy="gain", path_lengths=lengths, footprint_radius=0.2,
                             sensor_range=4.0).candidates(g, (12.0, 9.5))
    assert [v for c in cut for v in (c.x, c.y, *c.target)] == pytest.approx(
        [v for c in whole for v in (c.x, c.y, *c.target)])
    assert [c.gain_m2 for c in cut] == pytest.approx([c.gain_m2 for c in whole])
    assert cut and shapes and all(s[0] * s[1] <= 80 * 80 for s in shapes)


def long_room(pocket: bool = True, closet: bool = False) -> np.ndarray:
    """A known walled room 30 x 3 m; a 0.7 x 0.7 m unknown pocket in its west corner, or a closet off it.

    The closet (1.2 x 1.3 m, its walls seen from outside) lies north of the room's west end, behind
    a 0.9 m doorway.
    """
    data = np.full((45, 300), 100, np.int8)
    data[1:30, 1:299] = 0
    if pocket:
        data[1:8, 1:8] = -1                # seen by no beam (0.49 m^2)
        data[8, 1:5] = 100                 # a cabinet's side, open towards the east
    if closet:
        data[31:43, 10:23] = -1            # the closet's inside, never seen
        data[30, 12:21] = 0                # its doorway (0.9 m) in the room's north wall
    return data


def test_a_small_pocket_far_from_the_robot_is_left_as_a_sliver_and_counted() -> None:
    """A 0.5 m^2 pocket 25 m away is no trip: not offered, kept as a sliver with its area."""
    p = planner("gain", min_frontier_m=0.5, min_unknown_m2=1.0, min_gain_m2=1.0)
    assert p.candidates(grid(long_room()), (25.0, 1.5)) == []
    assert len(p.slivers) == 1 and p.slivers[0].unknown_m2 == pytest.approx(0.49, abs=0.01)
    assert p.sliver_area() == pytest.approx(0.49, abs=0.01)
    near = planner("gain", min_frontier_m=0.5, min_unknown_m2=1.0, min_gain_m2=1.0)
    assert near.candidates(grid(long_room()), (2.0, 1.5)) and near.slivers == []  # on the robot's way


def test_a_small_room_behind_a_doorway_far_away_is_still_worth_a_trip() -> None:
    """A 1.6 m^2 closet behind a 0.9 m doorway 25 m away is offered: the body fits through and in."""
    p = planner("gain", min_frontier_m=0.5, min_unknown_m2=1.0, min_gain_m2=1.0)
    offered = p.candidates(grid(long_room(pocket=False, closet=True)), (25.0, 1.5))
    assert offered and 1.0 < offered[0].target[0] < 2.3 and offered[0].target[1] > 2.5
    assert p.slivers == []
