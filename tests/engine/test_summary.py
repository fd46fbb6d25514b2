"""Tests of summary.json's wording (engine.summary): provisional, final, the parts that must not fail."""

from __future__ import annotations

from typing import Any

from missiontree.engine.summary import RunEnd, final_pose, profile_section, provisional_summary, run_summary
from missiontree.testing import ClockRobot


def test_the_provisional_summary_is_marked_incomplete_and_running() -> None:
    """The summary written at the start says the run is not complete and still running."""
    summary = provisional_summary("patrol", 10.0, 3, "sim")
    assert (summary["complete"], summary["status"]) == (False, "RUNNING")
    assert (summary["ticks"], summary["seed"]) == (0, 3)


def test_the_run_summary_names_the_fault_and_the_reason_and_the_outcome() -> None:
    """A run stopped by an error keeps its reason; a fault gives node, error and frames; outcome is copied."""
    end = RunEnd("FAILURE", "error", 15, 2.5, reason="the tick log could not be written",
                 fault=("root/leaf", "ValueError: bad (at x.py:3 in update)", ("x.py:3 in update",)))
    summary = run_summary("m", end, tick_hz=10.0, seed=0, robot="sim", log=None, recorder=None, pictures=[],
                          outcome={"intent": {"served": "cup"}})
    assert summary["signal"] == "SIGTERM" and summary["reason"].startswith("the tick log")
    assert summary["fault"] == {"node": "root/leaf", "error": "ValueError: bad (at x.py:3 in update)",
                                "traceback": ["x.py:3 in update"]}
    assert summary["outcome"] == {"intent": {"served": "cup"}} and summary["complete"] is True


def test_a_reason_is_kept_only_when_an_error_stopped_the_run() -> None:
    """A run that ended on its status has no reason, even when one was noted."""
    end = RunEnd("SUCCESS", "status", 0, 1.0, reason="noted earlier")
    summary = run_summary("m", end, tick_hz=10.0, seed=0, robot="sim", log=None, recorder=None, pictures=[],
                          outcome={})
    assert "reason" not in summary and "fault" not in summary and "outcome" not in summary


class _NoPose(ClockRobot):
    def pose(self) -> Any:
        raise RuntimeError("no transform")


def test_a_pose_or_state_that_cannot_be_read_is_written_in_its_place() -> None:
    """final_pose never raises: a failing pose or final state becomes an error entry."""
    def broken_state() -> dict[str, Any]:
        raise KeyError("truth")

    found = final_pose(_NoPose(), broken_state)
    assert found == {"final_pose_error": "RuntimeError: no transform",
                     "final_state_error": "KeyError: 'truth'"}
    assert profile_section(None, 0.0, 0.1, 1.0) == {}
