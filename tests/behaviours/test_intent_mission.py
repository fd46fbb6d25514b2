"""trees/go_to_intent.yaml end to end on the simulator: intuitive, referential, failover, stdin."""

from __future__ import annotations

import io
import json
import math
from pathlib import Path

from missiontree.robot.commands import LineCommands
from missiontree.session import MissionRequest, Session

REPO = Path(__file__).resolve().parents[2]
MISSION = REPO / "trees" / "go_to_intent.yaml"
OFFICE_GRAPH = REPO / "config" / "scene_graphs" / "office.json"


def run(params: dict, stdin: str | None = None) -> tuple[str, list[dict], object]:
    log = io.StringIO()
    request = MissionRequest(mission=MISSION, params=params, quiet=True, log_stream=log, handle_signals=False,
                             max_duration=300)
    with Session.open(request) as session:
        if stdin is not None:
            session.robot.command_input = LineCommands(io.StringIO(stdin))
        result = session.run()
        final = session.robot.truth.robot_pose()
    events = [json.loads(line) for line in log.getvalue().splitlines() if line.strip()]
    return result.status.value, events, final


def of(events: list[dict], kind: str) -> list[dict]:
    return [e for e in events if e.get("event") == kind]


def test_an_intuitive_command_ends_at_a_confirmed_drink() -> None:
    """"I'm thirsty": the nearest drink by path is driven to, seen and confirmed; the robot stands by it."""
    status, events, final = run({"command": "I'm thirsty"})
    assert status == "SUCCESS"
    verified = of(events, "object_found")
    assert verified and verified[0]["id"] in {"bottle_pink", "cup_white"}
    goal = of(events, "goal_sent")[0]
    assert math.hypot(final.x - goal["object_x"], final.y - goal["object_y"]) < 1.0


def test_a_referential_command_resolves_the_relation() -> None:
    """"the laptop in front of the sofa" goes to laptop_1, confirmed by looking."""
    status, events, _ = run({"command": "Find the laptop in front of the sofa"})
    assert status == "SUCCESS"
    assert [e["object"] for e in of(events, "goal_sent")] == ["laptop_1"]


def test_nothing_satisfies_fails_with_the_reason_and_no_goal(tmp_path: Path) -> None:
    """A purple backpack is not in the graph: FAILURE with the model's reason, no goal ever sent."""
    status, events, _ = run({"command": "bring me the purple backpack"})
    assert status == "FAILURE" and not of(events, "goal_sent")
    assert "nothing in the map satisfies" in of(events, "command_served")[0]["reason"]


def test_an_object_not_seen_on_arrival_is_doubted_and_the_next_candidate_tried(tmp_path: Path) -> None:
    """A bottle the graph puts on empty floor is looked for twice, marked doubtful, and a cup is next."""
    graph = json.loads(OFFICE_GRAPH.read_text())
    for node in graph["nodes"]:
        if node["id"] == "bottle_pink":
            node["coordinates"] = [1.3, 5.4, 0.0]
    path = tmp_path / "moved.json"
    path.write_text(json.dumps(graph))
    status, events, _ = run({"command": "I'm thirsty", "scene_graph": str(path)})
    doubted = [e for e in of(events, "candidate_rejected") if e.get("kind") == "wrong"]
    assert doubted and doubted[0]["object"] == "bottle_pink"
    places = [e["attempt"] for e in of(events, "approach_step") if e["object"] == "bottle_pink"]
    assert places == [1, 2] and "second place" in doubted[0]["reason"]
    sent = of(events, "goal_sent")
    goals = [e["object"] for e in sent]
    assert goals[:2] == ["bottle_pink", "bottle_pink"] and len(goals) >= 3 and goals[2] != "bottle_pink"
    first, second = sent[0], sent[1]
    assert math.hypot(first["x"] - second["x"], first["y"] - second["y"]) > 0.2   # another place to look from
    assert status == "SUCCESS"


def test_commands_from_stdin_are_served_in_turn() -> None:
    """Without `command` the mission serves each stdin line, then ends when stdin ends."""
    status, events, _ = run({"command": ""}, stdin="I want the grey backpack\nI'm searching the blue chair\n")
    served = of(events, "command_served")
    assert [s["command"] for s in served] == ["I want the grey backpack", "I'm searching the blue chair"]
    assert [s["status"] for s in served] == ["success", "success"]
    assert status == "SUCCESS"


def test_an_ambiguous_reference_goes_to_the_nearest_and_says_so() -> None:
    """"the chair" with five chairs: the log says it is ambiguous; the first goal is the nearest by path."""
    status, events, _ = run({"command": "the chair"})
    [note] = of(events, "intent_ambiguous")
    ranked = of(events, "candidates_ranked")[0]["candidates"]
    first = of(events, "goal_sent")[0]["object"]
    assert "ambiguous: 5 chairs fit" in note["note"] and first in note["note"]
    assert first == min(ranked, key=lambda c: c["path_length"])["id"]
    assert status == "SUCCESS"


def test_an_object_no_model_can_see_is_reached_and_reported_unverifiable() -> None:
    """The detector knows no printer: the robot goes to it and says it could not confirm it (not doubted)."""
    status, events, final = run({"command": "I need to print a document"})
    [unverifiable] = of(events, "object_unverifiable")
    assert unverifiable["object"] == "printer_1" and "knows no printer" in unverifiable["reason"]
    assert not of(events, "candidate_rejected") and status == "SUCCESS"
    assert math.hypot(final.x - 10.2, final.y - 0.4) < 1.3


def test_each_command_outcome_is_written_to_the_run_directory(tmp_path: Path) -> None:
    """intent_served.json lists each command: the served object, why and confirmed; the unserved, why not."""
    log = io.StringIO()
    request = MissionRequest(mission=MISSION, params={"command": ""}, quiet=True, log_stream=log,
                             handle_signals=False, max_duration=300, out=tmp_path)
    with Session.open(request) as session:
        lines = "I need to print a document\nbring me a unicorn\n"
        session.robot.command_input = LineCommands(io.StringIO(lines))
        session.run()
    served, unserved = json.loads((tmp_path / "intent_served.json").read_text(encoding="utf-8"))
    assert served["status"] == "served" and served["object"] == "printer_1" and served["confirmed"] is False
    assert "print" in served["chosen_because"]
    assert unserved["status"] == "not served" and "unicorn" in unserved["reason"]


def test_summary_outcome_says_what_was_served_why_and_what_was_not(tmp_path: Path) -> None:
    """summary.json's outcome.intent lists each command: object, label, score, confirmed; or why not."""
    request = MissionRequest(mission=MISSION, params={"command": ""}, quiet=True, log_stream=io.StringIO(),
                             handle_signals=False, max_duration=300, out=tmp_path)
    with Session.open(request) as session:
        lines = "I need to print a document\nbring me a unicorn\n"
        session.robot.command_input = LineCommands(io.StringIO(lines))
        session.run()
    outcome = json.loads((tmp_path / "summary.json").read_text(encoding="utf-8"))["outcome"]["intent"]
    served, unserved = outcome["commands"]
    assert outcome["served"] == 1 and outcome["not_served"] == 1
    assert (served["object"], served["label"], served["confirmed"]) == ("printer_1", "printer", False)
    assert served["score"] >= 0.7 and "print" in served["score_because"] and served["chosen_because"]
    assert unserved["status"] == "not served" and "unicorn" in unserved["reason"]
