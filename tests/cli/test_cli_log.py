"""Tests of `missiontree log summarize`: what failed and why, from the tick log alone."""

from __future__ import annotations

import json
from pathlib import Path

import py_trees
import pytest

from missiontree.cli.log import summarize
from missiontree.cli.main import main
from missiontree.engine.context import MissionContext
from missiontree.engine.runner import Runner
from missiontree.testing import ClockRobot, ScriptedLeaf, clean_state


@pytest.fixture(autouse=True)
def _clean() -> None:
    clean_state()


def _failed_run(run_dir: Path) -> None:
    """A patrol whose navigation fails twice (retried) after an error in a check."""
    nav = ScriptedLeaf("navigate", script="RF", reason="goal blocked by an obstacle")
    root = py_trees.composites.Sequence("patrol", memory=True, children=[
        py_trees.composites.Selector("check", memory=False, children=[
            ScriptedLeaf("camera_ok", script="X"), ScriptedLeaf("skip", script="S")]),
        py_trees.decorators.Retry("retry", child=nav, num_failures=2),
    ])
    Runner(root, MissionContext(robot=ClockRobot()), run_dir=run_dir, mission="patrol",
           handle_signals=False).run()


def test_summary_names_the_failure_that_ended_the_run(tmp_path: Path) -> None:
    """The deepest node that failed on the last tick comes first, with its reason."""
    _failed_run(tmp_path)
    lines = [json.loads(line) for line in (tmp_path / "ticks.jsonl").read_text().splitlines()]
    summary = summarize(lines)
    assert summary["status"] == "FAILURE"
    reason = "goal blocked by an obstacle"
    assert summary["ended_by"][0] == {"node": "patrol/retry/navigate", "reason": reason}
    assert summary["failures"]["patrol/retry/navigate"]["count"] == 2
    assert summary["errors"][0]["node"] == "camera_ok"


def test_text_summary_from_a_run_directory(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """`log summarize RUN` prints how the run ended, failures with reasons and errors."""
    _failed_run(tmp_path)
    assert main(["log", "summarize", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert out.startswith("mission patrol: FAILURE (stopped by status)")
    decided, absorbed = out.split("failures absorbed by design")
    assert "patrol/retry/navigate: 1 — goal blocked by an obstacle" in decided  # the second attempt
    assert "patrol/retry/navigate: 1, absorbed by patrol/retry x1" in absorbed  # the first, retried
    assert "patrol/check/camera_ok: 1, absorbed by patrol/check x1" in absorbed  # the Selector moved on
    assert "patrol: 1 — child 'retry' failed: goal blocked by an obstacle (from 'retry/navigate') (x1)" in out
    assert "(no reason given)" not in out
    assert "RuntimeError: camera_ok: scripted error" in out


def test_summary_of_a_run_stopped_by_the_limit_lists_what_was_running(tmp_path: Path) -> None:
    """A run cut by its duration limit reports the nodes still running."""
    root = py_trees.composites.Sequence("main", memory=True, children=[ScriptedLeaf("wait", script="R")])
    Runner(root, MissionContext(robot=ClockRobot()), run_dir=tmp_path, max_duration=1.0,
           handle_signals=False).run()
    lines = [json.loads(line) for line in (tmp_path / "ticks.jsonl").read_text().splitlines()]
    summary = summarize(lines)
    assert (summary["stopped_by"], summary["running_at_end"]) == ("limit", ["main", "main/wait"])


def test_missing_run_exits_two(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A run directory without a tick log exits 2 and says what to give."""
    assert main(["log", "summarize", str(tmp_path)]) == 2
    assert "has no ticks.jsonl" in capsys.readouterr().err


def test_json_summary(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """--json prints the summary as JSON."""
    _failed_run(tmp_path)
    assert main(["log", "summarize", str(tmp_path / "ticks.jsonl"), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["mission"] == "patrol"


def _lines(run_dir: Path) -> list[dict]:
    return [json.loads(line) for line in (run_dir / "ticks.jsonl").read_text().splitlines()]


def test_a_composite_that_failed_names_the_child_that_ended_it(tmp_path: Path) -> None:
    """A Sequence failing because a nested leaf failed says which child failed and the leaf's reason."""
    ask = ScriptedLeaf("ask", script="RF", reason="model said no")
    root = py_trees.composites.Sequence("mission", memory=True, children=[
        py_trees.composites.Sequence("surveillance", memory=True,
                                     children=[ScriptedLeaf("look", script="S"), ask]),
    ])
    Runner(root, MissionContext(robot=ClockRobot()), run_dir=tmp_path, handle_signals=False).run()
    failures = summarize(_lines(tmp_path))["failures"]
    assert failures["mission/surveillance"]["reasons"] == {"child 'ask' failed: model said no": 1}
    assert failures["mission"]["reasons"] == {
        "child 'surveillance' failed: model said no (from 'surveillance/ask')": 1}


def test_the_failure_ending_a_run_is_the_leaf_not_its_parents(tmp_path: Path) -> None:
    """"Ended by" lists only nodes with reasons of their own, not the composites that passed them up."""
    root = py_trees.composites.Sequence("mission", memory=True, children=[
        py_trees.composites.Sequence("inner", memory=True, children=[
            ScriptedLeaf("ask", script="F", reason="model said no")])])
    Runner(root, MissionContext(robot=ClockRobot()), run_dir=tmp_path, handle_signals=False).run()
    ended_by = summarize(_lines(tmp_path))["ended_by"]
    assert ended_by == [{"node": "mission/inner/ask", "reason": "model said no"}]


def test_a_decorator_keeps_its_words_and_adds_the_childs_reason(tmp_path: Path) -> None:
    """A Retry that gave up shows its own count followed by the reason of the child that failed."""
    _failed_run(tmp_path)
    reasons = summarize(_lines(tmp_path))["failures"]["patrol/retry"]["reasons"]
    [reason] = reasons
    assert reason.endswith("; child 'navigate' failed: goal blocked by an obstacle")
    assert reason.startswith("Retry: all 2 attempts failed")  # the mission file's words, not py_trees'


def test_the_child_that_failed_earlier_is_found_from_the_replayed_state() -> None:
    """A composite turning FAILURE when its child failed on an earlier tick still names that child."""
    lines = [
        {"event": "tick", "tick": 1, "t": 0.0, "status": "RUNNING", "changed": [
            {"node": "main/guarded/check", "status": "FAILURE", "was": "INVALID", "reason": "battery low"},
            {"node": "main/guarded", "status": "RUNNING", "was": "INVALID"}]},
        {"event": "tick", "tick": 2, "t": 0.1, "status": "FAILURE", "changed": [
            {"node": "main/guarded", "status": "FAILURE", "was": "RUNNING"},
            {"node": "main", "status": "FAILURE", "was": "RUNNING"}]},
    ]
    summary = summarize(lines)
    assert summary["failures"]["main/guarded"]["reasons"] == {"child 'check' failed: battery low": 1}
    assert summary["ended_by"] == [{"node": "main/guarded", "reason": "child 'check' failed: battery low"}]
    assert summary["failures"]["main"]["reasons"] == {
        "child 'guarded' failed: battery low (from 'guarded/check')": 1}


def test_a_composite_with_no_failed_child_in_the_log_says_so() -> None:
    """With no failing descendant anywhere in the log, the reason stays "(no reason given)"."""
    lines = [{"event": "tick", "tick": 1, "t": 0.0, "status": "FAILURE",
              "changed": [{"node": "main", "status": "FAILURE", "was": "INVALID"}]}]
    assert summarize(lines)["failures"]["main"]["reasons"] == {"(no reason given)": 1}


def test_when_several_children_fail_in_one_tick_the_last_ticked_is_named_with_the_others() -> None:
    """A Parallel whose two children failed in the same tick names the last one ticked and lists the other."""
    lines = [{"event": "tick", "tick": 1, "t": 0.0, "status": "FAILURE", "changed": [
        {"node": "watch/camera", "status": "FAILURE", "was": "INVALID", "reason": "no frames"},
        {"node": "watch/lidar", "status": "FAILURE", "was": "INVALID", "reason": "no scans"},
        {"node": "watch", "status": "FAILURE", "was": "INVALID"}]}]
    reasons = summarize(lines)["failures"]["watch"]["reasons"]
    assert reasons == {"child 'lidar' failed (as did 'camera'): no scans": 1}


def test_summary_json_and_log_summarize_agree_on_every_failure(tmp_path: Path) -> None:
    """Counts, decided and absorbed failures are the same in summary.json and in `log summarize`."""
    _failed_run(tmp_path)
    written = json.loads((tmp_path / "summary.json").read_text())["failures"]
    replayed = summarize(_lines(tmp_path))["failures"]
    assert set(written) == set(replayed)
    for node, entry in written.items():
        again = replayed[node]
        assert (entry["count"], entry["decided"], entry["absorbed_by"]) == \
            (again["count"], again["decided"], again["absorbed_by"]), node


def test_a_guard_failing_every_tick_under_a_selector_is_one_absorbed_failure(tmp_path: Path) -> None:
    """A memoryless Selector re-checking a failing guard for 20 ticks: one transition, absorbed, named."""
    root = py_trees.composites.Selector("respond_or_patrol", memory=False, children=[
        py_trees.decorators.SuccessIsFailure("servo_then_resume", child=ScriptedLeaf(
            "servo", script="F", reason="no new alarm")),
        ScriptedLeaf("patrol", script="R" * 19 + "S")])
    Runner(root, MissionContext(robot=ClockRobot()), run_dir=tmp_path, handle_signals=False).run()
    summary = json.loads((tmp_path / "summary.json").read_text())
    entry = summary["failures"]["respond_or_patrol/servo_then_resume"]
    assert (entry["count"], entry["decided"], entry["absorbed_by"]) == (1, 0, {"respond_or_patrol": 1})
    assert summary["nodes"]["respond_or_patrol/servo_then_resume/servo"] == {"SUCCESS": 0, "FAILURE": 1}
    replayed = summarize(_lines(tmp_path))["failures"]["respond_or_patrol/servo_then_resume"]
    assert (replayed["count"], replayed["absorbed_by"]) == (1, {"respond_or_patrol": 1})


def test_force_failure_is_named_as_in_the_mission_file(tmp_path: Path) -> None:
    """ForceFailure's forced failure reads "ForceFailure: ...", never py_trees' "success is failure"."""
    root = py_trees.composites.Selector("root", memory=False, children=[
        py_trees.decorators.SuccessIsFailure("serve", child=ScriptedLeaf("servo", script="S")),
        ScriptedLeaf("patrol", script="S")])
    Runner(root, MissionContext(robot=ClockRobot()), run_dir=tmp_path, handle_signals=False).run()
    text = (tmp_path / "ticks.jsonl").read_text() + (tmp_path / "summary.json").read_text()
    assert "success is failure" not in text
    summary = json.loads((tmp_path / "summary.json").read_text())
    forced = "ForceFailure: the child succeeded, FAILURE by design"
    assert summary["failure_reasons"]["root/serve"] == [forced]


def test_escape_sequences_in_names_and_reasons_reach_the_terminal_escaped(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A node name and a reason with title-set and screen-clear sequences are printed as visible escapes."""
    hostile = "label\x1b]0;owned\x07\x1b[2J"
    root = py_trees.composites.Sequence("patrol", memory=True, children=[
        ScriptedLeaf(f"look_for_{hostile}", script="F", reason=f"saw a {hostile}")])
    Runner(root, MissionContext(robot=ClockRobot()), run_dir=tmp_path, mission="patrol",
           handle_signals=False).run()
    assert main(["log", "summarize", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "\x1b" not in out and "\x07" not in out
    assert "look_for_label\\x1b]0;owned\\x07\\x1b[2J" in out


def test_summarize_leads_with_what_the_mission_said_it_did(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The outcome a leaf reported (summary.json) is the line after the status, before the failures."""
    from missiontree.engine.leaf import Leaf, Status

    class Serves(Leaf):
        def update(self) -> Status:
            self.context.report("intent", {"text": "'tea': not served: nothing here serves it"})
            return Status.FAILURE

    Runner(Serves("serve"), MissionContext(robot=ClockRobot()), run_dir=tmp_path, handle_signals=False).run()
    assert main(["log", "summarize", str(tmp_path)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[1] == "outcome: 'tea': not served: nothing here serves it"
    (tmp_path / "summary.json").write_text("{not json", encoding="utf-8")  # the log alone still speaks
    assert main(["log", "summarize", str(tmp_path)]) == 0
    assert not any(line.startswith("outcome:") for line in capsys.readouterr().out.splitlines())
