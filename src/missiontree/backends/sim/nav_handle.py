"""The ActionHandle of a goal sent to the simulated navigator (its status, feedback and result)."""

from __future__ import annotations

from missiontree.robot.actions import UNREACHABLE, ActionResult, ActionStatus, NavFeedback
from missiontree.types import Pose2D, Tolerance

__all__ = ["SimNavHandle"]


class SimNavHandle:
    """The ActionHandle of one simulated NavigateToPose goal."""

    def __init__(self, goal: Pose2D, tolerance: Tolerance, sent: float) -> None:
        self.goal = goal
        self.tolerance = tolerance
        self.sent = sent
        self._status = ActionStatus.ACCEPTED
        self._feedback: NavFeedback | None = None
        self._result: ActionResult | None = None
        self.cancel_requested = False

    def status(self) -> ActionStatus:
        """Current status."""
        return self._status

    def feedback(self) -> NavFeedback | None:
        """Latest feedback (distance remaining along the path), None before the first."""
        return self._feedback

    def result(self) -> ActionResult | None:
        """The result once done."""
        return self._result

    def cancel(self) -> None:
        """Ask to cancel; takes effect at the simulator's next step (idempotent)."""
        if not self._status.done:
            self.cancel_requested = True

    def report(self, feedback: NavFeedback) -> None:
        """The navigator's progress: the goal is running, ``feedback`` its latest distance and time."""
        self._status = ActionStatus.RUNNING
        self._feedback = feedback

    def finish(self, status: ActionStatus, reason: str = "", code: int = 0) -> None:
        """End the goal with ``status`` (the first end wins; later calls are ignored)."""
        if not self._status.done:
            self._status = status
            # every abort of the in-process navigator is about the goal (no server to lose)
            kind = UNREACHABLE if status is ActionStatus.ABORTED else ""
            self._result = ActionResult(status, reason, code, kind=kind)
