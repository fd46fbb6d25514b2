"""Fault injection harness: a simulator robot whose machinery fails on cue, missions, log checks.

Every fault test asserts the same three things (:func:`assert_clean_end`): the robot was stopped,
``summary.json`` is valid, complete and says why the run ended, and the tick log kept everything
logged before the fault (whole JSON lines, ticks numbered 1..N without a gap, the end line last).
"""

from __future__ import annotations

import json
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from missiontree.robot.actions import INFRASTRUCTURE, ActionResult, ActionStatus
from missiontree.testing import clean_state, fresh_plugins

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "tests" / "reasoning"))  # the fake OpenAI-compatible server


@pytest.fixture(autouse=True)
def _clean() -> None:
    clean_state()


class LosableHandle:
    """A navigation goal whose action server vanishes when the robot's machinery is lost."""

    def __init__(self, handle: Any, robot: FaultyRobot) -> None:
        self._handle = handle
        self._robot = robot
        self._lost_result: ActionResult | None = None

    def _check(self) -> None:
        if self._lost_result is None and self._robot.lost and not self._handle.status().done:
            self._handle.cancel()
            self._lost_result = ActionResult(ActionStatus.ABORTED, "NavigateToPose server vanished",
                                             kind=INFRASTRUCTURE)

    def status(self) -> ActionStatus:
        """ABORTED once lost, else the simulator's status."""
        self._check()
        return self._lost_result.status if self._lost_result else self._handle.status()

    def result(self) -> ActionResult | None:
        """The infrastructure abort once lost, else the simulator's result."""
        self._check()
        return self._lost_result or self._handle.result()

    def feedback(self) -> Any:
        """The simulator's feedback."""
        return self._handle.feedback()

    def cancel(self) -> None:
        """Cancel the simulator's goal."""
        self._handle.cancel()


class FaultyRobot:
    """A SimRobot proxy: the navigation server vanishes at ``lost_at``; sensors freeze at ``quiet_at``.

    Frozen sensors keep answering with their last reading (its stamp ages), as a ROS 2 robot whose
    publishers died does. ``stop()`` calls are counted.
    """

    def __init__(self, robot: Any, lost_at: float | None = None, quiet_at: float | None = None) -> None:
        self._robot = robot
        self.lost_at = lost_at
        self.quiet_at = quiet_at
        self.stop_calls = 0
        self.goals_sent = 0
        self._frozen: dict[str, Any] = {}

    def __getattr__(self, name: str) -> Any:
        return getattr(self._robot, name)

    @property
    def lost(self) -> bool:
        """True once the navigation machinery is gone."""
        return self.lost_at is not None and self._robot.now() >= self.lost_at

    def _sensor(self, name: str) -> Any:
        if self.quiet_at is not None and self._robot.now() >= self.quiet_at:
            return self._frozen.get(name)
        value = getattr(self._robot, name)()
        self._frozen[name] = value
        return value

    def pose(self) -> Any:
        """The pose (frozen once quiet)."""
        return self._sensor("pose")

    def scan(self) -> Any:
        """The scan (frozen once quiet)."""
        return self._sensor("scan")

    def rgbd(self) -> Any:
        """The camera frame (frozen once quiet)."""
        return self._sensor("rgbd")

    def navigate_to(self, goal: Any, tolerance: Any = None) -> LosableHandle:
        """A goal on the simulator that aborts as infrastructure once the machinery is lost."""
        self.goals_sent += 1
        return LosableHandle(self._robot.navigate_to(goal, tolerance), self)

    def stop(self) -> None:
        """Counted, then the simulator's stop (zero velocity, navigation cancelled)."""
        self.stop_calls += 1
        self._robot.stop()


def faulty_plugins(made: list[FaultyRobot], **faults: Any) -> Any:
    """Plugins with a ``faulty`` backend: the simulator wrapped in a :class:`FaultyRobot`."""
    plugins = fresh_plugins()
    sim = plugins.backend("sim")

    def factory(options: dict[str, Any]) -> FaultyRobot:
        robot = FaultyRobot(sim(options), **faults)
        made.append(robot)
        return robot

    plugins.backends["faulty"] = factory
    return plugins


def read_lines(path: Path) -> list[dict[str, Any]]:
    """Every line of a JSONL file, each checked to be a whole JSON object."""
    return [json.loads(line) for line in path.read_text(encoding="utf-8").splitlines()]


def assert_clean_end(run_dir: Path, *, why: str, stopped_by: str = "status",
                     stopped: Callable[[], bool] | None = None, finished_line: bool = True) -> dict[str, Any]:
    """The run ended cleanly after a fault: see the module docstring. Returns the summary."""
    summary = json.loads((run_dir / "summary.json").read_text(encoding="utf-8"))
    assert summary["complete"] is True
    assert summary["status"] != "SUCCESS" and summary["stopped_by"] == stopped_by
    said = json.dumps(summary)
    assert why in said, f"summary does not say {why!r}: {said[:2000]}"
    lines = read_lines(run_dir / "ticks.jsonl")
    ticks = [line["tick"] for line in lines if line.get("event") == "tick"]
    assert ticks == list(range(1, len(ticks) + 1)), "a tick line was lost"
    assert lines[0]["event"] == "mission_started"
    if finished_line:
        assert lines[-1]["event"] == "mission_finished"
    if stopped is not None:
        assert stopped(), "the robot was not stopped"
    return summary
