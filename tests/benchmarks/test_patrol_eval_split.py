"""The patrol benchmark's test split helpers: routes from a map, walkers through them, split figures."""

from __future__ import annotations

import math
import random
import sys
from pathlib import Path

import numpy as np

from missiontree.backends.sim.world import load_robot_profile
from missiontree.types import OccupancyGrid, Pose2D

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
import patrol_eval  # noqa: E402

RES = 0.05


def two_rooms(sealed: bool = False) -> OccupancyGrid:
    """Two 5 x 4 m rooms side by side, joined by a 1 m door unless ``sealed``."""
    data = np.zeros((int(5 / RES), int(11 / RES)), np.int8)
    data[:2, :] = data[-2:, :] = 100
    data[:, :2] = data[:, -2:] = 100
    wall = int(5.5 / RES)
    data[:, wall - 1:wall + 1] = 100
    if not sealed:
        data[int(2.0 / RES):int(3.0 / RES), wall - 1:wall + 1] = 0
    return OccupancyGrid(0.0, RES, Pose2D(0.0, 0.0, 0.0), data)


def test_room_spots_give_each_room_an_open_spot() -> None:
    """Each room of the map gets a spot with room to turn, and the map gets at least MIN_WAYPOINTS."""
    grid = two_rooms()
    spots = patrol_eval.room_spots(grid, (1.5, 2.5))
    clearance = patrol_eval.clearance_map(grid)
    assert len(spots) >= patrol_eval.MIN_WAYPOINTS
    assert any(x < 5.4 for x, _ in spots) and any(x > 5.6 for x, _ in spots)
    for x, y in spots:
        row, col = grid.world_to_cell(x, y)
        assert clearance[row, col] >= patrol_eval.ROUTE_CLEARANCE


def test_map_route_leaves_out_what_the_robot_cannot_reach() -> None:
    """A room behind a sealed wall gets no waypoint; every leg is a planned path ending at its waypoint."""
    profile = load_robot_profile("turtlebot4")
    grid = two_rooms(sealed=True)
    route = patrol_eval.map_route(grid, (1.5, 2.5), profile)
    assert route.waypoints and all(x < 5.4 for x, _ in route.waypoints)
    for (x, y), leg in zip(route.waypoints, route.legs, strict=True):
        assert math.dist(leg[-1], (x, y)) < 0.1
    assert patrol_eval.map_route(two_rooms(), (1.5, 2.5), profile).waypoints[-1][0] > 5.6


def test_map_route_stops_within_its_budget() -> None:
    """The tour takes no waypoint whose leg would carry it past the budget (the first one excepted)."""
    profile = load_robot_profile("turtlebot4")
    route = patrol_eval.map_route(two_rooms(), (1.5, 2.5), profile, budget=0.5)
    assert len(route.waypoints) == 1
    full = patrol_eval.map_route(two_rooms(), (1.5, 2.5), profile)
    assert len(full.waypoints) > 1 and full.length <= patrol_eval.ROUTE_LENGTH


def test_route_walkers_cross_each_waypoint_and_keep_off_walls() -> None:
    """Walkers pass within a step of every waypoint and no leg of their routes comes near an obstacle."""
    profile = load_robot_profile("turtlebot4")
    grid = two_rooms()
    route = patrol_eval.map_route(grid, (1.5, 2.5), profile)
    people = patrol_eval.route_walkers(grid, route, random.Random(3))
    clearance = patrol_eval.clearance_map(grid)
    assert len(people) > len(route.waypoints)  # crossers, and walkers along the legs
    for person in people:
        points = [tuple(p) for p in person["route"]]
        for a, b in zip(points, points[1:] + points[:1], strict=True):
            assert patrol_eval.line_clear(grid, clearance, a, b, patrol_eval.WALKER_CLEARANCE - 0.06)
    for x, y in route.waypoints:
        assert any(_near_segment((x, y), p["route"][0], p["route"][1]) < 0.1 for p in people)


def _near_segment(p: tuple[float, float], a: list[float], b: list[float]) -> float:
    ax, ay, bx, by = *a, *b
    along = ((p[0] - ax) * (bx - ax) + (p[1] - ay) * (by - ay)) / ((bx - ax) ** 2 + (by - ay) ** 2)
    t = max(0.0, min(1.0, along))
    return math.hypot(p[0] - ax - t * (bx - ax), p[1] - ay - t * (by - ay))


def test_line_clear_sees_a_wall_between_two_points() -> None:
    """A segment through the wall between the rooms is not clear; one inside a room is."""
    grid = two_rooms(sealed=True)
    clearance = patrol_eval.clearance_map(grid)
    assert patrol_eval.line_clear(grid, clearance, (1.0, 1.0), (4.0, 3.5), 0.3)
    assert not patrol_eval.line_clear(grid, clearance, (4.0, 1.0), (7.0, 1.0), 0.3)


def run_score(split: str, config: str, detected: int, encounters: int, reached: int = 4,
          skipped: int = 0) -> patrol_eval.RunScore:
    return patrol_eval.RunScore(split, "w", config, 7, sim_seconds=100.0, encounters=encounters,
                                detected=detected, calls=50, errors=[0.1, 0.2, 1.5],
                                bearings=[0.0, 0.1, -0.1], reached=reached, skipped=skipped)


def test_summary_gives_rates_with_wilson_intervals_and_the_gap() -> None:
    """Rates carry their 95 % Wilson interval, and the gap is test minus dev."""
    dev = patrol_eval.summarise([run_score("dev", "ours", 10, 10)])
    test = patrol_eval.summarise([run_score("test", "ours", 8, 10, reached=3, skipped=1)])
    assert test["ours"]["detection_rate"] == 0.8
    low, high = test["ours"]["detection_rate_ci95"]
    assert 0.4 < low < 0.8 < high < 1.0
    assert test["ours"]["share_over_1m"] == round(1 / 3, 4)
    gap = patrol_eval.gaps(dev, test)
    assert gap["ours"]["detection_rate"] == -0.2
    assert gap["ours"]["waypoint_reach_rate"] == -0.25
    table = patrol_eval.markdown_table({"dev": dev, "test": test}, gap)
    row = next(line for line in table if "ours | detection rate" in line)
    assert "1.000" in row and "0.800 [" in row and "-0.200" in row
