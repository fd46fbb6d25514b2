"""Robot actions as handles: send, poll, cancel (Nav2 NavigateToPose semantics).

A backend's ``navigate_to`` returns at once with an :class:`ActionHandle`; the leaf polls
``status()`` every tick and ``cancel()``s it when halted. The end of an action is a
value, :class:`ActionResult`, with a short reason when it did not succeed.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

from missiontree.types import Pose2D


class ActionStatus(enum.Enum):
    """Lifecycle of an action, mirroring action_msgs/GoalStatus."""

    PENDING = "pending"      # sent, not yet accepted by the server
    ACCEPTED = "accepted"    # accepted, not yet executing
    RUNNING = "running"      # executing
    SUCCEEDED = "succeeded"
    ABORTED = "aborted"      # the server gave up; the result carries the reason
    CANCELED = "canceled"
    REJECTED = "rejected"    # the server refused the goal

    @property
    def done(self) -> bool:
        """True once the action has ended, whatever the outcome."""
        return self in _DONE


_DONE = {ActionStatus.SUCCEEDED, ActionStatus.ABORTED, ActionStatus.CANCELED, ActionStatus.REJECTED}


#: Failure kind: the goal itself cannot be reached (blocked, inside an obstacle); a patrol skips it.
UNREACHABLE = "unreachable"
#: Failure kind: the machinery is gone (no action server, the robot vanished, results lost); a
#: mission cannot go on and must fail with the reason, never skip on.
INFRASTRUCTURE = "infrastructure"


@dataclass(frozen=True)
class ActionResult:
    """How an action ended.

    Attributes:
        status: A final status.
        reason: Short human-readable reason; empty on success.
        code: Backend error code (Nav2 ``error_code``), 0 when none.
        value: Optional payload.
        kind: Why it failed, when the backend knows: :data:`UNREACHABLE` or
            :data:`INFRASTRUCTURE`; empty when unknown or on success.
    """

    status: ActionStatus
    reason: str = ""
    code: int = 0
    value: Any = None
    kind: str = ""

    @property
    def succeeded(self) -> bool:
        """True when the action succeeded."""
        return self.status is ActionStatus.SUCCEEDED


@dataclass(frozen=True)
class NavFeedback:
    """Progress of a navigation goal, like NavigateToPose feedback."""

    current_pose: Pose2D
    distance_remaining: float
    navigation_time: float = 0.0
    number_of_recoveries: int = 0


@runtime_checkable
class ActionHandle(Protocol):
    """A running robot action. Every method returns at once."""

    def status(self) -> ActionStatus:
        """Current status."""
        ...

    def feedback(self) -> NavFeedback | None:
        """Latest feedback, or None before the first."""
        ...

    def result(self) -> ActionResult | None:
        """The result once ``status().done``, else None."""
        ...

    def cancel(self) -> None:
        """Ask the action to stop; idempotent, safe after it ended."""
        ...


class RefusedAction:
    """An action refused before it ran: REJECTED from the start, with the reason and failure kind.

    What a robot that cannot move (a recording) or a goal the safety envelope refuses returns in
    place of a handle: the leaf polls it as any other and fails with the reason.
    """

    def __init__(self, reason: str, kind: str = INFRASTRUCTURE) -> None:
        self._result = ActionResult(ActionStatus.REJECTED, reason, kind=kind)

    def status(self) -> ActionStatus:
        """Always REJECTED."""
        return ActionStatus.REJECTED

    def feedback(self) -> NavFeedback | None:
        """None: the action never ran."""
        return None

    def result(self) -> ActionResult:
        """The refusal and its reason."""
        return self._result

    def cancel(self) -> None:
        """Nothing to cancel."""
