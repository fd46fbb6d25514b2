"""Decorator node types: Retry, Repeat, Timeout, Inverter, RateLimit, OneShot, Guard, ForceSuccess/Failure.

Each is a real py_trees decorator (or a small subclass of one). The ones that measure time —
Timeout and RateLimit — use the robot's clock when the tree was set up with a mission context
(simulated time in the simulator), else :func:`time.monotonic`.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any, Literal

import py_trees
from pydantic import BaseModel, ConfigDict, Field, field_validator

from missiontree.engine.faults import (
    VERDICT_WORDS,
    FaultKeepingForceSuccess,
    FaultKeepingInverter,
    verdict_of,
)
from missiontree.engine.nodes.clock import Clock, clock_of
from missiontree.engine.nodes.conditions import ConditionFields, evaluate, read_key
from missiontree.engine.ports import BlackboardRef
from missiontree.engine.registry import NodeType

Behaviour = py_trees.behaviour.Behaviour
Status = py_trees.common.Status


class _Clocked:
    """Mixin: take the robot's clock from ``setup(context=...)``."""

    _clock: Clock = staticmethod(clock_of(None))  # type: ignore[assignment]

    def setup(self, **kwargs: Any) -> None:
        """Keep the mission context's clock (py_trees passes setup kwargs to every node)."""
        self._clock = clock_of(kwargs.get("context"))


# -- parameters --------------------------------------------------------------------------------


class _NoParams(BaseModel):
    model_config = ConfigDict(extra="forbid")


class RetryParams(BaseModel):
    """Parameters of Retry."""

    model_config = ConfigDict(extra="forbid")

    attempts: int = Field(ge=1, description="Runs of the child allowed; fail after this many failures.")


class RepeatParams(BaseModel):
    """Parameters of Repeat."""

    model_config = ConfigDict(extra="forbid")

    times: int = Field(description="Succeed after the child succeeded this many times in a row; -1 repeats "
                       "forever. A failure of the child fails the Repeat.")

    @field_validator("times")
    @classmethod
    def _forever_or_positive(cls, times: int) -> int:
        if times == 0 or times < -1:
            raise ValueError(f"expected -1 (forever) or at least 1, found {times}")
        return times


class TimeoutParams(BaseModel):
    """Parameters of Timeout."""

    model_config = ConfigDict(extra="forbid")

    seconds: float = Field(gt=0, description="Fail (halting the child) when it runs longer than this.")


class RateLimitParams(BaseModel):
    """Parameters of RateLimit."""

    model_config = ConfigDict(extra="forbid")

    period: float = Field(gt=0, description="Tick the child at most once every this many seconds; "
                          "in between, repeat its last result.")


class OneShotParams(BaseModel):
    """Parameters of OneShot."""

    model_config = ConfigDict(extra="forbid")

    on: Literal["success", "completion"] = Field(
        "success", description="success: run the child until it succeeds once, then always succeed; "
        "completion: run it once to SUCCESS or FAILURE and then always repeat that result.")


class GuardParams(ConditionFields):
    """Parameters of Guard: the blackboard condition re-checked before every tick of the child."""


# -- behaviours --------------------------------------------------------------------------------


class ClockedTimeout(_Clocked, py_trees.decorators.Timeout):
    """py_trees' Timeout on the mission clock instead of the wall clock."""

    def initialise(self) -> None:
        """Start the countdown on the mission clock."""
        self.finish_time = self._clock() + self.duration
        self.feedback_message = ""

    def update(self) -> Status:
        """Fail and halt the child once the time is up, else reflect the child."""
        now = self._clock()
        if self.decorated.status == Status.RUNNING and now > self.finish_time:
            self.feedback_message = f"timed out after {self.duration:g} s"
            self.decorated.stop(Status.INVALID)
            return Status.FAILURE
        if self.decorated.status == Status.RUNNING:
            self.feedback_message = f"{self.finish_time - now:.2f} s left"
        else:
            self.feedback_message = "child finished in time"
        return self.decorated.status


class RateLimit(_Clocked, py_trees.decorators.Decorator):
    """Tick the child at most once every ``period`` seconds; in between, repeat its last result.

    A child halted while RUNNING (its branch was pre-empted) is ticked again at once on re-entry.
    """

    def __init__(self, name: str, child: Behaviour, period: float) -> None:
        super().__init__(name=name, child=child)
        self.period = period
        self._last_tick: float | None = None
        self._last_status = Status.INVALID

    def tick(self) -> Iterator[Behaviour]:
        """Tick the child if it is due, else hold the last result without ticking it."""
        now = self._clock()
        held = self._last_status in (Status.SUCCESS, Status.FAILURE) or (
            self._last_status == Status.RUNNING and self.decorated.status == Status.RUNNING
        )
        if self._last_tick is not None and now - self._last_tick < self.period and held:
            self.status = self._last_status
            self.feedback_message = f"holding {self._last_status.value}; next tick in " \
                f"{self.period - (now - self._last_tick):.2f} s"
            yield self
            return
        self._last_tick = now
        yield from super().tick()
        self._last_status = self.decorated.status

    def update(self) -> Status:
        """Reflect the child."""
        return self.decorated.status


class VerdictRetry(py_trees.decorators.Retry):
    """py_trees' Retry, except that a child's FAILURE that is a verdict ends it at once.

    Running a search again after it answered "not found" only repeats the answer (and its cost);
    the Retry fails with the verdict's reason, so the run's reason is the answer, not an older
    attempt's failure.
    """

    def update(self) -> Status:
        """Run the child again after a failure, unless the failure is a verdict."""
        found = verdict_of(self.decorated)
        if found is not None:
            self.feedback_message = f"{VERDICT_WORDS}: {found[1]}"
            return Status.FAILURE
        return super().update()


class Guard(py_trees.decorators.EternalGuard):
    """Re-check a blackboard condition before every tick of the child; halt it and fail when false."""

    def __init__(self, name: str, child: Behaviour, params: GuardParams) -> None:
        self.params = params
        keys = {params.key}
        if isinstance(params.value, BlackboardRef):
            keys.add(params.value.key)
        super().__init__(name=name, child=child, condition=self._check, blackboard_keys=keys)

    def _check(self) -> bool:
        value = self.params.value
        if isinstance(value, BlackboardRef):
            value = read_key(self.blackboard, value.key)
        found = read_key(self.blackboard, self.params.key)
        holds, reason = evaluate(self.params.effective_op(), found, value)
        if not holds:
            self.feedback_message = f"guard {self.params.describe()} is false: {reason}"
        return holds


# -- factories -----------------------------------------------------------------------------------


def _one(children: list[Behaviour]) -> Behaviour:
    (child,) = children
    return child


def _oneshot(name: str, p: OneShotParams, children: list[Behaviour]) -> Behaviour:
    policy = (py_trees.common.OneShotPolicy.ON_SUCCESSFUL_COMPLETION if p.on == "success"
              else py_trees.common.OneShotPolicy.ON_COMPLETION)
    return py_trees.decorators.OneShot(name=name, child=_one(children), policy=policy)


DECORATORS = [
    NodeType("Retry", "decorator", RetryParams,
             lambda n, p, c: VerdictRetry(n, _one(c), num_failures=p.attempts),  # type: ignore
             "Run the child again after a failure, up to `attempts` runs; a verdict below (a leaf's "
             "answer that running it again cannot change) ends it at once."),
    NodeType("Repeat", "decorator", RepeatParams,
             lambda n, p, c: py_trees.decorators.Repeat(n, _one(c), num_success=p.times),  # type: ignore
             "Run the child again after each success, `times` successes in all (-1: forever)."),
    NodeType("Timeout", "decorator", TimeoutParams,
             lambda n, p, c: ClockedTimeout(n, _one(c), duration=p.seconds),  # type: ignore
             "Fail and halt the child when it runs longer than `seconds` (mission clock)."),
    NodeType("Inverter", "decorator", _NoParams,
             lambda n, p, c: FaultKeepingInverter(n, _one(c)),
             "Swap the child's SUCCESS and FAILURE (a FAILURE caused by an error stays FAILURE)."),
    NodeType("RateLimit", "decorator", RateLimitParams,
             lambda n, p, c: RateLimit(n, _one(c), period=p.period),  # type: ignore
             "Tick the child at most every `period` seconds; in between, repeat its last result."),
    NodeType("OneShot", "decorator", OneShotParams, _oneshot,  # type: ignore[arg-type]
             "Run the child to completion once, then keep returning that result."),
    NodeType("Guard", "decorator", GuardParams,
             lambda n, p, c: Guard(n, _one(c), p),  # type: ignore
             "Tick the child only while a blackboard condition holds; halt it and fail once it does not."),
    NodeType("ForceSuccess", "decorator", _NoParams,
             lambda n, p, c: FaultKeepingForceSuccess(n, _one(c)),
             "Turn the child's FAILURE into SUCCESS (RUNNING stays RUNNING; a FAILURE caused by an error "
             "stays FAILURE)."),
    NodeType("ForceFailure", "decorator", _NoParams,
             lambda n, p, c: py_trees.decorators.SuccessIsFailure(n, _one(c)),
             "Turn the child's SUCCESS into FAILURE (RUNNING stays RUNNING)."),
]
