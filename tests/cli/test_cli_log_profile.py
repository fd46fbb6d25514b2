"""Tests of ``missiontree log profile``: a run's profile printed as a table."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from missiontree.cli.log_profile import format_profile, read_profile
from missiontree.cli.main import main
from missiontree.engine.context import MissionContext
from missiontree.engine.runner import Runner
from missiontree.errors import ConfigError
from missiontree.testing import ClockRobot, ScriptedLeaf, clean_state


@pytest.fixture(autouse=True)
def _clean() -> None:
    clean_state()


def _run(run_dir: Path) -> None:
    context = MissionContext(robot=ClockRobot())
    Runner(ScriptedLeaf("leaf", script="RRRS"), context, run_dir=run_dir, handle_signals=False,
           mission="demo").run()


def test_prints_each_node_with_ticks_rate_and_cpu(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The table names the mission, each node with its ticks and rate, and the simulator's stepping."""
    _run(tmp_path)
    assert main(["log", "profile", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert out.startswith("mission demo: 0.3 s on the robot clock")
    row = next(line for line in out.splitlines() if line.startswith("leaf "))
    assert row.split()[1:3] == ["4", "10.00"]
    assert "simulator stepping" in out and "largest cost centres:" in out


def test_json_prints_the_profile_section(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """--json prints summary.json's profile as it is."""
    _run(tmp_path)
    assert main(["log", "profile", str(tmp_path), "--json"]) == 0
    printed = json.loads(capsys.readouterr().out)
    assert printed == json.loads((tmp_path / "summary.json").read_text())["profile"]


def test_a_summary_without_a_profile_is_a_clear_error(tmp_path: Path) -> None:
    """An older run's summary.json without a profile says so and how to get one."""
    (tmp_path / "summary.json").write_text(json.dumps({"mission": "old", "complete": True}))
    with pytest.raises(ConfigError, match="no profile section"):
        read_profile(tmp_path)


def test_top_keeps_the_nodes_that_used_most_cpu() -> None:
    """--top N shows the N nodes with the most CPU, largest first."""
    profile = {"run": {"cpu_s": 1.0}, "nodes": {
        "a": {"ticks": 1, "rate_hz": 1.0, "cpu_s": 0.1}, "b": {"ticks": 1, "rate_hz": 1.0, "cpu_s": 0.5},
        "c": {"ticks": 1, "rate_hz": 1.0, "cpu_s": 0.2}}}
    lines = format_profile("m", profile, top=2).splitlines()
    rows = [line.split()[0] for line in lines if line[:2] in ("a ", "b ", "c ")]
    assert rows == ["b", "c"]
