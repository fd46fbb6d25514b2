"""Fleet search bookkeeping and leaves: the first find ends it for all; 'not found' waits for the others."""

from __future__ import annotations

from typing import Any

import py_trees
import pytest

from missiontree.behaviours.fleet_scene import FleetBuildSceneGraph
from missiontree.behaviours.fleet_search import FleetFound, FleetSearchWatch, SearchBoard, search_board
from missiontree.engine.context import MissionContext
from missiontree.engine.fleet import FleetView
from missiontree.testing import clean_state
from missiontree.types import Pose2D, PoseStamped

Status = py_trees.common.Status


@pytest.fixture(autouse=True)
def _clean() -> None:
    clean_state()


class _Robot:
    def __init__(self, name: str) -> None:
        self.name = name

    def now(self) -> float:
        return 12.0

    def pose(self) -> PoseStamped:
        return PoseStamped(12.0, Pose2D(0.0, 0.0, 0.0))

    def occupancy(self) -> None:
        return None

    def rgbd(self) -> None:
        return None


class _Events:
    def __init__(self) -> None:
        self.seen: list[tuple[str, dict[str, Any]]] = []

    def emit(self, event: str, /, **fields: Any) -> None:
        self.seen.append((event, fields))


def _context(view: FleetView | None, name: str) -> MissionContext:
    return MissionContext(robot=_Robot(name), events=_Events(), fleet=view)  # type: ignore[arg-type]


def _tick(leaf: py_trees.behaviour.Behaviour) -> Status:
    for _ in leaf.tick():
        pass
    return leaf.status


def test_the_first_confirmation_is_the_find_and_a_later_one_is_recorded_beside_it() -> None:
    """confirm() is True once; the second robot's confirmation goes to also_confirmed."""
    board = SearchBoard()
    assert board.confirm("robot2", {"x": 1.0}) is True
    assert board.confirm("robot1", {"x": 1.1}) is False
    assert board.report()["found"]["robot"] == "robot2"
    assert [a["robot"] for a in board.report()["also_confirmed"]] == ["robot1"]


def test_a_robot_that_gave_up_is_no_longer_searching_and_a_lost_one_neither() -> None:
    """others_searching() leaves out robots that said not found and robots lost."""
    view = FleetView(["robot1", "robot2", "robot3"], lambda: 0.0)
    board = search_board(_context(view, "robot1"))
    assert board is not None
    for name in view.names:
        board.start(name)
    board.give_up("robot2", "not found: ...")
    assert board.others_searching("robot1") == ["robot3"]
    assert view.lose("robot3", "killed") is True  # the board takes a lost robot's search over
    assert board.others_searching("robot1") == []
    board.start("robot3")  # a lost robot does not come back
    assert board.others_searching("robot1") == []


def test_another_robots_find_ends_this_robots_search_naming_the_finder() -> None:
    """FleetSearchWatch runs until robot2's FleetFound records the find, then SUCCESS naming robot2."""
    view = FleetView(["robot1", "robot2"], lambda: 0.0)
    watch = FleetSearchWatch("others_found")
    watch.setup(context=_context(view, "robot1"))
    assert _tick(watch) is Status.RUNNING
    found = FleetFound("found")
    found.setup(context=_context(view, "robot2"))
    py_trees.blackboard.Blackboard.set(
        "/search_candidate", {"id": "backpack_1", "label": "backpack", "colour": "red", "x": 2.0, "y": 3.0})
    assert _tick(found) is Status.SUCCESS
    assert found.feedback_message == "found by robot2: red backpack at (2.00, 3.00)"
    assert _tick(watch) is Status.SUCCESS
    assert watch.feedback_message.startswith("robot2 found the red backpack at (2.00, 3.00)")


def test_the_finders_own_watch_keeps_running() -> None:
    """The robot that found it ends through its own search, not through its watch."""
    view = FleetView(["robot1", "robot2"], lambda: 0.0)
    board = search_board(_context(view, "robot1"))
    assert board is not None
    board.confirm("robot1", {"x": 0.0, "y": 0.0, "label": "cup"})
    watch = FleetSearchWatch("others_found")
    watch.setup(context=_context(view, "robot1"))
    assert _tick(watch) is Status.RUNNING


def test_without_a_fleet_the_watch_never_ends_and_a_find_still_succeeds() -> None:
    """A single robot: the watch runs on, FleetFound names the robot."""
    watch = FleetSearchWatch("others_found")
    watch.setup(context=_context(None, "robot1"))
    assert _tick(watch) is Status.RUNNING
    found = FleetFound("found")
    found.setup(context=_context(None, "robot1"))
    py_trees.blackboard.Blackboard.set("/search_candidate", {"label": "cup", "x": 1.0, "y": 1.0})
    assert _tick(found) is Status.SUCCESS and found.feedback_message.startswith("found by robot1: cup")


def test_every_robots_scene_graph_leaf_shares_one_live_scene() -> None:
    """Two robots' FleetBuildSceneGraph leaves put the same scene on both contexts; alone, each its own."""
    view = FleetView(["robot1", "robot2"], lambda: 0.0)
    params = FleetBuildSceneGraph.Params(detector="detector")  # type: ignore[call-arg]
    leaves, contexts = [], []
    for name in view.names:
        context = _context(view, name)
        context.models["detector"] = object()
        leaf = FleetBuildSceneGraph("semantic_map", params)
        leaf.setup(context=context)
        leaf.initialise()
        leaves.append(leaf)
        contexts.append(context)
    assert leaves[0].builder is leaves[1].builder
    assert contexts[0].scene is contexts[1].scene is leaves[0].builder.scene
    alone = _context(None, "robot1")
    alone.models["detector"] = object()
    single = FleetBuildSceneGraph("semantic_map", params)
    single.setup(context=alone)
    single.initialise()
    assert alone.scene is single.builder.scene and alone.scene is not contexts[0].scene
