"""The intent tree and ServeCommands: what the model says is checked; the channel is served in turn."""

from __future__ import annotations

import io
import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import py_trees
from pydantic import BaseModel

from missiontree.backends.sim import create_robot
from missiontree.behaviours.commands import ServeCommands, ServeCommandsParams
from missiontree.behaviours.intent import ReadIntent
from missiontree.engine.build import build_tree
from missiontree.engine.context import MissionContext
from missiontree.engine.loader import load_mission
from missiontree.reasoning.protocols import Message
from missiontree.reasoning.schemas import IntentResolution
from missiontree.robot.commands import LineCommands
from missiontree.session.models import build_models
from missiontree.testing import ClockRobot, capture_tick_log, fresh_plugins

REPO = Path(__file__).resolve().parents[2]
OFFICE_GRAPH = str(REPO / "config" / "scene_graphs" / "office.json")
MISSION = REPO / "trees" / "go_to_intent.yaml"


class ScriptedLanguageModel:
    """A language model that answers every intent question with the same ids (a stand-in for a wrong LLM)."""

    name = "scripted_llm"

    def __init__(self, ids: list[str]) -> None:
        self.ids = ids
        self.asked: list[str] = []

    def chat(self, messages: Sequence[Message], schema: type[BaseModel] | None = None) -> str:
        self.asked.append(messages[-1].content)
        return IntentResolution(candidates=self.ids, reason="scripted").model_dump_json()

    def check(self) -> str:
        return "scripted"


def run_tree(command: str, models: dict, robot: Any, scene_graph: str = OFFICE_GRAPH) -> tuple[str, list]:
    """trees/go_to_intent.yaml (its steps as nodes) with these models on this robot."""
    plugins = fresh_plugins()
    spec = load_mission(MISSION, plugins.nodes, params={"command": command, "scene_graph": scene_graph})
    root = build_tree(spec, plugins.nodes)
    try:
        result, log = capture_tick_log(root, MissionContext(robot=robot, models=models), max_duration=300.0)
    finally:
        robot.close()
    return result.status.value, log


def run_leaf(ids: list[str], command: str = "I am thirsty") -> tuple[str, list[dict]]:
    """The tree with a language model that names ``ids`` for any command."""
    models = build_models("offline", providers=fresh_plugins().providers)
    models["llm"] = ScriptedLanguageModel(ids)
    return run_tree(command, models, create_robot({"world": "office", "seed": 1}))


def of(log: list[dict], kind: str) -> list[dict]:
    return [e for e in log if e.get("event") == kind]


def test_ids_the_graph_lacks_are_rejected_in_the_log_and_never_driven_to() -> None:
    """The model names a made-up id and a room: both rejected with reasons; the real cup is the goal."""
    status, log = run_leaf(["exit_door_9", "room_1", "cup_white"])
    rejected = {e["object"]: e["reason"] for e in of(log, "candidate_rejected")}
    assert rejected == {"exit_door_9": "not in the scene graph", "room_1": "is a room, not an object"}
    assert [e["object"] for e in of(log, "goal_sent")] == ["cup_white"]
    assert status == "SUCCESS"


def test_only_made_up_ids_fail_with_the_reasons_and_no_goal() -> None:
    """Nothing the model named exists: FAILURE naming each id and why; never a goal."""
    status, log = run_leaf(["exit_door_9", "kitchen_exit"])
    assert status == "FAILURE" and not of(log, "goal_sent")
    reason = of(log, "command_served")[0]["reason"]
    assert "exit_door_9: not in the scene graph" in reason and "kitchen_exit" in reason


def test_goals_come_from_the_graph_not_from_the_prompt() -> None:
    """The goal sent for a candidate is a standoff pose near the graph's coordinates of that object."""
    _, log = run_leaf(["backpack_red"], command="the red backpack")
    goal = of(log, "goal_sent")[0]
    assert (goal["object_x"], goal["object_y"]) == (11.3, 1.2)
    assert 0.3 < ((goal["x"] - 11.3) ** 2 + (goal["y"] - 1.2) ** 2) ** 0.5 < 1.3


def test_serve_commands_without_a_channel_fails_with_the_reason() -> None:
    """No command given and a robot with no command channel: FAILURE saying how to give one."""
    root = ServeCommands("serve", py_trees.behaviours.Success("ok"), ServeCommandsParams(command=""))
    result, log = capture_tick_log(root, MissionContext(robot=ClockRobot()))
    assert result.status.value == "FAILURE"
    assert "no command channel" in json.dumps(log)


def test_serve_commands_takes_stdin_lines_in_turn_and_ends_with_the_stream() -> None:
    """Each stdin line is written to the blackboard and its child run once; the end of stdin ends it."""
    robot = create_robot({"world": "office", "seed": 1})
    robot.command_input = LineCommands(io.StringIO("first\n\n  second  \n"))
    seen: list[str] = []

    class Record(py_trees.behaviour.Behaviour):
        def __init__(self) -> None:
            super().__init__("record")
            self.bb = self.attach_blackboard_client("record")
            self.bb.register_key("intent_command", access=py_trees.common.Access.READ)

        def update(self) -> py_trees.common.Status:
            seen.append(self.bb.get("intent_command"))
            return py_trees.common.Status.SUCCESS

    root = ServeCommands("serve", Record(), ServeCommandsParams(command=""))
    try:
        result, log = capture_tick_log(root, MissionContext(robot=robot), max_duration=30.0)
    finally:
        robot.close()
    assert seen == ["first", "second"]
    assert [e["command"] for e in of(log, "command_served")] == ["first", "second"]
    assert result.status.value == "SUCCESS"


def test_a_weak_choice_is_never_driven_to_or_served() -> None:
    """The model sends "I'm parched" to the printer: rejected as a weak choice, no goal, FAILURE with why."""
    status, log = run_leaf(["printer_1"], command="I'm parched")
    assert status == "FAILURE" and not of(log, "intent_served") and not of(log, "goal_sent")
    [rejected] = of(log, "candidate_rejected")
    assert "weak choice" in rejected["reason"] and "printer" in rejected["reason"]
    assert "strongly enough" in of(log, "command_served")[0]["reason"]


def test_a_stronger_tier_is_driven_to_before_a_nearer_weaker_one() -> None:
    """Bored: the TV (1.0) is tried before the nearer laptop (0.7); by path only within a tier."""
    status, log = run_leaf(["laptop_1", "tv_1"], command="I am bored")
    assert status == "SUCCESS"
    assert [e["object"] for e in of(log, "goal_sent")] == ["tv_1"]


def test_a_strong_choice_nothing_can_confirm_is_served_and_says_so() -> None:
    """A printer to print a document is served unconfirmed: the record names it, why, and confirmed false."""
    status, log = run_leaf(["printer_1"], command="I need to print a document")
    [served] = of(log, "intent_served")
    assert status == "SUCCESS" and served["object"] == "printer_1" and served["confirmed"] is False
    assert served["chosen_because"] == "scripted" and "serves print (" in served["note"]
    assert "NOT confirmed" in of(log, "command_served")[0]["reason"]


def test_a_choice_read_only_by_embedding_is_driven_to_but_never_served_unconfirmed() -> None:
    """A choice read by embedding alone is driven to but, unconfirmable, fails instead of a SUCCESS.

    'I want my essay on paper' (no listed word) is read as printing: the printer is driven to, but
    nothing can confirm it, so it is doubted.
    """
    status, log = run_leaf(["printer_1"], command="I want my essay on paper")
    assert [e["object"] for e in of(log, "goal_sent")] == ["printer_1"]
    assert status == "FAILURE" and not of(log, "intent_served")
    assert "only by embedding" in of(log, "command_served")[0]["reason"]


def test_bored_goes_to_the_laptop_when_the_tv_cannot_be_reached(tmp_path: Path) -> None:
    """The offline reasoner offers the laptop tier too: the TV (no place to reach it) hands over to it."""
    graph = json.loads(Path(OFFICE_GRAPH).read_text(encoding="utf-8"))
    for node in graph["nodes"]:
        if node.get("id") == "tv_1":
            node["coordinates"] = [13.0, 4.0, 1.2]  # beyond the map's edge: no standoff pose
    path = tmp_path / "office_tv_away.json"
    path.write_text(json.dumps(graph), encoding="utf-8")
    models = build_models("offline", providers=fresh_plugins().providers)
    robot = create_robot({"world": "office", "seed": 1})
    status, log = run_tree("I am bored", models, robot, scene_graph=str(path))
    assert {e["object"] for e in of(log, "candidate_rejected")} >= {"tv_1"}
    assert [e["object"] for e in of(log, "goal_sent")] == ["laptop_1"]
    assert status == "SUCCESS"
    roles = {e.get("role") for e in of(log, "model_call")}
    assert "planner" not in roles and roles <= {"llm", "detector", "vlm"}  # ranking is map geometry


def test_a_standoff_goal_the_stack_cannot_reach_is_tried_from_another_side() -> None:
    """The first goal to the bottle aborts: the same object is approached once more from elsewhere."""
    models = build_models("offline", providers=fresh_plugins().providers)
    models["llm"] = ScriptedLanguageModel(["bottle_green"])
    robot = create_robot({"world": "office", "seed": 1})
    real = robot.navigate_to
    calls: list[object] = []

    def first_fails(goal, tolerance):  # type: ignore[no-untyped-def]
        calls.append(goal)
        if len(calls) == 1:  # a goal inside the map's outer wall: the stack proves it unreachable
            return real(type(goal)(-50.0, -50.0, goal.yaw), tolerance)
        return real(goal, tolerance)

    robot.navigate_to = first_fails  # type: ignore[method-assign]
    status, log = run_tree("I am thirsty", models, robot)
    steps = [e["attempt"] for e in of(log, "approach_step") if e["object"] == "bottle_green"]
    goals = of(log, "goal_sent")
    assert steps == [1, 2] and [g["object"] for g in goals] == ["bottle_green"] * 2
    assert math.hypot(goals[0]["x"] - goals[1]["x"], goals[0]["y"] - goals[1]["y"]) > 0.2
    assert status == "SUCCESS"


def test_on_a_live_graph_a_colour_no_object_has_sends_the_robot_to_look_at_each() -> None:
    """"The purple chair" with no purple chair listed: on a live graph every chair is to be looked at."""
    from missiontree.reasoning.intent import graph_objects
    from missiontree.reasoning.schemas import ReferenceParse
    from missiontree.semantics.scene_graph import SceneGraph

    leaf = ReadIntent("read", ReadIntent.Params(scene_graph=""))
    leaf.emit = lambda *a, **k: None  # type: ignore[method-assign]
    leaf.read = lambda *a, **k: []  # type: ignore[method-assign]
    state = {"text": "the purple chair", "file": False,
             "scene": graph_objects(SceneGraph.load(Path(OFFICE_GRAPH)))}
    answer = IntentResolution(candidates=[], reason="no purple chair in the scene",
                              reference=ReferenceParse(label="chair", attributes=["purple"]))
    ids = leaf._look_at_all(state, answer)
    assert ids and all(state["scene"].objects[i].label == "chair" for i in ids) and state["confirm_only"]
    state = {**state, "file": True, "confirm_only": False}  # a graph file is the user's word
    assert leaf._look_at_all(state, answer) == [] and not state["confirm_only"]


def test_a_live_graph_that_grew_while_candidates_failed_is_read_again() -> None:
    """The blue chair seen while looking at other chairs: the command is read again over the grown graph."""
    from types import SimpleNamespace

    from missiontree.reasoning.intent import graph_objects

    full = json.loads(Path(OFFICE_GRAPH).read_text(encoding="utf-8"))
    before = {**full, "nodes": [n for n in full["nodes"] if n.get("id") != "chair_blue"]}
    board = {"intent_state": {"text": "the blue chair", "file": False, "scene": graph_objects(before),
                              "tried": [], "seen": 0, "rereads": 0, "ids": []},
             "intent_rejected": [{"id": "chair_red", "reason": "not confirmed: red, not blue",
                                  "kind": "wrong"}]}
    written: dict[str, object] = {}
    leaf = ReadIntent("read", ReadIntent.Params(scene_graph=""))
    leaf.read = lambda port, default=None: board.get(getattr(leaf.params, port), default)  # type: ignore
    leaf.write = lambda port, value: written.__setitem__(port, value)  # type: ignore[method-assign]
    leaf.emit = lambda *a, **k: None  # type: ignore[method-assign]
    leaf.ctx = SimpleNamespace(scene=SimpleNamespace(graph=full))  # type: ignore[assignment]
    asked: list[object] = []
    leaf._ask = asked.append  # type: ignore[method-assign]
    leaf.initialise()
    assert asked == [full] and leaf.asked["rereads"] == 1
    assert leaf.asked["tried"] == [["chair_red", "not confirmed: red, not blue"]]
    assert written["doubtful"] == ["chair_red"]
