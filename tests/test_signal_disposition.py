"""The signal tests pass whatever SIGINT disposition the test run inherits.

Many CI runners start the suite as a background job, with SIGINT ignored; a child process then
inherits the ignored disposition. Each test here runs a signal test in a fresh pytest with SIGINT
ignored from the start.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

TESTS = Path(__file__).resolve().parent


def _run_with_sigint_ignored(node_id: str) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    return subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-rs", node_id],
        cwd=TESTS.parent, env=env, capture_output=True, text=True, timeout=240,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_IGN),  # noqa: PLW1509 - the point
    )


def test_runner_second_signal_test_passes_with_sigint_ignored() -> None:
    done = _run_with_sigint_ignored(
        "tests/engine/test_runner.py::test_second_signal_interrupts_at_once_but_still_halts_and_stops")
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-2000:]
    assert "1 passed" in done.stdout


def test_ros2_sigint_test_passes_with_sigint_ignored() -> None:
    pytest.importorskip("rclpy")
    done = _run_with_sigint_ignored(
        "tests/backends/ros2/test_ros2_robot.py::test_sigint_sends_zero_velocity_before_the_process_stops")
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-2000:]
    assert "1 passed" in done.stdout, done.stdout[-2000:]
