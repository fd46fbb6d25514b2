"""`batch ... --log sqlite`: every run of the batch in <out>/log.sqlite."""

from __future__ import annotations

from pathlib import Path

import pytest

from missiontree.cli.main import main
from missiontree.paths import REPO_ROOT
from missiontree.runlog.sqlite_log import query

TIMER = str(REPO_ROOT / "trees" / "examples" / "timer_and_blackboard.yaml")


def test_batch_appends_every_run_to_its_sqlite_log(tmp_path: Path) -> None:
    """Two seeds: two runs with their batch ids, seeds and transitions, one query away."""
    out = tmp_path / "batch"
    code = main(["batch", TIMER, "--seeds", "0-1",
                 "--jobs", "1", "--out", str(out), "--log", "sqlite", "--quiet"])
    assert code == 0
    assert query(out / "log.sqlite", "SELECT name, seed, status FROM runs ORDER BY name")[1] == [
        ("default_s0", 0, "SUCCESS"), ("default_s1", 1, "SUCCESS")]
    assert query(out / "log.sqlite", "SELECT COUNT(DISTINCT run_id) FROM transitions")[1] == [(2,)]


def test_batch_sqlite_log_needs_the_tick_logs(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """--log sqlite with --no-logs is refused before any run (it is written from the tick logs)."""
    code = main(["batch", TIMER, "--seeds", "0",
                 "--out", str(tmp_path / "b"), "--log", "sqlite", "--no-logs", "--quiet"])
    assert code == 2
    assert "drop --no-logs" in capsys.readouterr().err
