"""Tests of `missiontree run`: exit codes, run directory, flags over the mission's run section."""

from __future__ import annotations

import importlib.metadata
import json
import os
import signal
import subprocess
import sys
import time
import types
from pathlib import Path
from typing import Any

import pytest

import missiontree
from missiontree.cli.main import main
from missiontree.plugins import manager
from missiontree.plugins.hookspecs import hookimpl
from missiontree.testing import ClockRobot, clean_state

REPO = Path(__file__).resolve().parents[2]
Capture = pytest.CaptureFixture[str]
SEEN_OPTIONS: list[dict[str, Any]] = []


@pytest.fixture(autouse=True)
def _clock_backend(monkeypatch: pytest.MonkeyPatch) -> None:
    """Every test starts clean, with a plugin offering the 'clock' backend (a ClockRobot)."""
    clean_state()
    SEEN_OPTIONS.clear()
    module = types.ModuleType("mt_test_clock_backend")

    def missiontree_register_backends(backends: dict[str, Any]) -> None:
        backends["clock"] = lambda options: SEEN_OPTIONS.append(options) or ClockRobot()

    module.missiontree_register_backends = hookimpl(missiontree_register_backends)  # type: ignore[attr-defined]
    monkeypatch.setitem(sys.modules, module.__name__, module)
    ep = importlib.metadata.EntryPoint(name="clock", value=module.__name__, group="missiontree")
    monkeypatch.setattr(manager, "discover_entry_points", lambda: [ep])


MISSION = """\
version: 1
run: {backend: clock, tick_hz: 10}
blackboard: {phase: idle}
root:
  Sequence:
    name: main
    memory: true
    children:
      - Wait: {seconds: 1.0}
      - SetBlackboard: {key: phase, value: done}
"""

FAILING = """\
version: 1
run: {backend: clock}
root:
  Sequence:
    name: main
    memory: true
    children:
      - Wait: {seconds: 0.3}
      - Fail: {reason: "dock not found"}
"""


def _write(tmp_path: Path, text: str, name: str = "mission.yaml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def test_successful_mission_exits_zero_and_writes_the_run_directory(
        tmp_path: Path, capsys: Capture) -> None:
    """A mission that succeeds exits 0 and leaves ticks.jsonl and summary.json in --out."""
    out = tmp_path / "run"
    assert main(["run", str(_write(tmp_path, MISSION)), "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert (summary["status"], summary["ticks"], summary["mission"]) == ("SUCCESS", 11, "mission")
    assert "mission: SUCCESS after 11 ticks" in capsys.readouterr().out
    ticks = [json.loads(line) for line in (out / "ticks.jsonl").read_text().splitlines()]
    assert ticks[1]["bb"]["phase"] == "idle"  # the blackboard defaults, logged with tick 1


def test_failing_mission_exits_one(tmp_path: Path) -> None:
    """A mission whose root fails exits 1 and the summary keeps the reason."""
    out = tmp_path / "run"
    assert main(["run", str(_write(tmp_path, FAILING)), "--out", str(out)]) == 1
    summary = json.loads((out / "summary.json").read_text())
    assert summary["failure_reasons"]["main/Fail"] == ["dock not found"]



def test_a_search_target_the_detector_cannot_know_is_bad_input(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``--set target=42`` exits 2 with the classes it could name, and no Python exception name."""
    code = main(["run", str(REPO / "trees" / "find_object.yaml"), "--set", "target=42",
                 "--out", str(tmp_path / "run"), "--quiet"])
    err = capsys.readouterr().err
    assert code == 2
    assert "names no class the detector knows" in err and "backpack" in err
    assert "ValueError" not in err and "Traceback" not in err

def test_duration_limit_exits_one(tmp_path: Path) -> None:
    """--max-duration shorter than the mission stops it with exit code 1."""
    out = tmp_path / "run"
    assert main(["run", str(_write(tmp_path, MISSION)), "--out", str(out), "--max-duration", "0.5"]) == 1
    assert json.loads((out / "summary.json").read_text())["stopped_by"] == "limit"


def test_flags_override_the_run_section(tmp_path: Path) -> None:
    """--tick-hz and --seed win over the mission's run: section and reach the run and the backend."""
    out = tmp_path / "run"
    mission = _write(tmp_path, MISSION)
    assert main(["run", str(mission), "--out", str(out), "--tick-hz", "5", "--seed", "7"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert (summary["ticks"], summary["seed"], summary["tick_hz"]) == (6, 7, 5.0)
    assert SEEN_OPTIONS == [{"seed": 7}]


def test_config_file_reaches_the_backend_as_a_mapping(tmp_path: Path) -> None:
    """--config FILE is read (safely) and handed to the backend factory as a dict."""
    config = _write(tmp_path, "lidar: {rate: 20}\n", "run-config.yaml")
    mission = _write(tmp_path, MISSION)
    assert main(["run", str(mission), "--out", str(tmp_path / "r"), "--config", str(config)]) == 0
    assert SEEN_OPTIONS[0]["config"] == {"lidar": {"rate": 20}}


def test_broken_mission_exits_two_with_file_and_line(tmp_path: Path, capsys: Capture) -> None:
    """A mission naming an unknown node type exits 2 with file:line on stderr and no traceback."""
    path = _write(tmp_path, "version: 1\nroot:\n  Wiat: {seconds: 1}\n")
    assert main(["run", str(path), "--backend", "clock"]) == 2
    err = capsys.readouterr().err
    assert f"{path}:3:" in err or "mission.yaml:3:" in err
    assert "Traceback" not in err


def test_unknown_backend_exits_two_naming_the_known_ones(tmp_path: Path, capsys: Capture) -> None:
    """--backend with a name nobody registered exits 2 and lists the backends."""
    assert main(["run", str(_write(tmp_path, MISSION)), "--backend", "gazebo"]) == 2
    assert "known backends: clock, recorded, ros2, sim" in capsys.readouterr().err


def test_no_plugins_flag_leaves_installed_plugins_out(tmp_path: Path, capsys: Capture) -> None:
    """With --no-plugins the plugin's backend is unknown."""
    assert main(["run", str(_write(tmp_path, MISSION)), "--no-plugins", "--out", str(tmp_path / "r")]) == 2
    assert "unknown backend 'clock'" in capsys.readouterr().err


def test_same_seed_on_the_simulator_gives_the_same_log_bytes(tmp_path: Path) -> None:
    """Two simulator runs of the same mission and seed write byte-identical tick logs."""
    tree = REPO / "trees" / "examples" / "timer_and_blackboard.yaml"
    logs = []
    for name in ("a", "b"):
        clean_state()
        assert main(["run", str(tree), "--backend", "sim", "--seed", "3", "--out", str(tmp_path / name)]) == 0
        logs.append((tmp_path / name / "ticks.jsonl").read_bytes())
    assert logs[0] == logs[1]
    assert b'"wall"' not in logs[0]


# -- run directories: checked before the run, one run at a time, no leftovers ------------------------

def test_out_at_a_file_or_an_uncreatable_place_exits_two(tmp_path: Path, capsys: Capture) -> None:
    """--out at a file, below a file, or where nothing can be made: exit 2 naming it, no traceback."""
    mission = _write(tmp_path, MISSION)
    afile = tmp_path / "afile"
    afile.write_text("mine")
    assert main(["run", str(mission), "--out", str(afile)]) == 2
    assert "is a file, not a directory" in capsys.readouterr().err
    assert main(["run", str(mission), "--out", str(afile / "sub")]) == 2
    assert "cannot create the run directory" in capsys.readouterr().err
    assert main(["run", str(mission), "--out", "/proc/missiontree-no-such/run"]) == 2
    assert "cannot create the run directory" in capsys.readouterr().err
    assert afile.read_text() == "mine"


def test_empty_out_is_refused(tmp_path: Path, capsys: Capture) -> None:
    """--out '' would write into the working directory: refused as a usage error (exit 2)."""
    with pytest.raises(SystemExit) as stopped:
        main(["run", str(_write(tmp_path, MISSION)), "--out", ""])
    assert stopped.value.code == 2
    assert "empty path" in capsys.readouterr().err


def test_a_directory_in_use_by_a_live_run_exits_two(tmp_path: Path, capsys: Capture) -> None:
    """The lock holds a live pid: exit 2 naming it; the other run's lock is left alone."""
    out = tmp_path / "run"
    out.mkdir()
    (out / "run.lock").write_text(f"{os.getppid()}\n")
    assert main(["run", str(_write(tmp_path, MISSION)), "--out", str(out)]) == 2
    assert f"in use by another run (pid {os.getppid()}" in capsys.readouterr().err
    assert (out / "run.lock").read_text().strip() == str(os.getppid())


def test_a_stale_lock_of_a_dead_run_is_taken_over(tmp_path: Path) -> None:
    """A lock whose pid is dead (a killed run) is taken over; the lock is gone after the run."""
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    out = tmp_path / "run"
    out.mkdir()
    (out / "run.lock").write_text(f"{dead.pid}\n")
    (out / "ticks.jsonl").write_text("")
    assert main(["run", str(_write(tmp_path, MISSION)), "--out", str(out)]) == 0
    assert not (out / "run.lock").exists()


def test_reusing_a_run_directory_clears_the_earlier_runs_files(tmp_path: Path) -> None:
    """An earlier run's alarms and pictures do not sit beside the new summary."""
    out = tmp_path / "run"
    mission = _write(tmp_path, MISSION)
    assert main(["run", str(mission), "--out", str(out)]) == 0
    (out / "alarms.jsonl").write_text('{"id": 1}\n')
    (out / "alarms").mkdir()
    (out / "alarms" / "alarm_001.png").write_bytes(b"png")
    assert main(["run", str(mission), "--out", str(out)]) == 0
    assert not (out / "alarms.jsonl").exists() and not (out / "alarms").exists()
    assert {"summary.json", "ticks.jsonl"} <= {p.name for p in out.iterdir()}


def test_a_non_empty_directory_that_holds_no_run_is_refused(tmp_path: Path, capsys: Capture) -> None:
    """--out at a folder of the user's files: exit 2, nothing deleted."""
    out = tmp_path / "documents"
    out.mkdir()
    (out / "notes.txt").write_text("keep me")
    assert main(["run", str(_write(tmp_path, MISSION)), "--out", str(out)]) == 2
    assert "holds no earlier run" in capsys.readouterr().err
    assert sorted(p.name for p in out.iterdir()) == ["notes.txt"]


def test_ctrl_c_during_start_up_prints_no_traceback(tmp_path: Path) -> None:
    """SIGINT while the command is still importing and loading: exit 130, one line, no traceback.

    A signal inside the interpreter's own start-up (before any missiontree code: a "Fatal Python
    error: init_..." of Python's, or a traceback through runpy's imports alone) is outside the
    command: that attempt is repeated, and a delay whose every attempt fell there is not counted.
    At least one attempt must reach the command.
    """
    package = str(Path(missiontree.__file__).parent)
    reached = 0
    for delay in (0.15, 0.4, 0.8):
        for _attempt in range(5):
            process = subprocess.Popen(
                [sys.executable, "-m", "missiontree", "run", str(REPO / "trees" / "patrol.yaml"), "--quiet",
                 "--out", str(tmp_path / f"run{delay}"), "--max-duration", "5"],
                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=REPO)
            time.sleep(delay)
            process.send_signal(signal.SIGINT)
            _, stderr = process.communicate(timeout=120)
            interpreter = "Fatal Python error: init_" in stderr or (
                "Traceback" in stderr and package not in stderr)
            if not interpreter:
                break
        else:
            continue  # the interpreter's own start-up every time: nothing of the command was tried
        reached += 1
        assert "Traceback" not in stderr, stderr
        assert process.returncode in (130, -signal.SIGINT), (delay, process.returncode, stderr)
    assert reached, "every Ctrl-C fell inside the interpreter's own start-up"


def test_the_result_line_says_why_a_mission_failed_in_its_own_words() -> None:
    """A FAILURE names the deciding reason and, under a Retry that ran out, the reason below it."""
    from missiontree.cli.run import outcome_text

    summary = {"status": "FAILURE",
               "failures": {"m": {"decided": 1, "reasons": []},
                            "m/retry": {"decided": 1, "reasons": ["Retry: all 3 attempts failed"]},
                            "m/retry/seq": {"decided": 0, "reasons": []}},
               "failure_reasons": {"m/retry": ["Retry: all 3 attempts failed"],
                                   "m/retry/seq/look": ["not found: no red backpack"]}}
    assert outcome_text(summary) == "why: Retry: all 3 attempts failed; below it: not found: no red backpack"
    reported = {**summary, "outcome": {"intent": {"text": "'tea': not served: nothing serves it"}}}
    assert outcome_text(reported).startswith("'tea': not served: nothing serves it; why: Retry")  # own words
    said_already = {**summary, "outcome": {"x": {"text": "gave up: " + outcome_text(summary)}}}
    assert outcome_text(said_already).count("Retry") == 1
    assert outcome_text({"status": "SUCCESS"}) == ""
    long = {"status": "FAILURE", "failures": {"m": {"decided": 1, "reasons": ["x" * 5000]}}}
    assert len(outcome_text(long)) <= 400


def test_a_retry_stopped_by_a_verdict_quotes_the_verdict_alone() -> None:
    """A Retry stopped by a verdict is the reason; an older attempt's deeper failure is not appended."""
    from missiontree.cli.run import outcome_text
    from missiontree.engine.faults import VERDICT_WORDS

    verdict = f"{VERDICT_WORDS}: not found: no red backpack"
    summary = {"status": "FAILURE",
               "failures": {"m/retry": {"decided": 1, "reasons": [verdict]}},
               "failure_reasons": {"m/retry": [verdict],
                                   "m/retry/seq/approach/confirm": ["not the red backpack: blue"]}}
    assert outcome_text(summary) == f"why: {verdict}"
