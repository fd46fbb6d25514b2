"""Tests of the tick log: changed nodes, blackboard changes, events, context ids, stable values."""

from __future__ import annotations

import dataclasses
import enum
import io
import json
import time
from pathlib import Path
from typing import Annotated

import numpy as np
import py_trees
import pytest
import structlog
from pydantic import BaseModel

from missiontree.engine.context import MissionContext
from missiontree.engine.leaf import Leaf, Status
from missiontree.engine.node_words import node_paths
from missiontree.engine.ports import Output
from missiontree.engine.tick_log import TickLog, TickRecorder, plain, read_log, read_records
from missiontree.errors import ConfigError
from missiontree.testing import ClockRobot, ScriptedLeaf, capture_tick_log, clean_state


@pytest.fixture(autouse=True)
def _clean() -> None:
    clean_state()


def _ticks(lines: list[dict]) -> list[dict]:
    return [line for line in lines if line["event"] == "tick"]


def test_only_nodes_whose_status_changed_are_listed() -> None:
    """A node still RUNNING as before is not listed again; its change to SUCCESS is."""
    _, lines = capture_tick_log(ScriptedLeaf("a", script="RRS"))
    ticks = _ticks(lines)
    assert [c["status"] for c in ticks[0]["changed"]] == ["RUNNING"]  # INVALID -> RUNNING
    assert "changed" not in ticks[1]                                   # still RUNNING
    assert ticks[2]["changed"] == [{"node": "a", "status": "SUCCESS", "was": "RUNNING"}]


def test_failure_entries_carry_the_reason() -> None:
    """A node that fails is listed with its failure reason."""
    _, lines = capture_tick_log(ScriptedLeaf("nav", script="F", reason="goal blocked"))
    change = _ticks(lines)[0]["changed"][0]
    assert (change["status"], change["reason"]) == ("FAILURE", "goal blocked")


def test_node_halted_by_a_higher_priority_branch_is_listed_without_being_ticked() -> None:
    """A running branch preempted by a higher-priority one shows up as INVALID in that tick's line."""
    guard = ScriptedLeaf("guard", script="FS", restart=False)  # tick 1 fails; tick 2 succeeds, preempts
    work = ScriptedLeaf("work", script="R")
    root = py_trees.composites.Selector("root", memory=False, children=[guard, work])
    _, lines = capture_tick_log(root)
    second = {c["node"]: c for c in _ticks(lines)[1]["changed"]}
    assert second["root/work"]["status"] == "INVALID" and second["root/work"]["was"] == "RUNNING"
    assert second["root/guard"]["status"] == "SUCCESS"


class _Writer(Leaf):
    """Writes the same value twice, then a new one, then removes the key."""

    class Params(BaseModel):
        out: Annotated[str, Output("a value")] = "value"

    def initialise(self) -> None:
        self.n = 0

    def update(self) -> Status:
        self.n += 1
        if self.n <= 2:
            self.write("out", 1.5)
        elif self.n == 3:
            self.write("out", 2.5)
        else:
            self.bb.unset("value")
            return Status.SUCCESS
        return Status.RUNNING


def test_blackboard_changes_list_new_values_only() -> None:
    """A key written with an unchanged value is not logged again; a removed key is listed as unset."""
    _, lines = capture_tick_log(_Writer("w"))
    ticks = _ticks(lines)
    assert ticks[0]["bb"] == {"value": 1.5}
    assert "bb" not in ticks[1]
    assert ticks[2]["bb"] == {"value": 2.5}
    assert ticks[3]["bb_unset"] == ["value"]


class _Emits(Leaf):
    """Emits a typed event and checks the structlog context while ticking."""

    def update(self) -> Status:
        self.emit("goal_sent", x=1.23456789, frame="map")
        self.seen_context = structlog.contextvars.get_contextvars()
        return Status.SUCCESS


def test_leaf_events_carry_time_tick_and_mission() -> None:
    """A leaf's event is a line with its fields, the node name, backend time, tick and mission id."""
    leaf = _Emits("sender")
    _, lines = capture_tick_log(leaf, MissionContext(robot=ClockRobot(start=5.0)), mission="m1")
    event = next(line for line in lines if line["event"] == "goal_sent")
    assert event == {"event": "goal_sent", "frame": "map", "mission": "m1", "node": "sender",
                     "t": 5.0, "tick": 1, "x": 1.234568}
    assert leaf.seen_context == {"mission": "m1", "tick": 1}


def test_structlog_context_is_unbound_after_the_run() -> None:
    """After the run the mission and tick ids are no longer bound."""
    capture_tick_log(ScriptedLeaf("a"))
    assert structlog.contextvars.get_contextvars() == {}


def test_lines_have_sorted_keys() -> None:
    """Every line is written with its keys sorted, so equal runs give equal bytes."""
    stream = io.StringIO()
    log = TickLog(stream, "m", clock=lambda: 0.0, simulated=True)
    log.emit("alarm", zeta=1, alpha=2)
    assert stream.getvalue() == '{"alpha":2,"event":"alarm","t":0.0,"zeta":1}\n'


class _Colour(enum.Enum):
    RED = 1


@dataclasses.dataclass
class _Point:
    x: float
    y: float


class _Opaque:
    pass


@pytest.mark.parametrize(("value", "expected"), [
    (0.1 + 0.2, 0.3),
    (float("inf"), "inf"),
    (_Colour.RED, "RED"),
    (_Point(1 / 3, 2.0), {"x": 0.333333, "y": 2.0}),
    (np.float32(0.5), 0.5),
    (np.arange(3), [0, 1, 2]),
    (np.zeros((40, 30)), {"array": [40, 30], "dtype": "float64"}),
    ({3, 1, 2}, [1, 2, 3]),
    (Path("runs/x"), "runs/x"),
    (_Opaque(), "<_Opaque>"),
])
def test_plain_values_are_json_ready_and_stable(value: object, expected: object) -> None:
    """Values are converted to stable JSON forms; unknown objects never show a memory address."""
    assert plain(value) == expected


def test_node_paths_are_unique_for_repeated_names() -> None:
    """Siblings with the same name get an index so every node path is unique."""
    a1, a2 = ScriptedLeaf("a"), ScriptedLeaf("a")
    root = py_trees.composites.Sequence("root", memory=True, children=[a1, a2])
    paths = node_paths(root)
    assert (paths[a1], paths[a2]) == ("root/a[0]", "root/a[1]")


def test_recorder_counts_outcomes_and_reasons() -> None:
    """The summary counts transitions into SUCCESS and FAILURE per node and keeps distinct reasons."""
    leaf = ScriptedLeaf("nav", script="RF", reason="no path")
    root = py_trees.decorators.Retry("retry", child=leaf, num_failures=3)
    root.setup()
    recorder = TickRecorder(root, TickLog(io.StringIO(), "m", clock=lambda: 0.0, simulated=True))
    for _ in range(6):
        recorder.record(0.0, list(root.tick()))
    summary = recorder.summary()
    assert summary["nodes"]["retry/nav"] == {"SUCCESS": 0, "FAILURE": 3}
    assert summary["failure_reasons"]["retry/nav"] == ["no path"]
    failures = summary["failures"]["retry/nav"]
    assert (failures["decided"], failures["absorbed_by"]) == (1, {"retry": 2})  # two retried, the last not


def test_a_status_held_over_many_ticks_counts_once() -> None:
    """A leaf failing on ten ticks in a row (re-checked by a memoryless Selector) turned FAILURE once."""
    guard = ScriptedLeaf("guard", script="F", reason="no alarm")
    root = py_trees.composites.Selector("root", memory=False, children=[guard, ScriptedLeaf("w", script="R")])
    root.setup()
    recorder = TickRecorder(root, TickLog(io.StringIO(), "m", clock=lambda: 0.0, simulated=True))
    for _ in range(10):
        recorder.record(0.0, list(root.tick()))
    summary = recorder.summary()
    assert summary["nodes"]["root/guard"] == {"SUCCESS": 0, "FAILURE": 1}
    assert summary["failures"]["root/guard"]["absorbed_by"] == {"root": 1}


def test_read_log_names_a_broken_line(tmp_path: Path) -> None:
    """Reading back a log with a line that is not JSON names the file and line."""
    path = tmp_path / "ticks.jsonl"
    path.write_text('{"event": "tick"}\nnot json\n')
    with pytest.raises(ConfigError, match=r"ticks.jsonl:2: not a tick log line"):
        read_log(path)


def test_one_reader_serves_a_finished_log_and_a_growing_one(tmp_path: Path) -> None:
    """read_log takes a last line without its newline; read_records leaves it for the next read."""
    path = tmp_path / "ticks.jsonl"
    path.write_text('{"tick": 1}\n{"tick": 2}')
    assert [r["tick"] for r in read_log(path)] == [1, 2]
    records, offset = read_records(path)
    assert [r["tick"] for r in records] == [1] and offset == len('{"tick": 1}\n')
    path.write_text('{"tick": 1}\n{"tick": 2}\nbroken\n')
    with pytest.raises(ConfigError, match=r"line 2 after byte 12: not a tick log line"):
        read_records(path, offset)


class _ThreadEmitter(Leaf):
    """Emits one event from a worker thread during its first tick, then succeeds on the second."""

    def initialise(self) -> None:
        self.n = 0

    def update(self) -> Status:
        import threading

        self.n += 1
        if self.n == 1:
            worker = threading.Thread(target=lambda: self.emit("model_answer", latency=0.25))
            worker.start()
            worker.join()
            return Status.RUNNING
        return Status.SUCCESS


def test_event_from_another_thread_is_written_on_the_tick_thread() -> None:
    """An event emitted off the tick thread is written with its tick's line, like the tick's own events."""
    _, lines = capture_tick_log(_ThreadEmitter("caller"))
    kinds = [line["event"] for line in lines]
    assert kinds[:3] == ["mission_started", "model_answer", "tick"]  # tick 1's events, then its line
    answer = lines[1]
    assert (answer["tick"], answer["latency"], answer["node"]) == (1, 0.25, "caller")


def test_event_field_named_event_is_kept_under_another_name() -> None:
    """A leaf field called 'event' does not clash with the line's kind."""
    stream = io.StringIO()
    TickLog(stream, "m", clock=lambda: 0.0, simulated=True).emit("alarm", event="person")
    assert '"event":"alarm"' in stream.getvalue() and '"event_field":"person"' in stream.getvalue()


def test_events_after_the_run_are_dropped() -> None:
    """Once the run has finished, a late event from a worker is dropped, not written to a closed file."""
    stream = io.StringIO()
    log = TickLog(stream, "m", clock=lambda: 0.0, simulated=True)
    log.unbind()
    log.emit("late", x=1)
    assert stream.getvalue() == ""


class _Blink(Leaf):
    """RUNNING on its first tick, SUCCESS on the next."""

    def initialise(self) -> None:
        self.ticked = False

    def update(self) -> Status:
        if self.ticked:
            return Status.SUCCESS
        self.ticked = True
        return Status.RUNNING


def test_the_recorders_work_does_not_grow_with_finished_children() -> None:
    """In a memory Sequence of 3,000 steps, the last ticks look at as few nodes as the first ones."""
    from missiontree.engine.runner import Runner

    root = py_trees.composites.Sequence("plan", memory=True, children=[_Blink(f"s{i}") for i in range(3000)])
    runner = Runner(root, MissionContext(robot=ClockRobot()), log_stream=io.StringIO(), handle_signals=False)
    runner.setup()
    assert runner.recorder is not None
    examined = []
    for _ in range(2990):
        runner.tick()
        examined.append(runner.recorder.examined)
    assert max(examined[-100:]) <= max(examined[1:100]) <= 6  # the Sequence and two steps, not 2,990


def test_halted_nodes_are_still_found_when_only_stops_are_watched() -> None:
    """A running branch halted by a higher-priority one is found through its stop(), untouched."""
    from missiontree.engine.runner import Runner

    guard = ScriptedLeaf("guard", script="FFS", restart=False)
    work = py_trees.composites.Sequence("work", memory=True, children=[ScriptedLeaf("step", script="R")])
    root = py_trees.composites.Selector("root", memory=False, children=[guard, work])
    stream = io.StringIO()
    Runner(root, MissionContext(robot=ClockRobot()), log_stream=stream, handle_signals=False,
           max_duration=0.5).run()
    ticks = [json.loads(line) for line in stream.getvalue().splitlines() if '"event":"tick"' in line]
    third = {c["node"]: (c["was"], c["status"]) for c in ticks[2]["changed"]}
    assert third["root/work"] == ("RUNNING", "INVALID") and third["root/work/step"] == ("RUNNING", "INVALID")
    assert type(work) is py_trees.composites.Sequence and type(guard) is ScriptedLeaf  # watch removed


def test_setup_is_linear_in_a_composites_child_count() -> None:
    """Paths of 20,000 children with repeated names are found without comparing every pair."""
    names = [f"step{i % 100}" for i in range(20000)]
    root = py_trees.composites.Sequence("plan", memory=True,
                                        children=[py_trees.behaviours.Success(n) for n in names])
    start = time.process_time()
    paths = node_paths(root)
    elapsed = time.process_time() - start
    assert paths[root.children[150]] == "plan/step50[150]"
    assert elapsed < 1.0  # comparing every pair took seconds


def test_a_halted_child_of_a_large_composite_is_found_through_its_watched_stop() -> None:
    """A Selector of 30 children: the running last one, halted when the first succeeds, is logged."""
    from missiontree.engine.runner import Runner

    guards = [ScriptedLeaf("guard", script="FFS", restart=False)]
    guards += [ScriptedLeaf(f"no{i}", script="F") for i in range(28)]
    work = ScriptedLeaf("work", script="R")
    root = py_trees.composites.Selector("root", memory=False, children=[*guards, work])
    stream = io.StringIO()
    runner = Runner(root, MissionContext(robot=ClockRobot()), log_stream=stream, handle_signals=False,
                    max_duration=0.5)
    runner.setup()
    assert runner.recorder is not None and work in runner.recorder._watching  # large: watched
    runner.run()
    ticks = [json.loads(line) for line in stream.getvalue().splitlines() if '"event":"tick"' in line]
    third = {c["node"]: (c["was"], c["status"]) for c in ticks[2]["changed"]}
    assert third["root/work"] == ("RUNNING", "INVALID")
    assert type(work) is ScriptedLeaf  # switched back after the run
