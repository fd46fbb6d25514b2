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
    assert "patrol/retry/navigate: 2 — goal blocked by an obstacle (x2)" in out
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
