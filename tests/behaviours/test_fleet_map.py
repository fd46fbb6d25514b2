"""The fleet's merged map and frontier claims (behaviours/fleet_map.py)."""

from __future__ import annotations

import math

import numpy as np

from missiontree.behaviours.fleet_map import FleetMap, FleetRobot, FrontierClaims, merge_grids
from missiontree.engine.fleet import FleetView
from missiontree.mapping.exploration import Candidate, ExplorationPlanner
from missiontree.types import OccupancyGrid, Pose2D


def _grid(data: list[list[int]], ox: float = 0.0, oy: float = 0.0, stamp: float = 0.0) -> OccupancyGrid:
    return OccupancyGrid(stamp, 1.0, Pose2D(ox, oy, 0.0), np.array(data, np.int8))


def _cand(x: float, y: float, score: float) -> Candidate:
    return Candidate(x, y, "frontier", 5, 1.0, 1.0, score, (x, y))


def test_a_cell_known_to_any_robot_is_known_in_the_merged_map() -> None:
    """Unknown in one map, free in the other: free in the merged map."""
    a = _grid([[-1, -1], [0, 100]])
    b = _grid([[0, -1], [-1, -1]])
    merged = merge_grids([a, b])
    assert merged.data.tolist() == [[0, -1], [0, 100]]


def test_occupied_wins_only_by_majority() -> None:
    """A cell one robot reads occupied (another robot standing there) and another free stays free."""
    a = _grid([[100, 100]])
    b = _grid([[0, 100]])
    assert merge_grids([a, b]).data.tolist() == [[0, 100]]


def test_maps_with_different_origins_are_merged_over_their_union() -> None:
    """A map that grew to the west is placed by its origin."""
    a = _grid([[0, 0]], ox=0.0)
    b = _grid([[100]], ox=-1.0, stamp=3.0)
    merged = merge_grids([a, b])
    assert merged.origin.x == -1.0 and merged.stamp == 3.0
    assert merged.data.tolist() == [[100, 0, 0]]


class _MapRobot:
    def __init__(self, name: str, grid: OccupancyGrid) -> None:
        self.name, self.grid = name, grid

    def occupancy(self) -> OccupancyGrid:
        return self.grid

    def now(self) -> float:
        return 7.0


def test_the_fleet_map_is_recomputed_only_when_a_robots_map_changed() -> None:
    """Asking twice without a new map merges once; a new map of one robot merges again."""
    fleet_map = FleetMap()
    one, two = _MapRobot("robot1", _grid([[0, -1]])), _MapRobot("robot2", _grid([[-1, 0]]))
    fleet_map.add("robot1", one)
    fleet_map.add("robot2", two)
    first = fleet_map.grid()
    assert fleet_map.grid() is first and fleet_map.merges == 1
    two.grid = _grid([[-1, 100]])
    assert fleet_map.grid() is not first and fleet_map.merges == 2
    robot = FleetRobot(one, fleet_map)
    assert robot.occupancy().data.tolist() == [[0, 100]]  # type: ignore[union-attr]
    assert robot.own_occupancy() is one.grid and robot.now() == 7.0


def test_a_place_another_robot_claimed_is_not_offered() -> None:
    """No two robots on one frontier: robot2 does not get robot1's place; its own stays."""
    claims = FrontierClaims(claim_radius=1.0, sensor_range=4.0)
    claims.claim("robot1", (2.0, 2.0))
    kept = claims.filter("robot2", [_cand(2.3, 2.0, 10.0), _cand(9.0, 9.0, 5.0)])
    assert [(c.x, c.y) for c in kept] == [(9.0, 9.0)]
    assert len(claims.filter("robot1", [_cand(2.3, 2.0, 10.0)])) == 1


def test_a_place_near_another_claim_counts_less_and_the_order_follows() -> None:
    """A candidate 2 m from a claim (half overlap) loses to a farther-away one of a slightly lower score."""
    claims = FrontierClaims(claim_radius=1.0, sensor_range=4.0, overlap_discount=0.6)
    claims.claim("robot1", (0.0, 0.0))
    kept = claims.filter("robot2", [_cand(2.0, 0.0, 10.0), _cand(20.0, 0.0, 8.0)])
    assert [c.x for c in kept] == [20.0, 2.0]
    assert math.isclose(kept[1].score, 7.0)


def test_a_lost_robots_claim_goes_back_on_offer() -> None:
    """After robot1 is lost its place is offered to robot2, and the release is an event."""
    events: list[tuple[str, dict[str, object]]] = []
    claims = FrontierClaims(emit=lambda e, **f: events.append((e, f)))
    view = FleetView(["robot1", "robot2"], lambda: 5.0)
    view.on_loss(claims.release)
    claims.claim("robot1", (2.0, 2.0))
    assert view.lose("robot1", "killed") is True
    assert len(claims.filter("robot2", [_cand(2.0, 2.0, 1.0)])) == 1
    assert events[0][0] == "fleet_claim_released" and events[0][1]["robot"] == "robot1"
    claims.claim("robot1", (3.0, 3.0))  # a lost robot claims nothing any more
    assert claims.others("robot2") == []


def test_a_wrapped_planner_filters_its_candidates_once() -> None:
    """wrap() composes the planner's candidates with the claims, and wrapping twice changes nothing."""
    claims = FrontierClaims(claim_radius=1.0)
    grid = _grid([[0] * 6 for _ in range(6)] + [[-1] * 6 for _ in range(6)])
    plain = ExplorationPlanner().candidates(grid, (2.5, 2.5))
    assert plain
    wrapped = claims.wrap(ExplorationPlanner(), "robot2")
    first = wrapped.candidates
    assert claims.wrap(wrapped, "robot2").candidates is first
    claims.claim("robot1", plain[0].target)
    offered = wrapped.candidates(grid, (2.5, 2.5))
    assert all(math.dist(c.target, plain[0].target) > 1.0 for c in offered)
