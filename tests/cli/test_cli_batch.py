"""Tests of `missiontree batch`: files written, exit codes, bad input, the Dask extra and address."""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

import pytest

from missiontree.cli.main import main
from missiontree.evaluation import batch, dask_engine, engines
from missiontree.testing import clean_state

MISSION = """\
version: 1
params:
  wait: 0.2
  fail: false
run:
  backend: sim
  tick_hz: 10
  max_duration: 10
blackboard:
  failing: ${fail}
root:
  Sequence:
    name: main
    memory: true
    children:
      - Wait: {seconds: "${wait}"}
      - CheckBlackboard: {key: failing, value: false}
"""


@pytest.fixture(autouse=True)
def _clean() -> None:
    clean_state()


@pytest.fixture
def mission(tmp_path: Path) -> Path:
    path = tmp_path / "m.yaml"
    path.write_text(MISSION, encoding="utf-8")
    return path


@pytest.mark.slow
def test_batch_writes_results_summary_junit_and_fails_on_a_failed_run(
        mission: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A sweep with a failing value: exit 1, the table per value, every file, one line per run."""
    out = tmp_path / "out"
    code = main(["batch", str(mission), "--seeds", "0-1", "--sweep", "fail=false,true", "--jobs", "2",
                 "--out", str(out)])
    captured = capsys.readouterr()
    assert code == 1
    assert "fail=true" in captured.out and "95% Wilson" in captured.out and "batch FAILED" in captured.out
    assert "runs/s" in captured.err and "ETA" in captured.err  # the progress bar
    lines = [json.loads(line) for line in (out / "results.jsonl").read_text().splitlines()]
    assert [(r["params"]["fail"], r["seed"], r["status"]) for r in lines] == [
        ("false", 0, "SUCCESS"), ("false", 1, "SUCCESS"), ("true", 0, "FAILURE"), ("true", 1, "FAILURE")]
    failed = lines[2]
    assert "main/CheckBlackboard" in failed["reason"]
    assert failed["robot_time_s"] == pytest.approx(0.2, abs=0.15)
    for key in ("world", "seed", "run_seed", "params", "status", "reason", "robot_time_s", "wall_time_s",
                "path_length_m", "figures"):
        assert key in failed
    summary = json.loads((out / "summary.json").read_text())
    assert summary["by_param"]["fail"]["true"]["success_rate"] == 0.0
    assert summary["passed_batch"] is False
    assert (out / "junit.xml").read_text().count("<testcase") == 4
    assert (out / "runs" / failed["run_id"] / "summary.json").is_file()

    again = main(["batch", str(mission), "--seeds", "0-1", "--sweep", "fail=false,true", "--out", str(out),
                  "--resume", "--min-success", "50%", "--quiet"])
    assert again == 0  # nothing re-run; half the runs succeeded


def test_an_out_dir_with_runs_needs_resume(mission: Path, tmp_path: Path,
                                         capsys: pytest.CaptureFixture[str]) -> None:
    """Runs already in --out are never overwritten silently."""
    out = tmp_path / "out"
    (out / "runs" / "default_s0").mkdir(parents=True)
    (out / "runs" / "default_s0" / "record.json").write_text("{}")
    assert main(["batch", str(mission), "--seeds", "0", "--out", str(out), "--quiet"]) == 2
    assert "--resume" in capsys.readouterr().err


@pytest.mark.parametrize(("args", "message"), [
    (["--seeds", "3-1"], "runs backwards"),
    (["--seeds", "0", "--set", "nope=1"], "nope"),
    (["--seeds", "0", "--sweep", "wait=abc,0.1"], "wait"),
    (["--seeds", "0", "--worlds", "no_such_world"], "no_such_world"),
    (["--seeds", "0", "--jobs", "0"], "--jobs"),
])
def test_bad_input_is_exit_2_before_any_run(mission: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                            args: list[str], message: str) -> None:
    """Bad seeds, params, values, worlds or jobs stop the batch with exit 2 and no run directory."""
    out = tmp_path / "out"
    assert main(["batch", str(mission), "--out", str(out), "--quiet", *args]) == 2
    assert message in capsys.readouterr().err
    assert not (out / "runs").exists()


def test_a_missing_mission_file_is_exit_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The mission file must exist."""
    assert main(["batch", str(tmp_path / "none.yaml"), "--quiet"]) == 2
    assert "does not exist" in capsys.readouterr().err


def test_min_success_takes_rates_and_percentages(mission: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Out-of-range rates are an argparse error (exit 2)."""
    with pytest.raises(SystemExit) as exit_info:
        main(["batch", str(mission), "--min-success", "150%"])
    assert exit_info.value.code == 2


def test_dask_without_the_extra_is_exit_2_naming_it(mission: Path, tmp_path: Path,
                                                    monkeypatch: pytest.MonkeyPatch,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    """--dask with distributed not importable: exit 2 and the message names the 'dask' extra."""
    monkeypatch.setitem(sys.modules, "distributed", None)
    assert main(["batch", str(mission), "--seeds", "0", "--dask", "local", "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "'dask' extra" in err and "missiontree[dask]" in err


def test_the_scheduler_address_comes_from_the_flag_or_environment(monkeypatch: pytest.MonkeyPatch) -> None:
    """--dask wins; else DASK_SCHEDULER_ADDRESS; else the local pool with --jobs workers."""
    made: list[tuple[str, Any]] = []

    class Recorded:
        def __init__(self, address: str, workers: Any) -> None:
            made.append((address, workers))

    monkeypatch.setattr(dask_engine, "DaskEngine", Recorded)
    monkeypatch.setenv("DASK_SCHEDULER_ADDRESS", "tcp://cluster:8786")
    batch.make_engine(None, 3)
    batch.make_engine("tcp://other:8786", None)
    assert made == [("tcp://cluster:8786", 3), ("tcp://other:8786", None)]
    monkeypatch.delenv("DASK_SCHEDULER_ADDRESS")
    pool = batch.make_engine(None, 3)
    assert isinstance(pool, engines.PoolEngine) and pool.workers == 3


def test_core_imports_without_dask() -> None:
    """Importing the evaluation package and the batch command never imports Dask."""
    import subprocess

    code = ("import sys; import missiontree.evaluation, missiontree.cli.batch; "
            "sys.exit(1 if 'distributed' in sys.modules or 'dask' in sys.modules else 0)")
    assert subprocess.run([sys.executable, "-c", code], timeout=120).returncode == 0


def test_a_second_batch_into_the_same_out_is_refused(mission: Path, tmp_path: Path,
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    """While another live batch holds --out, a second one exits 2 naming it and writes nothing there."""
    import os

    out = tmp_path / "out"
    out.mkdir()
    (out / "batch.lock").write_text(f"{os.getppid()}\n")  # a live process: the batch already running
    (out / "results.jsonl").write_text("the other batch's results\n")
    assert main(["batch", str(mission), "--seeds", "0", "--out", str(out), "--quiet", "--resume"]) == 2
    assert f"in use by another batch (pid {os.getppid()}" in capsys.readouterr().err
    assert (out / "results.jsonl").read_text() == "the other batch's results\n"
    assert not (out / "runs").exists()


def test_a_lock_left_by_a_dead_batch_is_taken_over_and_released(mission: Path, tmp_path: Path) -> None:
    """A lock whose pid is dead does not block the next batch, which removes its own lock at the end."""
    out = tmp_path / "out"
    out.mkdir()
    (out / "batch.lock").write_text("999999999\n")
    assert main(["batch", str(mission), "--seeds", "0", "--jobs", "1", "--out", str(out), "--quiet"]) == 0
    assert (out / "results.jsonl").is_file() and not (out / "batch.lock").exists()


def test_substitute_stubs_every_run_and_each_summary_lists_it(mission: Path, tmp_path: Path) -> None:
    """`batch --substitute`: every run's summary.json lists the substitution, and the stub decides."""
    rules = tmp_path / "rules.yaml"
    rules.write_text("rules:\n  - match: CheckBlackboard\n    status: SUCCESS\n", encoding="utf-8")
    out = tmp_path / "out"
    code = main(["batch", str(mission), "--seeds", "0-1", "--set", "fail=true", "--jobs", "1",
                 "--out", str(out), "--quiet", "--substitute", str(rules)])
    assert code == 0  # without the stub, CheckBlackboard fails every run
    runs = sorted((out / "runs").iterdir())
    assert len(runs) == 2
    for run_dir in runs:
        subs = json.loads((run_dir / "summary.json").read_text())["substitutions"]
        assert [(s["node"], s["type"], s["status"]) for s in subs] == [
            ("main/CheckBlackboard", "CheckBlackboard", "SUCCESS")]


def test_substitute_rule_matching_nothing_is_exit_2_before_any_run(
        mission: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A rules file whose rule matches no node stops the batch before any run starts."""
    rules = tmp_path / "rules.yaml"
    rules.write_text("rules:\n  - match: NoSuchNode\n    status: SUCCESS\n", encoding="utf-8")
    out = tmp_path / "out"
    assert main(["batch", str(mission), "--seeds", "0", "--out", str(out), "--quiet",
                 "--substitute", str(rules)]) == 2
    assert "rules.yaml:2" in capsys.readouterr().err
    assert not (out / "runs").exists()


def test_substitute_needs_a_regular_file(mission: Path, tmp_path: Path,
                                         capsys: pytest.CaptureFixture[str]) -> None:
    """Every run reads the rules file, so a missing file (or a pipe) is exit 2 before any run."""
    out = tmp_path / "out"
    assert main(["batch", str(mission), "--seeds", "0", "--out", str(out), "--quiet",
                 "--substitute", str(tmp_path / "none.yaml")]) == 2
    assert "--substitute" in capsys.readouterr().err
    assert not (out / "runs").exists()
