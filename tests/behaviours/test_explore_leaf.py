"""The Explore leaf on a scripted robot: blacklisting, ending, stuck, look-around, map files."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest
from patrol_doubles import Events, FakeHandle, FakeRobot

from missiontree.behaviours.explore import Explore
from missiontree.engine.context import MissionContext
from missiontree.engine.leaf import Status
from missiontree.mapping.exploration import Candidate, ExplorationPlanner
from missiontree.mapping.mapfile import read_map
from missiontree.robot.actions import ActionStatus
from missiontree.types import OccupancyGrid, Pose2D, Tolerance

RES = 0.05


def corridor_map() -> np.ndarray:
    """A corridor 6 x 1.6 m (x 0-6, y 0-1.6) with walls along its sides, open at both ends to unknown.

    Known free: x 1.5-4.5; unknown beyond on both ends.
    """
    data = np.full((32, 120), -1, np.int8)
    data[:, 30:90] = 0
    data[0, 30:90] = 100
    data[-1, 30:90] = 100
    return data


class MapRobot(FakeRobot):
    """A scripted robot with a map: goals west of ``block_x`` abort; reaching one reveals its end."""

    def __init__(self, data: np.ndarray, block_x: float | None = None, polls: int = 3) -> None:
        super().__init__()
        self.data = data
        self.block_x = block_x
        self.polls_per_goal = polls
        self.set_pose(Pose2D(3.0, 0.8, 0.0))

    def occupancy(self) -> OccupancyGrid | None:  # type: ignore[override]
        return OccupancyGrid(self.time, RES, Pose2D(0.0, 0.0), self.data.copy())

    def navigate_to(self, goal: Pose2D, tolerance: Tolerance | None = None) -> FakeHandle:
        if self.block_x is not None and goal.x < self.block_x:
            handle = FakeHandle(goal, tolerance, ActionStatus.ABORTED, "no path to it on the map", 1)
        else:
            handle = FakeHandle(goal, tolerance, ActionStatus.SUCCEEDED, "", self.polls_per_goal)
        self.goals.append(handle)
        return handle

    def reveal_east(self) -> None:
        """The east end turns out closed: free up to a wall at x 5.5."""
        self.data[1:-1, 90:110] = 0
        self.data[0, 90:110] = 100
        self.data[-1, 90:110] = 100
        self.data[:, 110] = 100


def make(robot: FakeRobot, run_dir: Path | None = None, **params: object) -> tuple[Explore, Events]:
    events = Events()
    leaf = Explore("explore", Explore.Params(**params))
    leaf.setup(context=MissionContext(robot=robot, events=events, run_dir=run_dir))
    return leaf, events


def run(leaf: Explore, robot: FakeRobot, max_ticks: int = 400, on_tick: object = None) -> int:
    """Tick every 0.1 s of robot time until the leaf ends."""
    for count in range(1, max_ticks + 1):
        leaf.tick_once()
        if on_tick is not None:
            on_tick()  # type: ignore[operator]
        if leaf.status in (Status.SUCCESS, Status.FAILURE):
            return count
        robot.advance(0.1)
    raise AssertionError(f"still {leaf.status.name} after {max_ticks} ticks: {leaf.feedback_message}")


@pytest.mark.parametrize("strategy", ["gain", "nearest"])
def test_a_frontier_the_map_proves_closed_is_given_up_and_exploring_ends_explored(strategy: str) -> None:
    """The west goal aborts and the map then shows a wall across the corridor: given up as closed, SUCCESS."""
    robot = MapRobot(corridor_map(), block_x=2.0)
    leaf, events = make(robot, strategy=strategy)

    def watch() -> None:
        if any(g.goal.x < 2.0 and g.status().done for g in robot.goals):
            robot.data[:, 50] = 100  # the west of the corridor turns out walled off at x 2.5
        if any(g.goal.x > 4.0 and g.polls <= 1 for g in robot.goals):  # arriving there: it sees the end
            robot.reveal_east()

    run(leaf, robot, on_tick=watch)
    assert leaf.status == Status.SUCCESS, leaf.feedback_message
    blacklisted = events.of("explore_blacklist")
    assert len(blacklisted) == 1 and blacklisted[0]["x"] < 2.0 and blacklisted[0]["proved_closed"]
    assert "no path to it on the map" in blacklisted[0]["reason"]
    assert "the map shows no way to it" in blacklisted[0]["reason"]
    assert len([g for g in robot.goals if g.goal.x < 2.0]) == 1  # never offered again once closed
    assert any(g.goal.x > 4.0 for g in robot.goals)
    assert "no reachable frontier worth a trip remains" in leaf.feedback_message
    assert "1 unreachable" in leaf.feedback_message
    assert leaf.bb.get("explore_complete") is True
    assert leaf.ctx is not None and leaf.ctx.outcome["exploration"]["text"].startswith("explored: ")


@pytest.mark.parametrize("strategy", ["gain", "nearest"])
def test_a_frontier_the_map_shows_open_is_retried_then_the_exploration_is_partial(strategy: str) -> None:
    """West goals abort while the map shows a way: three tries from new places, then FAILURE 'partial'."""
    robot = MapRobot(corridor_map(), block_x=2.0)
    leaf, events = make(robot, strategy=strategy)

    def reveal() -> None:
        if any(g.goal.x > 4.0 and g.polls <= 1 for g in robot.goals):
            robot.reveal_east()

    run(leaf, robot, on_tick=reveal)
    assert leaf.status == Status.FAILURE
    west = [g.goal for g in robot.goals if g.goal.x < 2.0]
    assert len(west) == 3  # max_attempts
    assert len({(round(g.x, 2), round(g.y, 2)) for g in west}) == 3  # each from another approach
    assert any(g.x < 1.5 for g in west)  # one goes through the frontier into the unknown
    assert len(events.of("explore_try_failed")) == 2
    blacklisted = events.of("explore_blacklist")
    assert len(blacklisted) == 1 and not blacklisted[0]["proved_closed"]
    message = leaf.feedback_message
    assert message.startswith("partial: 1 frontier left unexplored")
    assert "(1.5" in message and "m^2 unknown behind it" in message and "1 given up open" in message
    assert leaf.bb.get("explore_complete") is False
    left = leaf.bb.get("unexplored")
    assert len(left) == 1 and left[0]["x"] < 2.0


def test_partial_is_success_when_asked_and_still_says_partial() -> None:
    """With partial_is_success the same run ends SUCCESS, its reason still starting 'partial:'."""
    robot = MapRobot(corridor_map(), block_x=2.0)
    leaf, _ = make(robot, partial_is_success=True)

    def reveal() -> None:
        if any(g.goal.x > 4.0 and g.polls <= 1 for g in robot.goals):
            robot.reveal_east()

    run(leaf, robot, on_tick=reveal)
    assert leaf.status == Status.SUCCESS
    assert leaf.feedback_message.startswith("partial:")
    assert leaf.bb.get("explore_complete") is False
    assert leaf.ctx is not None  # summary.json's outcome says partial, whatever the status
    reported = leaf.ctx.outcome["exploration"]
    assert reported["outcome"] == "partial" and not reported["complete"]
    assert reported["text"].startswith("exploration partial: 1 frontier(s) left")


def test_goals_keep_clear_of_walls_and_unknown_cells() -> None:
    """A goal is sent to known free space with the robot's clearance, not onto the frontier's edge."""
    robot = MapRobot(corridor_map())
    leaf, _ = make(robot, footprint_radius=0.2)
    leaf.tick_once()
    goal = robot.goals[0].goal
    r, c = int(goal.y / RES), int(goal.x / RES)
    k = int(math.ceil(0.3 / RES)) - 1
    assert (robot.data[r - k:r + k + 1, c - k:c + k + 1] == 0).all()
    assert robot.goals[0].tolerance is not None and robot.goals[0].tolerance.yaw >= 2 * math.pi - 1e-9


def test_no_map_fails_with_a_reason_after_the_timeout() -> None:
    """With no free cell in the map the leaf waits map_timeout seconds, then fails saying why."""
    robot = MapRobot(np.full((10, 10), -1, np.int8))
    leaf, _ = make(robot, map_timeout=2.0)
    run(leaf, robot)
    assert leaf.status == Status.FAILURE
    assert "no map with free space" in leaf.feedback_message
    assert robot.time >= 2.0 and robot.goals == []


def test_stuck_robot_fails_when_nothing_changes() -> None:
    """Goals that never end while the robot stands still and the map stays the same end in FAILURE."""
    robot = MapRobot(corridor_map(), polls=10**9)
    leaf, _ = make(robot, stuck_timeout=5.0, no_progress_timeout=1000.0)
    run(leaf, robot)
    assert leaf.status == Status.FAILURE
    assert leaf.feedback_message.startswith("stuck:")
    assert robot.goals[-1].cancelled  # the goal was cancelled when the leaf ended


def test_look_around_turns_a_full_circle_at_a_goal_reached() -> None:
    """With look_around, reaching a goal turns the robot 2 pi (by drive) before the next goal goes out."""
    data = corridor_map()
    data[:, :30] = 100  # the west end is a wall: one frontier left
    robot = MapRobot(data)
    leaf, events = make(robot, look_around=True, look_steps=4, look_pause=0.2, turn_speed=1.0)
    looks: list[list[float]] = []  # heading change during each look-around
    was_looking = [False]

    def watch() -> None:
        looking = leaf.state == "look"
        if looking and not was_looking[0]:
            looks.append([robot.current.yaw])
        if looking:
            looks[-1].append(robot.current.yaw)
        elif looks:
            robot.reveal_east()
        was_looking[0] = looking

    run(leaf, robot, on_tick=watch)
    assert events.of("explore_reached")
    assert looks
    for yaws in looks:
        assert yaws[-1] - yaws[0] == pytest.approx(2 * math.pi, abs=0.15)
    assert any(v == 0.0 and w == 0.0 for v, w in robot.drives)  # paused between the steps
    assert robot.drives[-1] == (0.0, 0.0)


def test_a_frontier_reached_and_looked_around_from_that_stays_unknown_is_a_failed_try() -> None:
    """With look_around, a frontier still unknown after the look is a failed try; three end it partial."""
    data = corridor_map()
    data[:, :30] = 100  # the west end is a wall; the east end never reveals (the lidar cannot see in)
    robot = MapRobot(data)
    leaf, events = make(robot, look_around=True, look_steps=4, look_pause=0.0, turn_speed=2.0)
    run(leaf, robot, max_ticks=2000)
    tries = events.of("explore_try_failed") + events.of("explore_blacklist")
    assert any("looked around" in e["reason"] for e in tries)
    assert len(events.of("explore_reached")) == 3  # three tries, then given up: not looked from forever
    assert leaf.status == Status.FAILURE and leaf.feedback_message.startswith("partial: ")


def test_learned_map_is_written_into_the_run_directory(tmp_path: Path) -> None:
    """When the leaf ends, map.pgm + map.yaml (map_server format) hold the map it explored."""
    data = corridor_map()
    data[:, :30] = 100
    data[:, 90:] = 100
    robot = MapRobot(data)
    leaf, events = make(robot, run_dir=tmp_path)
    run(leaf, robot)
    assert leaf.status == Status.SUCCESS  # nothing left to explore
    assert (tmp_path / "map.pgm").is_file()
    back = read_map(tmp_path / "map.yaml")
    np.testing.assert_array_equal(back.data, data)
    assert events.of("map_saved")[0]["path"] == str(tmp_path / "map.yaml")
    assert leaf.bb.get("map_yaml") == str(tmp_path / "map.yaml")
    assert leaf.bb.get("explored_area") == pytest.approx(data.size * RES * RES)


def test_exploration_json_says_how_it_ended(tmp_path: Path) -> None:
    """exploration.json beside the map: 'explored' and complete after a full run, nothing left."""
    data = corridor_map()
    data[:, :30] = 100
    data[:, 90:] = 100
    robot = MapRobot(data)
    leaf, _ = make(robot, run_dir=tmp_path)
    run(leaf, robot)
    report = json.loads((tmp_path / "exploration.json").read_text())
    assert report["outcome"] == "explored" and report["complete"] is True
    assert report["frontiers_left"] == [] and report["unknown_left_m2"] == 0.0


def test_a_frontier_whose_edge_moves_a_little_keeps_its_goal() -> None:
    """The far edge of a frontier flickering 0.4 m in the scans is no reason to send another goal."""
    robot = MapRobot(corridor_map(), polls=60)
    robot.data[:, 0:30] = 100                       # the west end known closed: one frontier, east
    leaf, _ = make(robot, strategy="nearest")
    for _ in range(5):
        leaf.tick_once()
        robot.advance(0.1)
    assert len(robot.goals) == 1 and robot.goals[0].goal.x > 3.5
    robot.data[1:-1, 90:98] = 0                     # the edge seen 0.4 m further east
    for _ in range(40):                             # two replan periods
        leaf.tick_once()
        robot.advance(0.1)
    assert len(robot.goals) == 1, [(round(g.goal.x, 2), round(g.goal.y, 2)) for g in robot.goals]


class SeesawPlanner(ExplorationPlanner):
    """A planner whose two frontiers, west and east, take turns at scoring clearly best, never seen."""

    def candidates(self, grid: OccupancyGrid, robot_xy: tuple[float, float],
                   ignore_blacklist: bool = False) -> list[Candidate]:
        self.calls = getattr(self, "calls", 0) + 1
        west = Candidate(2.0, 0.8, "frontier", 10, 5.0, 1.0, 5.0, (1.6, 0.8))
        east = Candidate(4.0, 0.8, "frontier", 10, 5.0, 1.0, 5.0, (4.4, 0.8))
        low = [dataclasses.replace(c, score=1.0) for c in (west, east)]
        return [west, low[1]] if self.calls % 2 else [east, low[0]]

    def still_frontier(self, grid: OccupancyGrid, x: float, y: float, radius: float = 0.3) -> bool:
        return True


def test_a_place_left_for_a_better_one_is_not_switched_back_to() -> None:
    """Two frontiers taking turns at scoring best: the robot switches once, not back and forth."""
    robot = MapRobot(corridor_map(), polls=10_000)

    class Seesaw(Explore):
        def make_planner(self) -> ExplorationPlanner:
            return SeesawPlanner(**self.planner_options())

    events = Events()
    leaf = Seesaw("explore", Explore.Params(strategy="gain"))
    leaf.setup(context=MissionContext(robot=robot, events=events, run_dir=None))
    for _ in range(300):                            # 30 s: 15 replans
        leaf.tick_once()
        robot.advance(0.1)
    assert len(robot.goals) == 2, [(round(g.goal.x, 2), round(g.goal.y, 2)) for g in robot.goals]


class FlickerPlanner(ExplorationPlanner):
    """A planner whose one frontier reads seen at every check yet is offered again each time."""

    def candidates(self, grid: OccupancyGrid, robot_xy: tuple[float, float],
                   ignore_blacklist: bool = False) -> list[Candidate]:
        return [Candidate(4.0, 0.8, "frontier", 10, 5.0, 1.0, 5.0, (4.4, 0.8))]

    def still_frontier(self, grid: OccupancyGrid, x: float, y: float, radius: float = 0.3) -> bool:
        return False


def test_a_flickering_frontier_is_gone_to_instead_of_being_sent_again_and_again() -> None:
    """A frontier that reads seen, then is offered again, is left twice at most; then the robot goes there."""
    robot = MapRobot(corridor_map(), polls=10_000)

    class Flicker(Explore):
        def make_planner(self) -> ExplorationPlanner:
            return FlickerPlanner(**self.planner_options())

    leaf = Flicker("explore", Explore.Params(strategy="gain"))
    leaf.setup(context=MissionContext(robot=robot, events=Events(), run_dir=None))
    for _ in range(300):                            # 30 s: 15 replans
        leaf.tick_once()
        robot.advance(0.1)
    assert len(robot.goals) == 3


@pytest.mark.parametrize(("res", "expected"), [(0.05, 0.27), (0.03, 0.23)])
def test_reachability_is_judged_with_the_navigators_footprint_on_the_maps_resolution(res: float,
                                                                                     expected: float) -> None:
    """The body padded by two cells of the map: on a 3 cm map gaps of 0.46-0.54 m count as open."""

    class FineRobot(MapRobot):
        def occupancy(self) -> OccupancyGrid | None:  # type: ignore[override]
            return OccupancyGrid(self.time, res, Pose2D(0.0, 0.0), self.data.copy())

    robot = FineRobot(corridor_map())
    leaf, _ = make(robot)
    leaf.tick_once()
    assert leaf.planner is not None and leaf.planner.reach_radius == pytest.approx(expected)
    fixed, _ = make(FineRobot(corridor_map()), nav_footprint_radius=0.3)
    fixed.tick_once()
    assert fixed.planner is not None and fixed.planner.reach_radius == pytest.approx(0.3)


def test_a_spent_time_budget_cancels_the_goal_and_ends_partial_naming_what_is_left(tmp_path: Path) -> None:
    """Frontiers still open when the robot-time budget is spent: goal cancelled, FAILURE, json partial."""
    robot = MapRobot(corridor_map(), polls=1000)  # goals never arrive: the budget ends the run
    leaf, _ = make(robot, run_dir=tmp_path, time_budget=1.0)
    ticks = run(leaf, robot)
    assert leaf.status == Status.FAILURE
    assert leaf.feedback_message.startswith("partial: the time budget of 1 s was spent: 2 frontiers left")
    assert "m^2 unknown behind them" in leaf.feedback_message and "m^2 known" in leaf.feedback_message
    assert 10 <= ticks <= 12  # 1 s of robot time at 0.1 s a tick
    assert robot.goals and all(g.cancelled for g in robot.goals)
    report = json.loads((tmp_path / "exploration.json").read_text())
    assert report["outcome"] == "partial" and report["complete"] is False and report["time_budget_s"] == 1.0
    assert len(report["frontiers_left"]) == 2 and report["unknown_left_m2"] > 0
    assert leaf.ctx is not None and "time budget of 1 s was spent" in leaf.ctx.outcome["exploration"]["text"]


def test_no_time_budget_by_default_explores_to_the_end() -> None:
    """Without a time_budget a run longer than any small budget still ends 'explored'."""
    data = corridor_map()
    data[:, :30] = 100
    robot = MapRobot(data, polls=50)
    leaf, _ = make(robot)

    def watch() -> None:
        if any(g.goal.x > 4.0 and g.polls <= 1 for g in robot.goals):
            robot.reveal_east()

    run(leaf, robot, on_tick=watch)
    assert leaf.status == Status.SUCCESS and robot.time > 4.0, leaf.feedback_message


def test_a_small_sim_world_ends_partial_when_its_time_budget_is_spent(tmp_path: Path) -> None:
    """On the simulator from no map, a 3 s budget ends FAILURE 'time budget'; exploration.json: partial."""
    from missiontree.session import MissionRequest, Session

    pytest.importorskip("missiontree.backends.sim")
    world = tmp_path / "two_rooms.yaml"
    world.write_text(json.dumps({
        "name": "two_rooms", "robot": {"profile": "turtlebot4", "start": {"x": 1.0, "y": 2.0, "yaw": 0.0}},
        "walls": {"polygons": [[[0.0, 0.0], [8.0, 0.0], [8.0, 4.0], [0.0, 4.0]]],
                  "segments": [[[4.0, 1.2], [4.0, 4.0]], [[4.0, 0.0], [4.0, 0.1]]]}}))
    mission = tmp_path / "explore.yaml"
    mission.write_text(json.dumps({
        "version": 1, "run": {"backend": "sim", "map": "unknown", "tick_hz": 10},
        "root": {"Explore": {"name": "explore", "time_budget": 3.0}}}))
    request = MissionRequest(mission=mission, world=str(world), seed=1, unknown_map=True, max_duration=60,
                             out=tmp_path / "run", handle_signals=False, quiet=True,
                             config={"camera": {"rate": 0.5, "width": 64, "height": 48}})
    with Session.open(request) as session:
        result = session.run()
        elapsed = session.robot.now()
    assert result.status.name == "FAILURE", result.summary
    assert elapsed < 10.0  # robot seconds: ended by the budget, not the run's limit
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert "time budget" in json.dumps(summary)
    report = json.loads((tmp_path / "run" / "exploration.json").read_text())
    assert report["outcome"] == "partial" and report["time_budget_s"] == 3.0 and report["frontiers_left"]
