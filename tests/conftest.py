"""Shared fixtures: every test starts from clean global state (blackboard, structlog)."""

from __future__ import annotations

from collections.abc import Iterator

import py_trees
import pytest


@pytest.fixture(autouse=True)
def _clean_blackboard() -> Iterator[None]:
    """Clear py_trees' process-global blackboard before and after each test."""
    py_trees.blackboard.Blackboard.clear()
    yield
    py_trees.blackboard.Blackboard.clear()


#: Seconds the interpreter may take to exit once pytest has finished before the process is ended.
EXIT_GRACE_S = 120.0


def pytest_unconfigure(config: pytest.Config) -> None:
    """Arm a watchdog for the interpreter's exit: a run that finished must not hang the machine.

    Once, after a run with a failed ROS 2 test, the pytest process stayed alive for over 10 minutes
    after reporting (some thread a failed test left behind kept the interpreter from exiting). If the
    exit takes longer than EXIT_GRACE_S, faulthandler prints every thread's stack, which says what
    held it, and ends the process with exit code 1 instead of letting CI run into its time limit.
    """
    import faulthandler
    import sys

    faulthandler.dump_traceback_later(EXIT_GRACE_S, exit=True, file=sys.__stderr__)
