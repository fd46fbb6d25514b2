"""The simulated navigator's goal handle: cancel is a request, and an abort is about the goal."""

from __future__ import annotations

from missiontree.backends.sim.nav_handle import SimNavHandle
from missiontree.robot.actions import UNREACHABLE, ActionStatus, NavFeedback
from missiontree.types import Pose2D, Tolerance


def test_cancel_is_a_request_until_the_navigator_finishes_the_goal() -> None:
    handle = SimNavHandle(Pose2D(1.0, 2.0, 0.0), Tolerance(0.2, 0.3), sent=5.0)
    assert handle.status() is ActionStatus.ACCEPTED and handle.result() is None and handle.feedback() is None
    handle.cancel()
    assert handle.cancel_requested and handle.status() is ActionStatus.ACCEPTED
    handle.finish(ActionStatus.ABORTED, "path blocked", 206)
    result = handle.result()
    assert result is not None and result.status is ActionStatus.ABORTED and result.kind == UNREACHABLE
    handle.finish(ActionStatus.SUCCEEDED)  # a finished goal stays as it ended
    assert handle.status() is ActionStatus.ABORTED


def test_report_marks_the_goal_running_with_its_latest_feedback() -> None:
    """The navigator's progress reaches the handle through report(), not its private fields."""
    handle = SimNavHandle(Pose2D(1.0, 2.0, 0.0), Tolerance(0.2, 0.3), sent=5.0)
    feedback = NavFeedback(Pose2D(0.0, 0.0, 0.0), 2.2, 1.5, 0)
    handle.report(feedback)
    assert handle.status() is ActionStatus.RUNNING and handle.feedback() == feedback
