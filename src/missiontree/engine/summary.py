"""What ``summary.json`` says of a run: how it ended, what its nodes did, where its time went.

The runner ticks and decides how the run ended; these functions word it:

- :func:`provisional_summary` — written as the run starts, marked ``"complete": false``;
- :func:`run_summary` — the final one: status, why it stopped, ticks, events, pictures, the fault
  behind a FAILURE, what the leaves reported (``outcome``) and the tick recorder's counts;
- :func:`profile_section` and :func:`final_pose` — the parts that must never lose the summary when
  they fail (a measurement, a pose that cannot be read): their failure is written in its place.

The :class:`~missiontree.engine.recorder.RunRecorder` writes the result whole or not at all.
"""

from __future__ import annotations

import signal
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from missiontree.engine.profile import RunProfile
from missiontree.engine.tick_log import TickLog, TickRecorder, plain
from missiontree.robot.interface import Robot

__all__ = ["STOPPED_BY_ERROR", "STOPPED_BY_LIMIT", "STOPPED_BY_SIGNAL", "STOPPED_BY_STATUS", "RunEnd",
           "final_pose", "profile_section", "provisional_summary", "run_summary"]

#: Why a run ended (``stopped_by``).
STOPPED_BY_STATUS = "status"
STOPPED_BY_LIMIT = "limit"
STOPPED_BY_SIGNAL = "signal"
STOPPED_BY_ERROR = "error"


@dataclass(frozen=True)
class RunEnd:
    """How a run ended, as the runner saw it.

    Attributes:
        status: The root's status name at the end (``SUCCESS``, ``FAILURE``, ``RUNNING``, ...).
        stopped_by: ``status``, ``limit``, ``signal`` or ``error``.
        signum: The signal that stopped it, 0 when none did.
        duration: Robot-clock seconds from the first tick to the end.
        reason: Why it stopped when ``stopped_by`` is ``error`` ("" otherwise).
        fault: The faulted node's path, its error and the error's frames, when a fault lies behind a
            FAILURE; None when the run did not fail because of an error.
    """

    status: str
    stopped_by: str
    signum: int
    duration: float
    reason: str = ""
    fault: tuple[str, str, tuple[str, ...]] | None = None


def provisional_summary(mission: str, tick_hz: float, seed: int, robot: str) -> dict[str, Any]:
    """The summary written as the run starts: valid JSON marked incomplete until the run ends."""
    return plain({"mission": mission, "complete": False, "status": "RUNNING", "stopped_by": "",
                  "signal": "", "ticks": 0, "tick_hz": tick_hz, "seed": seed, "robot": robot})


def run_summary(mission: str, end: RunEnd, *, tick_hz: float, seed: int, robot: str, log: TickLog | None,
                recorder: TickRecorder | None, pictures: list[str],
                outcome: Mapping[str, Any]) -> dict[str, Any]:
    """How the run ended, what its nodes did and what its leaves reported (no profile, no pose)."""
    summary: dict[str, Any] = {
        "mission": mission,
        "complete": True,
        "status": end.status,
        "stopped_by": end.stopped_by,
        "signal": signal.Signals(end.signum).name if end.signum else "",
        "ticks": recorder.ticks if recorder else 0,
        "duration": end.duration,
        "tick_hz": tick_hz,
        "seed": seed,
        "robot": robot,
        "events": dict(sorted(log.event_counts.items())) if log else {},
        "pictures": pictures,
    }
    if end.stopped_by == STOPPED_BY_ERROR and end.reason:
        summary["reason"] = end.reason
    if end.fault is not None:  # failed because of an error, not because a condition was false
        node, cause, frames = end.fault
        summary["fault"] = {"node": node, "error": cause, "traceback": list(frames)}
    if outcome:  # what the mission did, in its leaves' words
        summary["outcome"] = dict(outcome)
    if recorder is not None:
        summary.update(recorder.summary())
    return summary


def profile_section(profiler: RunProfile | None, now: float, period: float,
                    duration: float) -> dict[str, Any]:
    """The run's profile (empty when off); the profiler's wrappers are removed (never raises)."""
    if profiler is None:
        return {}
    try:
        profiler.close_active(now, period)
        return profiler.summary(duration)
    except Exception as error:  # noqa: BLE001 - a failed measurement must not lose the summary
        return {"error": f"{type(error).__name__}: {error}"}
    finally:
        profiler.detach()


def final_pose(robot: Robot, final_state: Callable[[], dict[str, Any]] | None) -> dict[str, Any]:
    """The robot's own final pose estimate, plus what ``final_state`` adds (never raises)."""
    found: dict[str, Any] = {}
    try:
        stamped = robot.pose()
        if stamped is not None:
            pose = stamped.pose
            found["final_pose"] = {"x": pose.x, "y": pose.y, "yaw": pose.yaw, "stamp": stamped.stamp}
    except Exception as error:  # noqa: BLE001 - a pose that cannot be read must not lose the summary
        found["final_pose_error"] = f"{type(error).__name__}: {error}"
    if final_state is not None:
        try:
            found.update(final_state())
        except Exception as error:  # noqa: BLE001 - same
            found["final_state_error"] = f"{type(error).__name__}: {error}"
    return found
