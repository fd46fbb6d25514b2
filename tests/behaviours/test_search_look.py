"""The search's look at a place to look from: only the arc holding unseen floor, no full turn."""

from __future__ import annotations

import math

import numpy as np
from patrol_doubles import Events
from test_search_coverage import CameraRobot, Detector, K, grid_of, hall

from missiontree.behaviours.search_coverage import ViewCoverage, look_arc, unseen_bearings
from missiontree.behaviours.search_locate import Locate
from missiontree.engine.context import MissionContext
from missiontree.engine.leaf import Status
from missiontree.types import Pose2D

HALF = math.radians(30.0)


def covered(turns: tuple[float, float], bearings: list[float], half: float) -> bool:
    """Whether turning by ``turns`` (from heading 0) brings every bearing within ``half`` of the camera."""
    first, second = turns
    headings = np.concatenate([np.linspace(0.0, first, 50), first + np.linspace(0.0, second, 50)])
    for b in bearings:
        off = (np.asarray(headings) - b + math.pi) % (2.0 * math.pi) - math.pi
        if not np.any(np.abs(off) <= half + 1e-9):
            return False
    return True


def test_no_turn_when_the_unseen_floor_is_already_in_view() -> None:
    """Bearings within the half field of view need no turn."""
    assert look_arc(np.array([-0.3, 0.1, 0.4]), HALF) is None
    assert look_arc(np.zeros(0), HALF) is None


def test_floor_to_one_side_is_looked_at_by_a_turn_that_way_not_a_circle() -> None:
    """Unseen floor 60-120 degrees left: a left turn of at most 120 degrees covers it."""
    bearings = list(np.radians(np.linspace(60.0, 120.0, 7)))
    turns = look_arc(np.array(bearings), HALF)
    assert turns is not None
    assert turns[0] > 0 and abs(turns[0]) + abs(turns[1]) <= math.radians(120.0)
    assert covered(turns, bearings, HALF)


def test_floor_all_around_is_swept_in_less_than_a_circle() -> None:
    """Unseen floor all round: one sweep of 360 minus the field of view covers every bearing."""
    bearings = list(np.radians(np.arange(-180.0, 180.0, 10.0)))
    turns = look_arc(np.array(bearings), HALF)
    assert turns is not None
    assert abs(turns[0]) + abs(turns[1]) <= 2.0 * math.pi - 2.0 * HALF + 1e-9
    assert covered(turns, bearings, HALF)


def test_floor_on_both_sides_is_reached_at_the_nearer_end_and_swept() -> None:
    """Unseen floor behind-left and behind-right: the turn covers both without going round twice."""
    bearings = list(np.radians([100.0, 140.0, 180.0, -140.0, -120.0]))
    turns = look_arc(np.array(bearings), HALF)
    assert turns is not None
    assert covered(turns, bearings, HALF)
    assert abs(turns[0]) + abs(turns[1]) < 2.0 * math.pi - 2.0 * HALF


def test_unseen_floor_behind_a_wall_is_out_of_sight() -> None:
    """Floor beyond a wall (reachable through a door) is not among the bearings to turn to."""
    data = hall()
    data[:29, 60] = 100  # a wall across at x = 3 m, a door at its north end (y 1.45-1.95 m)
    grid = grid_of(data)
    cov = ViewCoverage(view_range=2.5)
    here = Pose2D(2.0, 0.5, 0.0)
    bearings = unseen_bearings(cov, grid, here)
    cells = [k for k in cov.unseen(grid, (2.0, 0.5), radius=2.5)
             if math.hypot((k[0] + 0.5) * cov.cell - 2.0, (k[1] + 0.5) * cov.cell - 0.5) <= 2.5]
    hidden = [k for k in cells if (k[0] + 0.5) * cov.cell > 3.1 and (k[1] + 0.5) * cov.cell < 1.0]
    assert hidden  # floor behind the wall, within range and on the robot's floor
    assert 0 < len(bearings) <= len(cells) - len(hidden)
    assert np.any(np.abs(bearings) > math.radians(150.0))  # the floor behind the robot, west


def test_the_search_turns_only_part_way_where_the_floor_behind_is_unseen() -> None:
    """With the unseen floor behind the robot, the look where it stands turns well under a circle."""
    robot = CameraRobot(hall(), Pose2D(4.0, 1.0, 0.0))
    events = Events()
    leaf = Locate("locate", Locate.Params(target="red backpack", priors="none", view_window=0.0))
    leaf.setup(context=MissionContext(robot=robot, events=events, models={"detector": Detector()}))  # type: ignore[arg-type]
    assert leaf.coverage is not None
    grid = robot.occupancy()
    assert grid is not None
    for x in np.arange(4.0, 9.0, 0.5):  # the camera looked east only: the floor west of the robot is unseen
        for yaw in np.radians([-60.0, -30.0, 0.0, 30.0, 60.0]):
            for _ in range(3):
                leaf.coverage.add_view(grid, Pose2D(float(x), 1.0, float(yaw)), K.hfov)
    for _ in range(600):
        leaf.tick_once()
        if leaf.status in (Status.SUCCESS, Status.FAILURE):
            break
        robot.advance(0.1)
    looks = events.of("search_look")
    assert looks, "no look was made"
    assert all(sum(abs(t) for t in look["turns_deg"]) < 300 for look in looks), looks
    assert leaf.status == Status.FAILURE and "not found" in leaf.feedback_message


def test_a_round_ended_with_a_candidate_leaves_no_view_goals_on_the_planner() -> None:
    """Between exploration steps the planner holds no camera callbacks (its report lists frontiers only)."""
    robot = CameraRobot(hall(), Pose2D(1.0, 1.0, math.pi))
    leaf = Locate("locate", Locate.Params(target="red backpack", priors="none"))
    leaf.setup(context=MissionContext(robot=robot, events=Events(), models={"detector": Detector()}))  # type: ignore[arg-type]
    leaf.tick_once()
    planner = leaf.planner
    assert planner is not None
    assert getattr(planner, "views", "missing") is None
    assert getattr(planner, "camera_unseen", "missing") is None
