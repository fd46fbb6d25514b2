"""The tour over exploration goals: least value-weighted latency, path lengths that go round walls."""

from __future__ import annotations

import numpy as np
import pytest

from missiontree.mapping.exploration import Candidate, ExplorationPlanner, straight_line_lengths
from missiontree.mapping.tour import CoarseGraph, between_lengths, latency_order, tour_latency
from missiontree.types import OccupancyGrid, Pose2D


def walled(door: bool = True) -> OccupancyGrid:
    """5 x 5 m of known floor at 5 cm, a wall down x = 2.5 m with a door at y 4.5-4.75 m (or none)."""
    data = np.zeros((100, 100), np.int8)
    data[:, 50] = 100
    if door:
        data[90:95, 50] = 0
    return OccupancyGrid(0.0, 0.05, Pose2D(0.0, 0.0), data)


def test_coarse_lengths_go_round_a_wall_through_its_door() -> None:
    """Two places 3 m apart either side of a wall are about 8 m apart through the door, none without."""
    through = CoarseGraph(walled()).lengths([(1.0, 1.0), (4.0, 1.0)])[0, 1]
    closed = CoarseGraph(walled(door=False)).lengths([(1.0, 1.0), (4.0, 1.0)])[0, 1]
    assert 7.0 < through < 11.0
    assert closed == np.inf


def test_between_lengths_fall_back_to_the_way_via_the_robot() -> None:
    """Where the coarse graph has no way, a goal's distance to another is at most the sum of theirs."""
    out = between_lengths(walled(door=False), [(1.0, 1.0), (4.0, 1.0)], np.array([2.0, 5.0]))
    assert out[0, 1] == pytest.approx(7.0)


def test_the_tour_finishes_a_cluster_before_crossing_to_a_better_single_goal() -> None:
    """Two goals of 5 beside each other beat one of 6 the same distance off: greedy took the 6 first."""
    values = np.array([5.0, 6.0, 5.0])
    start = np.array([3.0, 3.0, 4.0])
    between = np.array([[0.0, 6.0, 1.0], [6.0, 0.0, 7.0], [1.0, 7.0, 0.0]])
    order = latency_order(values, start, between)
    assert order == [0, 2, 1]
    assert tour_latency(order, values, start, between) < tour_latency([1, 0, 2], values, start, between)


def test_the_planner_offers_the_tour_s_first_stop_first() -> None:
    """in_order puts the clustered goals first although the lone goal scores best one step ahead."""
    p = ExplorationPlanner(strategy="gain", path_lengths=straight_line_lengths, order="tour")
    g = OccupancyGrid(0.0, 0.1, Pose2D(0.0, 0.0), np.zeros((100, 100), np.int8))
    robot = (5.0, 5.0)

    def goal(x: float, y: float, gain: float) -> Candidate:
        path = float(np.hypot(x - robot[0], y - robot[1]))
        return Candidate(x, y, "frontier", 10, gain, path, gain * float(np.exp(-p.cost_rate * path)), (x, y))

    lone, a, b = goal(2.0, 5.0, 6.0), goal(8.0, 5.0, 5.0), goal(8.0, 6.0, 5.0)
    ordered = p.in_order(g, robot, [lone, a, b])
    assert ordered[0] is a and ordered[-1] is lone
    assert ExplorationPlanner(strategy="gain", order="score").in_order(g, robot, [lone, a, b])[0] is lone


def test_a_stop_costs_time_so_a_small_place_beside_the_robot_waits() -> None:
    """With tour_stop_m 3 the large goal goes first; free stops took the 2 m^2 place 0.2 m off first."""
    g = OccupancyGrid(0.0, 0.1, Pose2D(0.0, 0.0), np.zeros((100, 100), np.int8))
    robot = (5.0, 5.0)

    def goal(p: ExplorationPlanner, x: float, gain: float) -> Candidate:
        path = abs(x - robot[0])
        score = gain * float(np.exp(-p.cost_rate * path))
        return Candidate(x, 5.0, "frontier", 10, gain, path, score, (x, 5.0))

    free = ExplorationPlanner(strategy="gain", order="tour", tour_stop_m=0.0)
    costly = ExplorationPlanner(strategy="gain", order="tour", tour_stop_m=3.0)
    near, far = goal(free, 4.8, 2.0), goal(free, 9.0, 10.0)
    assert free.in_order(g, robot, [far, near])[0] is near
    assert costly.in_order(g, robot, [far, near])[0] is far
