"""The replay reader: node states, blackboard, events and the ending at any tick."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from runlog_helpers import read_lines, statuses_by_replaying

from missiontree.engine.tick_log import read_records
from missiontree.errors import ConfigError
from missiontree.runlog.replay import KEYFRAME_EVERY, Replay, event_category, open_run

TREE = {
    "path": "main",
    "name": "main",
    "type": "Sequence",
    "category": "composite",
    "params": {"memory": True},
    "source": "m.yaml:3:3",
    "children": [
        {
            "path": "main/go",
            "name": "go",
            "type": "GoTo",
            "category": "leaf",
            "params": {"x": 1.0},
            "source": "m.yaml:6:7",
            "children": [],
        },
        {
            "path": "main/look",
            "name": "look",
            "type": "Look",
            "category": "leaf",
            "params": {},
            "source": "m.yaml:8:7",
            "children": [],
        },
    ],
}


def tick(n: int, status: str = "RUNNING", changed: list | None = None, **extra) -> dict:
    record = {
        "event": "tick",
        "mission": "m",
        "tick": n,
        "t": round((n - 1) * 0.1, 6),
        "status": status,
        **extra,
    }
    if changed:
        record["changed"] = changed
    return record


def failing_log() -> list[dict]:
    """Go runs, succeeds at tick 3; look runs and fails at tick 5, ending the run."""
    return [
        {"event": "mission_started", "mission": "m", "tick": 0, "t": 0.0, "tick_hz": 10.0},
        {"event": "goal_sent", "mission": "m", "node": "go", "tick": 1, "t": 0.0, "x": 1.0, "y": 2.0},
        tick(
            1,
            changed=[
                {"node": "main/go", "status": "RUNNING", "was": "INVALID", "feedback": "to (1, 2)"},
                {"node": "main", "status": "RUNNING", "was": "INVALID"},
            ],
            bb={"target": [1.0, 2.0]},
        ),
        tick(2),
        tick(
            3,
            changed=[
                {"node": "main/go", "status": "SUCCESS", "was": "RUNNING", "feedback": "arrived"},
                {"node": "main/look", "status": "RUNNING", "was": "INVALID"},
            ],
            bb={"seen": 0},
        ),
        tick(4, bb_unset=["target"]),
        {"event": "alarm", "mission": "m", "node": "look", "tick": 5, "t": 0.4, "position": [3.0, 4.0]},
        tick(
            5,
            "FAILURE",
            changed=[
                {
                    "node": "main/look",
                    "status": "FAILURE",
                    "was": "RUNNING",
                    "feedback": "nothing",
                    "reason": "no object",
                },
                {"node": "main", "status": "FAILURE", "was": "RUNNING"},
            ],
        ),
        {
            "event": "halted",
            "mission": "m",
            "tick": 5,
            "t": 0.4,
            "changed": [{"node": "main", "status": "INVALID", "was": "FAILURE"}],
        },
        {
            "event": "mission_finished",
            "mission": "m",
            "tick": 5,
            "t": 0.4,
            "status": "FAILURE",
            "stopped_by": "status",
        },
    ]


def test_state_at_each_tick_follows_the_changes():
    """A node keeps the status, feedback and reason of its last change until the next one."""
    replay = Replay(TREE).feed_all(failing_log())
    states, _ = replay.state_at(1)  # index 1 = tick 2
    assert states["main/go"].status == "RUNNING" and states["main/go"].feedback == "to (1, 2)"
    assert states["main/look"].status == "INVALID"
    states, _ = replay.state_at(4)
    assert states["main/go"].status == "SUCCESS"
    assert (states["main/look"].status, states["main/look"].reason) == ("FAILURE", "no object")
    assert states["main"].status == "FAILURE"  # the halt is kept apart, not applied
    assert [c.status for c in replay.halted] == [0]


def test_blackboard_at_a_tick_has_writes_and_removals():
    """Keys appear when written and disappear when unset."""
    replay = Replay(TREE).feed_all(failing_log())
    assert replay.state_at(0)[1] == {"target": [1.0, 2.0]}
    assert replay.state_at(2)[1] == {"target": [1.0, 2.0], "seen": 0}
    assert replay.state_at(3)[1] == {"seen": 0}


def test_events_land_on_their_tick_with_category_and_position():
    """An event written before its tick's line belongs to that tick."""
    replay = Replay(TREE).feed_all(failing_log())
    kinds = [(e.kind, e.tick, event_category(e)) for e in replay.events]
    assert kinds == [("goal_sent", 0, "goal"), ("alarm", 4, "alarm")]


def test_ending_names_the_failure_chain_down_to_the_leaf():
    """The "why did it end" chain goes root -> the child that failed last -> its reason."""
    ending = Replay(TREE).feed_all(failing_log()).ending()
    assert ending["chain"] == [0, 2] and ending["status"] == "FAILURE"
    assert ending["reason"] == "no object" and ending["tick"] == 4
    assert "main/look: no object" in ending["text"]


def test_nodes_missing_from_the_declaration_are_learned_from_the_log():
    """A log without a declared tree still replays, its nodes placed by path."""
    replay = Replay(None).feed_all(failing_log())
    assert [n.path for n in replay.nodes] == ["main", "main/go", "main/look"]  # ancestors first
    assert replay.nodes[replay.index["main/go"]].parent == replay.index["main"]


def test_keyframes_give_the_same_state_as_a_straight_replay(synthetic_run: Path):
    """Seeking across many keyframes agrees with replaying every line from the start."""
    lines = read_lines(synthetic_run)
    replay = open_run(synthetic_run)
    for number in (1, KEYFRAME_EVERY - 1, KEYFRAME_EVERY, KEYFRAME_EVERY + 1, 1234, 2999, 3000):
        expected = statuses_by_replaying(lines, number)
        states, _ = replay.state_at(replay.tick_index(number))
        assert {p: s.status for p, s in states.items() if s.status != "INVALID"} == {
            p: s for p, s in expected.items() if s != "INVALID"
        }, number
    backwards = replay.state_at(10)[0]  # going back after later keyframes were built
    assert {p: s.status for p, s in backwards.items() if s.status != "INVALID"} == {
        p: s for p, s in statuses_by_replaying(lines, 11).items() if s != "INVALID"
    }


def test_a_real_run_replays_with_its_declared_tree(patrol_run: Path):
    """The patrol's nodes carry the mission file's types and parameters."""
    replay = open_run(patrol_run)
    patrol = replay.nodes[replay.index["respond_or_patrol/patrol_and_watch/patrol"]]
    assert patrol.type == "Patrol" and patrol.params["laps"] == 1
    assert "patrol.yaml:" in patrol.source
    assert len(replay) == sum(1 for line in read_lines(patrol_run) if line["event"] == "tick")
    assert replay.poses, "the simulator's trajectory is recorded"


def test_a_partial_last_line_waits_for_the_next_read(tmp_path: Path):
    """read_records leaves an unfinished line for later (a run still writing)."""
    log = tmp_path / "ticks.jsonl"
    log.write_text(json.dumps(tick(1)) + "\n" + '{"event":"tick","tic')
    records, offset = read_records(log)
    assert len(records) == 1
    with log.open("a") as stream:
        stream.write('k":2,"t":0.1,"status":"RUNNING"}\n')
    more, _ = read_records(log, offset)
    assert [r["tick"] for r in more] == [2]


def test_a_broken_line_is_a_clear_error(tmp_path: Path):
    """A line that is not JSON names the file and line."""
    (tmp_path / "ticks.jsonl").write_text(json.dumps(tick(1)) + "\nnot json\n")
    with pytest.raises(ConfigError, match=r"ticks.jsonl:2: not a tick log line"):
        open_run(tmp_path)


def test_a_directory_without_a_log_is_a_clear_error(tmp_path: Path):
    """Viewing a directory that is not a run says what is missing."""
    with pytest.raises(ConfigError, match="no ticks.jsonl"):
        open_run(tmp_path)


def test_a_damaged_recorded_tree_is_refused_naming_the_file(tmp_path: Path) -> None:
    """A runview.json whose tree has a node without a path is a ConfigError naming the file, not a crash."""
    import json as _json

    from missiontree.errors import ConfigError
    from missiontree.runlog.replay import open_run
    from missiontree.testing_runs import synthesize_run

    run = tmp_path / "run"
    synthesize_run(run, 20)
    view = _json.loads((run / "runview.json").read_text())
    view["tree"]["children"][0] = {"name": 3.5}
    (run / "runview.json").write_text(_json.dumps(view))
    with pytest.raises(ConfigError, match=r"runview\.json: its tree is not one .* \(a node without a path\)"):
        open_run(run)


def test_recorded_poses_that_are_not_finite_numbers_are_left_out(tmp_path: Path) -> None:
    """Rows of the recorded trajectory with NaN, text or too few values are not drawn as poses."""
    import json as _json

    from missiontree.runlog.replay import open_run
    from missiontree.testing_runs import synthesize_run

    run = tmp_path / "run"
    synthesize_run(run, 20)
    view = _json.loads((run / "runview.json").read_text())
    view["poses"] = [[0.0, 1.0, 2.0], [0.1, float("nan"), 2.0], [0.2, "x", 1.0], [0.3, 1.0], [0.4, 1.5, 2.5]]
    (run / "runview.json").write_text(_json.dumps(view))
    assert open_run(run).poses == [(0.0, 1.0, 2.0), (0.4, 1.5, 2.5)]


def test_a_declared_tree_lists_node_conditions_among_params(tmp_path: Path):
    """A tree read from a mission file carries its nodes' conditions (as the viewer shows parameters)."""
    from missiontree.engine.loader import load_mission
    from missiontree.runlog.replay import declared_tree
    from missiontree.testing import fresh_plugins

    mission = tmp_path / "m.yaml"
    mission.write_text('version: 1\nblackboard: {battery: 1.0}\nroot:\n  Sequence:\n    name: main\n'
                       '    memory: true\n    children:\n'
                       '      - Wait: {seconds: 1, skip_if: "battery < 0.2"}\n',
                       encoding="utf-8")
    tree = declared_tree(load_mission(mission, fresh_plugins().nodes))
    assert tree["children"][0]["params"] == {"seconds": 1, "skip_if": "battery < 0.2"}
