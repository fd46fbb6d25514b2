"""Fault injection on the run itself: disk, run directory, signals, a killed run.

The faults: a disk that fills, a run directory deleted mid-run, a second signal at each phase of
shutdown, a run killed outright, two Ctrl-C within 50 ms.

Each asserts what every fault test does (:func:`conftest.assert_clean_end`): the robot stopped, a
valid summary that says why, nothing logged before the fault lost.
"""

from __future__ import annotations

import errno
import io
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest
from conftest import REPO, assert_clean_end, read_lines

from missiontree.engine.context import MissionContext
from missiontree.engine.leaf import Leaf, Status
from missiontree.engine.runner import Runner
from missiontree.testing import ClockRobot, ScriptedLeaf

TIMER = REPO / "trees" / "examples" / "timer_and_blackboard.yaml"


class _DiskThatFills(io.TextIOWrapper):
    """A log file on a disk with ``room`` bytes left: the write that would pass it fails with ENOSPC."""

    def __init__(self, path: Path, room: int) -> None:
        super().__init__(path.open("wb"), encoding="utf-8", newline="\n", write_through=True)
        self.room = room

    def write(self, text: str) -> int:
        self.room -= len(text.encode("utf-8"))
        if self.room < 0:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return super().write(text)


def test_a_disk_that_fills_ends_the_run_with_the_reason(tmp_path: Path) -> None:
    """The tick log's stream hits ENOSPC (an injected stream): the run stops, says why, keeps the lines."""
    robot = ClockRobot()
    with _DiskThatFills(tmp_path / "ticks.jsonl", room=4000) as disk:
        result = Runner(ScriptedLeaf("forever", script="R"), MissionContext(robot=robot), run_dir=tmp_path,
                        log_stream=disk, handle_signals=False, max_duration=600).run()
    assert (result.stopped_by, result.exit_code) == ("error", 1)
    summary = assert_clean_end(tmp_path, why="No space left on device", stopped_by="error",
                               stopped=lambda: robot.stop_calls == 1, finished_line=False)
    assert summary["ticks"] < 100  # stopped at the fault, not at the limit
    assert (tmp_path / "ticks.jsonl").stat().st_size <= 4000
    assert len(read_lines(tmp_path / "ticks.jsonl")) > 10  # what was written before the fault is kept


class _DeletesRunDir(Leaf):
    """Deletes the run directory on its fifth tick (an operator's rm -rf, a cleaner)."""

    def initialise(self) -> None:
        self.n = 0

    def update(self) -> Status:
        self.n += 1
        if self.n == 5:
            shutil.rmtree(self.context.run_dir)
        return Status.RUNNING


def test_a_run_directory_deleted_mid_run_is_reported_and_its_log_recovered(tmp_path: Path) -> None:
    """Deleted under the run: the run stops saying so, the directory is made again with the whole log."""
    robot = ClockRobot()
    out = tmp_path / "run"
    result = Runner(_DeletesRunDir("cleaner"), MissionContext(robot=robot), run_dir=out,
                    handle_signals=False, max_duration=60).run()
    assert (result.stopped_by, result.exit_code, result.ticks) == ("error", 1, 5)
    assert_clean_end(out, why="was deleted during the run", stopped_by="error",
                     stopped=lambda: robot.stop_calls == 1)


# -- a second signal at each phase of shutdown ------------------------------------------------------

class _SignalsOnce(Leaf):
    """Sends SIGINT on its third tick; optionally a second one when halted."""

    again_on_halt = False

    def initialise(self) -> None:
        self.n = 0

    def update(self) -> Status:
        self.n += 1
        if self.n == 3:
            os.kill(os.getpid(), signal.SIGINT)
        return Status.RUNNING

    def terminate(self, new_status: Status) -> None:
        self.halted_with = new_status
        if self.again_on_halt:
            os.kill(os.getpid(), signal.SIGINT)


class _SignalOnStop(ClockRobot):
    """A robot whose stop() is interrupted by another SIGINT."""

    def stop(self) -> None:
        os.kill(os.getpid(), signal.SIGINT)
        super().stop()


@pytest.mark.parametrize("phase", ["halt", "robot_stop", "summary"])
def test_a_second_signal_during_shutdown_loses_nothing(phase: str, tmp_path: Path) -> None:
    """A second SIGINT while halting, stopping the robot or writing the summary: all are still done."""
    before = signal.getsignal(signal.SIGINT)
    leaf = _SignalsOnce("watch")
    leaf.again_on_halt = phase == "halt"
    robot = _SignalOnStop() if phase == "robot_stop" else ClockRobot()

    def final_state() -> dict[str, Any]:
        if phase == "summary":
            os.kill(os.getpid(), signal.SIGINT)
        return {}

    result = Runner(leaf, MissionContext(robot=robot), run_dir=tmp_path, handle_signals=True,
                    final_state=final_state).run()
    assert (result.stopped_by, result.exit_code, result.ticks) == ("signal", 130, 3)
    assert leaf.halted_with == Status.INVALID
    summary = assert_clean_end(tmp_path, why='"signal": "SIGINT"', stopped_by="signal",
                               stopped=lambda: robot.stop_calls == 1)
    assert summary["status"] == "RUNNING"
    assert signal.getsignal(signal.SIGINT) == before


# -- through the command line -----------------------------------------------------------------------

def _start(out: Path, *extra: str) -> subprocess.Popen[str]:
    """`missiontree run` of a 7 s timer mission paced to wall time, started once summary.json exists."""
    process = subprocess.Popen(
        [sys.executable, "-m", "missiontree", "run", str(TIMER), "--realtime", "--quiet", "--out", str(out),
         *extra], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=REPO)
    deadline = time.monotonic() + 60
    while not (out / "summary.json").exists():
        assert process.poll() is None, process.communicate()
        assert time.monotonic() < deadline, "the run never started"
        time.sleep(0.05)
    time.sleep(0.5)
    return process


@pytest.mark.parametrize(("signum", "code"), [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_two_signals_within_50_ms_stop_by_signal_not_error(signum: int, code: int, tmp_path: Path) -> None:
    """Ctrl-C twice within 20 ms: exit 128+N, summary stopped_by signal (was: error/INVALID), no traceback."""
    out = tmp_path / "run"
    process = _start(out)
    process.send_signal(signum)
    time.sleep(0.02)
    process.send_signal(signum)
    stdout, stderr = process.communicate(timeout=60)
    assert process.returncode == code, (stdout, stderr)
    assert "Traceback" not in stderr
    summary = assert_clean_end(out, why=signal.Signals(signum).name, stopped_by="signal")
    assert summary["status"] == "RUNNING"
    assert not (out / "run.lock").exists()


def test_a_killed_run_leaves_a_summary_marked_incomplete_and_its_lock_is_taken_over(tmp_path: Path) -> None:
    """SIGKILL mid-run: summary.json is valid, marked complete: false; the next run takes the stale lock."""
    out = tmp_path / "run"
    process = _start(out)
    process.kill()
    process.communicate(timeout=30)
    summary = json.loads((out / "summary.json").read_text(encoding="utf-8"))
    assert summary["complete"] is False and summary["status"] == "RUNNING"
    assert (out / "run.lock").read_text().strip() == str(process.pid)
    command = [sys.executable, "-m", "missiontree", "run", str(TIMER), "--quiet", "--out", str(out)]
    again = subprocess.run(command, capture_output=True, text=True, cwd=REPO, timeout=120)
    assert again.returncode == 0, again.stderr
    assert json.loads((out / "summary.json").read_text())["complete"] is True
