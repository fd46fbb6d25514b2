"""The search's second chances: goals given up on a half-learned map, unreached candidates, cramped poses."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import pytest
from patrol_doubles import Events, FakeHandle, FakeRobot
from pydantic import BaseModel

from missiontree.behaviours.approach_steps import SAME_PLACE, standoff_goal
from missiontree.behaviours.search_locate import Locate
from missiontree.behaviours.search_resume import NUDGE_M, ResumeExplore, _with_room, clearance_map
from missiontree.engine.context import MissionContext
from missiontree.engine.leaf import Status
from missiontree.mapping.exploration import Candidate
from missiontree.reasoning.calls import CALLER_KEY, ModelCaller
from missiontree.reasoning.intent import GraphObject
from missiontree.reasoning.protocols import Message
from missiontree.reasoning.search_priors import Target, room_priors
from missiontree.robot.actions import ActionStatus
from missiontree.types import OccupancyGrid, Pose2D, Tolerance

RES = 0.05


def corridor_map() -> np.ndarray:
    """A corridor 6 x 1.6 m with walls along its sides; known free x 1.5-4.5, unknown beyond both ends."""
    data = np.full((32, 120), -1, np.int8)
    data[:, 30:90] = 0
    data[0, 30:90] = 100
    data[-1, 30:90] = 100
    return data


class MapRobot(FakeRobot):
    """A scripted robot with a map: goals west of ``block_x`` abort."""

    def __init__(self, data: np.ndarray, block_x: float) -> None:
        super().__init__()
        self.data = data
        self.block_x = block_x
        self.set_pose(Pose2D(3.0, 0.8, 0.0))

    def occupancy(self) -> OccupancyGrid | None:  # type: ignore[override]
        return OccupancyGrid(self.time, RES, Pose2D(0.0, 0.0), self.data.copy())

    def navigate_to(self, goal: Pose2D, tolerance: Tolerance | None = None) -> FakeHandle:
        if goal.x < self.block_x:
            handle = FakeHandle(goal, tolerance, ActionStatus.ABORTED, "no path to it on the map", 1)
        else:
            handle = FakeHandle(goal, tolerance, ActionStatus.SUCCEEDED, "", 3)
        self.goals.append(handle)
        return handle


def explore(
    robot: MapRobot, on_tick: object = None, leaf: ResumeExplore | None = None, **params: object
) -> tuple[ResumeExplore, Events]:
    events = Events()
    leaf = leaf or ResumeExplore("explore", ResumeExplore.Params(**params))
    leaf.setup(context=MissionContext(robot=robot, events=events))
    for _ in range(600):
        leaf.tick_once()
        if on_tick is not None:
            on_tick()  # type: ignore[operator]
        if leaf.status in (Status.SUCCESS, Status.FAILURE):
            return leaf, events
        robot.advance(0.1)
    raise AssertionError(f"still {leaf.status.name}: {leaf.feedback_message}")


def close_east(robot: MapRobot) -> None:
    if any(g.goal.x > 4.0 and g.polls <= 1 for g in robot.goals):
        robot.data[1:-1, 90:110] = 0
        robot.data[0, 90:110] = 100
        robot.data[-1, 90:110] = 100
        robot.data[:, 110] = 100


def grow_west(robot: MapRobot) -> None:
    """Half a metre more of the corridor seen past its west end: the frontier stays where it was given up."""
    robot.data[1:-1, 20:30] = 0
    robot.data[0, 20:30] = 100
    robot.data[-1, 20:30] = 100


def test_a_goal_the_map_shows_a_way_to_is_tried_by_explore_then_left_partial() -> None:
    """West aborts while the map shows a way: Explore's own three tries, then 'partial:'; no fourth west goal.

    (Explore now retries such a goal from other approaches itself; ResumeExplore's retry of a goal
    whose surroundings grew comes after those and adds none here.)
    """
    robot = MapRobot(corridor_map(), block_x=2.0)

    def tick() -> None:
        close_east(robot)
        if leaf.given_up:  # seen past the west end after it was given up
            grow_west(robot)

    robot.set_pose(Pose2D(2.3, 0.8, 0.0))  # nearer the west end: tried (and given up) first
    leaf = ResumeExplore("explore", ResumeExplore.Params(retry_growth=0.5))
    leaf, events = explore(robot, tick, leaf=leaf)
    assert leaf.status == Status.FAILURE and leaf.feedback_message.startswith("partial:")
    west = [g for g in robot.goals if g.goal.x < 2.0]
    assert len(west) == 3  # Explore's max_attempts, then left open


def test_a_goal_left_open_is_not_offered_again_while_the_map_around_it_is_unchanged() -> None:
    """An unchanged map: after Explore's tries, no retry of ResumeExplore's own."""
    robot = MapRobot(corridor_map(), block_x=2.0)
    leaf, events = explore(robot, lambda: close_east(robot))
    assert leaf.status == Status.FAILURE and leaf.feedback_message.startswith("partial:")
    assert not events.of("explore_retry")
    assert len([g for g in robot.goals if g.goal.x < 2.0]) == 3


def test_the_report_setting_gives_goals_up_for_good() -> None:
    robot = MapRobot(corridor_map(), block_x=2.0)

    def tick() -> None:
        close_east(robot)
        if any(g.goal.x < 2.0 for g in robot.goals):
            grow_west(robot)

    leaf, events = explore(robot, tick, retry_grown=False, retry_growth=0.5)
    assert leaf.status == Status.FAILURE and leaf.feedback_message.startswith("partial:")
    assert not events.of("explore_retry")
    assert len([g for g in robot.goals if g.goal.x < 2.0]) == 3


def room_grid() -> OccupancyGrid:
    """A known 4 x 4 m room (walls one cell thick) with a box obstacle at (2.0, 2.0)."""
    data = np.zeros((80, 80), np.int8)
    data[0, :] = data[-1, :] = data[:, 0] = data[:, -1] = 100
    data[38:42, 38:42] = 100
    return OccupancyGrid(0.0, RES, Pose2D(0.0, 0.0), data)


def test_a_frontier_goal_beside_an_obstacle_is_moved_to_where_the_robot_has_room() -> None:
    grid = room_grid()
    clear = clearance_map(grid)
    cramped = Candidate(2.0, 1.8, "frontier", 10, 5.0, 2.0, 1.0, (2.0, 1.5))
    moved = _with_room(cramped, grid, clear, room=0.3)
    assert (moved.x, moved.y) != (cramped.x, cramped.y)
    r, c = grid.world_to_cell(moved.x, moved.y)
    assert clear[r, c] >= 0.3 and math.hypot(moved.x - 2.0, moved.y - 1.8) <= NUDGE_M + RES
    assert moved.target == cramped.target and moved.score == cramped.score
    roomy = Candidate(1.0, 1.0, "frontier", 10, 5.0, 2.0, 1.0, (1.0, 0.5))
    assert _with_room(roomy, grid, clear, room=0.3) is roomy
    scan_point = Candidate(2.0, 1.8, "scan_point", 10, 0.0, 2.0, 1.0, (2.0, 1.8))
    assert _with_room(scan_point, grid, clear, room=0.3) is scan_point  # the report's points stay


def test_a_standoff_pose_not_reached_is_followed_by_another_place() -> None:
    grid = room_grid()
    obj = GraphObject("bag", "backpack", xy=(2.0, 2.0), z=0.2)
    robot = Pose2D(0.6, 0.6, 0.0)
    first, why = standoff_goal(obj, grid, robot, 0.17, None, [])
    assert first is not None, why
    second, why = standoff_goal(obj, grid, robot, 0.27, None, [first])
    assert second is not None, why
    assert math.hypot(second.x - first.x, second.y - first.y) >= SAME_PLACE
    # facing the object from there
    assert abs(math.atan2(2.0 - second.y, 2.0 - second.x) - second.yaw) < 1e-6


def ranked(leaf: Locate, rejected: list[dict[str, object]]) -> int:
    entry = {"id": "bag_1", "label": "backpack", "colour": "red", "x": 2.0, "y": 2.0}
    return leaf._ranked(entry, rejected, (0.0, 0.0), with_mismatch=False)[0]


def test_an_unreached_candidate_comes_back_once_when_nothing_is_left_to_explore() -> None:
    leaf = Locate("locate", Locate.Params(target="red backpack"))
    leaf.goal = Target("red backpack", "backpack", ("red",))
    unreached = [{"id": "bag_1", "label": "backpack", "x": 2.0, "y": 2.0, "kind": "unreached"}]
    wrong = [{"id": "bag_1", "label": "backpack", "x": 2.0, "y": 2.0, "kind": "wrong"}]
    assert ranked(leaf, unreached) == -1  # exploring on first
    assert ranked(leaf, wrong) == -1
    assert ranked(leaf, []) == 0
    leaf.exhausted = True
    assert ranked(leaf, unreached) == 0
    assert ranked(leaf, wrong) == -1  # looked at and not it: never again
    older = [{"id": "other", "label": "backpack", "x": 2.1, "y": 2.0}]  # no kind: wrong
    assert ranked(leaf, older) == -1
    leaf.offered_again.add("bag_1")
    assert ranked(leaf, unreached) == -1  # once only


def test_once_nothing_is_left_only_objects_of_a_doubtful_other_colour_are_looked_at() -> None:
    leaf = Locate("locate", Locate.Params(target="red backpack"))
    leaf.goal = Target("red backpack", "backpack", ("red",))
    leaf.exhausted = True

    def rank(colour: str, frames: int) -> int:
        entry = {"id": "b", "label": "backpack", "colour": colour, "x": 1.0, "y": 1.0, "observations": frames}
        return leaf._ranked(entry, [], (0.0, 0.0), with_mismatch=True)[0]

    assert rank("red", 100) == 0
    assert rank("unknown", 100) == 1
    assert rank("blue", 3) == 2  # seen blue in a few frames: may be misread, look closer
    assert rank("blue", 100) == -1  # blue over a hundred frames: not the red one


class Detector:
    """Only its class list is read (the target phrase against the detector's classes)."""

    labels = ["backpack", "cup", "bottle"]


class ScriptedLLM:
    """A language model that answers every question with ``answer`` and keeps the questions."""

    name = "scripted_llm"

    def __init__(self, answer: str) -> None:
        self.answer = answer
        self.asked: list[str] = []

    def chat(self, messages: Sequence[Message], schema: type[BaseModel] | None = None) -> str:
        self.asked.append(messages[-1].content)
        return self.answer


def locate_with(llm: ScriptedLLM | None, target: str = "cup") -> tuple[Locate, Events]:
    robot = MapRobot(corridor_map(), block_x=-1.0)
    events = Events()
    models: dict[str, object] = {"detector": Detector()}
    if llm is not None:
        models["llm"] = llm
    models[CALLER_KEY] = ModelCaller(robot.now, events, simulated=True, models=models)
    leaf = Locate("locate", Locate.Params(target=target, priors="model"))
    leaf.setup(context=MissionContext(robot=robot, models=models, events=events))
    for _ in range(5):
        leaf.tick_once()
        robot.advance(0.1)
    leaf.stop(Status.INVALID)
    return leaf, events


def test_the_language_model_ranks_the_rooms_when_priors_come_from_the_model() -> None:
    llm = ScriptedLLM('{"rooms": ["bathroom", "kitchen"], "reason": "cups are rinsed"}')
    leaf, events = locate_with(llm)
    assert len(llm.asked) == 1 and "cup" in llm.asked[0] and "kitchen" in llm.asked[0]
    [used] = events.of("search_priors")
    assert used["source"] == "model"
    assert leaf.priors == {"bathroom": 1.0, "kitchen": 0.8}
    assert any(e["role"] == "llm" and e["outcome"] == "succeeded" for e in events.of("model_call"))


@pytest.mark.parametrize(
    ("answer", "why"),
    [
        ("the kitchen, I think", "JSON"),  # not JSON, twice (asked again once with the error)
        ('{"rooms": ["garage", "attic"]}', "no known room type"),  # checked, but off the list
    ],
)
def test_a_malformed_ranking_keeps_the_offline_table(answer: str, why: str) -> None:
    llm = ScriptedLLM(answer)
    leaf, events = locate_with(llm)
    [used] = events.of("search_priors")
    assert used["source"] == "offline" and why in used["reason"]
    assert leaf.priors == room_priors("cup") and max(leaf.priors, key=leaf.priors.get) == "kitchen"
    assert leaf.status == Status.INVALID  # halted by the test, never failed by the answer


def test_no_language_model_configured_keeps_the_offline_table() -> None:
    leaf, events = locate_with(None)
    [used] = events.of("search_priors")
    assert used["source"] == "offline" and "no model configured for role 'llm'" in used["reason"]
    assert leaf.priors == room_priors("cup")


def test_the_reports_scan_points_split_the_office_at_its_door() -> None:
    """The report's scan points (ResumeExplore's) cut the office's two rooms apart: more than one round."""
    from missiontree.backends.sim import load_world

    world = load_world("office")
    leaf = ResumeExplore("moving_to_scan", ResumeExplore.Params(strategy="scan_points", max_goals=1))
    planner = leaf.make_planner()
    points = planner.candidates(world.grid, (world.start.x, world.start.y))
    assert len(points) >= 2


def test_an_unreached_candidate_comes_back_once_the_map_reached_it_without_waiting_for_the_end() -> None:
    """Seen in unmapped space and not reached: offered again as soon as the map around it is known."""
    leaf = Locate("locate", Locate.Params(target="red backpack"))
    leaf.goal = Target("red backpack", "backpack", ("red",))
    data = np.full((80, 80), -1, np.int8)
    data[:, :20] = 0  # known only west of x = 1 m; the backpack at (2, 2) lies in unknown space
    leaf.last_grid = OccupancyGrid(0.0, RES, Pose2D(0.0, 0.0), data)
    unreached = [{"id": "bag_1", "label": "backpack", "x": 2.0, "y": 2.0, "kind": "unreached"}]
    assert ranked(leaf, unreached) == -1  # exploring on: nothing known there yet
    data2 = data.copy()
    data2[20:60, 20:60] = 0  # the robot mapped the place
    leaf.last_grid = OccupancyGrid(1.0, RES, Pose2D(0.0, 0.0), data2)
    entry = {"id": "bag_1", "label": "backpack", "colour": "red", "x": 2.0, "y": 2.0}
    rank, _, offered = leaf._ranked(entry, unreached, (0.0, 0.0), with_mismatch=False)
    assert rank == 0 and "grown" in offered
    leaf._found(dict(offered, source="semantic map"))
    assert ranked(leaf, unreached) == -1  # the map has not grown since it was offered again
