"""Non-blocking model calls: submit on a worker pool, poll a handle every tick, time out, cancel.

A leaf never waits for a model on the tick thread. It submits the call in
``initialise()``, polls the returned :class:`ModelCall` in ``update()`` and cancels it in
``terminate()``::

    def initialise(self) -> None:
        caller = model_caller(self.context)
        self.call = caller.ask("vlm", [frame.color], surveillance_prompt(), SurveillanceVerdict,
                               node=self.name)

    def update(self) -> Status:
        status = self.call.status()
        if not status.done:
            return self.running(f"waiting for the vlm ({status.value})")
        if status is not CallStatus.SUCCEEDED:
            return self.fail(self.call.error())
        verdict = self.call.result().value   # a checked SurveillanceVerdict
        ...

    def terminate(self, new_status: Status) -> None:
        if self.call is not None:
            self.call.cancel()

Every call ends in one ``model_call`` tick-log event (role, provider, node, latency, outcome,
error), emitted on the thread that polls it, so events keep their order in the log — except the
successes of calls submitted with ``log_success=False`` (a detector on every camera frame: five
events a second would be most of the log; its failures are still logged).

**Time.** On a real robot a result is visible as soon as the worker finishes, and a timeout is
measured on the robot clock. In the simulator (``simulated=True``) a role may carry a
:class:`LatencyModel` — fixed, or uniform between two bounds drawn from a generator seeded by
the run seed and the role — and the result becomes visible exactly at ``submit time + latency``
on the simulated clock, waiting for the worker if it has not finished by then. A call whose drawn
latency exceeds its timeout times out exactly at ``submit time + timeout``. Runs therefore stay
deterministic byte for byte whatever the machine's speed. That waiting belongs to runs as fast as
possible only: when the simulator is paced to wall time (``realtime``), a poll never waits — a
result shows at ``submit time + latency`` or when the worker finishes, whichever is later, and a
call still running at ``submit time + timeout`` times out, as on a real robot. A role without a
latency model in the simulator answers at the first poll (the simulated clock stands still while
the worker runs).
"""

from __future__ import annotations

import enum
import random
import threading
import weakref
from collections.abc import Callable, Collection, Mapping, Sequence
from concurrent.futures import CancelledError, Future, ThreadPoolExecutor, wait
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Protocol

from pydantic import BaseModel

from missiontree.errors import ConfigError, MissionTreeError, ModelConfigError, ModelError, ModelTimeoutError
from missiontree.events import EventSink, NullEvents
from missiontree.reasoning.protocols import provider_name
from missiontree.services import ModelCalls

if TYPE_CHECKING:
    from missiontree.robot.interface import Robot

#: Key under which a mission's ModelCaller is kept in ``MissionContext.models``.
CALLER_KEY = "_caller"
#: Key under which the model wiring (session.models) leaves the :class:`CallSettings` of a models config.
SETTINGS_KEY = "_calls"

#: Wall-clock seconds the simulator waits for a worker that has not finished at its due time.
DEFAULT_WALL_TIMEOUT = 300.0


class CallContext(Protocol):
    """What a caller needs from the running mission (the engine's ``MissionContext`` provides it).

    Declared here so that this layer does not import the engine (imports point down only).
    """

    robot: Robot
    models: dict[str, Any]
    events: EventSink
    seed: int
    calls: ModelCalls | None


class BrokenProvider:
    """Stands in for a provider that could not be built; every use raises the reason.

    Attributes:
        role: The role it was configured for.
        name: The provider name from the config.
        reason: Why it could not be built (names the provider and the fix).
    """

    labels: list[str] = []

    def __init__(self, role: str, name: str, reason: str) -> None:
        self.role = role
        self.name = name
        self.reason = reason

    def _fail(self, *args: Any, **kwargs: Any) -> Any:
        raise ModelError(f"model role {self.role!r} (provider {self.name!r}) is unusable: {self.reason}")

    ask = chat = embed = detect = detect_frame = check = _fail

    def __repr__(self) -> str:
        return f"BrokenProvider(role={self.role!r}, name={self.name!r})"


class CallStatus(enum.Enum):
    """Lifecycle of a model call."""

    PENDING = "pending"        # submitted, waiting for a free worker
    RUNNING = "running"        # the provider is working (or simulated latency has not elapsed)
    SUCCEEDED = "succeeded"
    FAILED = "failed"          # the provider raised; ``error()`` says why
    TIMED_OUT = "timed_out"
    CANCELLED = "cancelled"

    @property
    def done(self) -> bool:
        """True once the call has ended, whatever the outcome."""
        return self in _DONE


_DONE = {CallStatus.SUCCEEDED, CallStatus.FAILED, CallStatus.TIMED_OUT, CallStatus.CANCELLED}


@dataclass(frozen=True)
class LatencyModel:
    """Simulated latency of a provider, in seconds of simulated time.

    Attributes:
        low: Smallest latency (the latency when fixed).
        high: Largest latency; equal to ``low`` for a fixed latency.
    """

    low: float
    high: float

    def draw(self, rng: random.Random) -> float:
        """One latency drawn uniformly from [low, high] (always consumes one number from ``rng``)."""
        value = rng.random()
        return self.low + (self.high - self.low) * value

    @classmethod
    def parse(cls, value: Any, where: str = "latency") -> LatencyModel | None:
        """Read a ``latency:`` config value.

        Accepted: ``null`` (none), a number (fixed seconds), ``{fixed: 1.0}``,
        ``{uniform: [0.5, 3.0]}``.

        Raises:
            ModelConfigError: Anything else, with the accepted forms.
        """
        forms = "a number of seconds, {fixed: 1.0} or {uniform: [0.5, 3.0]}"
        if value is None:
            return None
        if isinstance(value, bool):
            raise ModelConfigError(f"{where}: expected {forms}, found {value!r}")
        if isinstance(value, int | float):
            return cls._checked(float(value), float(value), where)
        if isinstance(value, Mapping) and len(value) == 1:
            (kind, arg), = value.items()
            if kind == "fixed" and isinstance(arg, int | float) and not isinstance(arg, bool):
                return cls._checked(float(arg), float(arg), where)
            if (kind == "uniform" and isinstance(arg, list | tuple) and len(arg) == 2
                    and all(isinstance(a, int | float) and not isinstance(a, bool) for a in arg)):
                return cls._checked(float(arg[0]), float(arg[1]), where)
        raise ModelConfigError(f"{where}: expected {forms}, found {value!r}")

    @classmethod
    def _checked(cls, low: float, high: float, where: str) -> LatencyModel:
        if not 0.0 <= low <= high:
            raise ModelConfigError(
                f"{where}: expected 0 <= low <= high seconds, found low={low}, high={high}; "
                "swap the bounds or use non-negative numbers")
        return cls(low, high)


@dataclass(frozen=True)
class CallSettings:
    """How a mission's model calls run, from the models config (``latency:``/``timeout:`` per role).

    Attributes:
        latency: Simulated latency model per role.
        timeouts: Timeout per role in seconds (None: no timeout).
        default_timeout: Timeout of roles without their own.
        workers: Worker threads.
    """

    latency: Mapping[str, LatencyModel | None] = field(default_factory=dict)
    timeouts: Mapping[str, float | None] = field(default_factory=dict)
    default_timeout: float | None = 30.0
    workers: int = 2


class ModelCall:
    """Handle of one submitted model call. Poll ``status()``; every method returns at once.

    Only the thread that ticks the tree should poll and cancel it.
    """

    def __init__(
        self,
        caller: ModelCaller,
        role: str,
        provider: str,
        node: str,
        future: Future[Any],
        submitted_at: float,
        timeout: float | None,
        simulated_latency: float | None,
    ) -> None:
        self.role = role
        self.provider = provider
        self.node = node
        self.submitted_at = submitted_at
        self.timeout = timeout
        self._caller = caller
        self._future = future
        self._simulated_latency = simulated_latency
        self._status = CallStatus.PENDING
        self._result: Any = None
        self._exception: BaseException | None = None
        self._error = ""
        self._latency: float | None = None
        self.finished_at: float | None = None  # robot-clock time the worker finished (real robots)
        self.log_success = True  # False: a success ends without a model_call event (see submit)

    # -- polling ---------------------------------------------------------------------------------

    def status(self) -> CallStatus:
        """The call's status now; the first time it is final, the ``model_call`` event is emitted."""
        if self._status.done:
            return self._status
        now = self._caller.clock()
        if self._simulated_latency is not None:
            return self._poll_simulated(now)
        return self._poll_real(now)

    def _poll_simulated(self, now: float) -> CallStatus:
        latency = self._simulated_latency or 0.0
        if self.timeout is not None and latency > self.timeout:
            if now >= self.submitted_at + self.timeout:
                self._future.cancel()
                return self._finish(CallStatus.TIMED_OUT, self.timeout, error=self._timeout_reason())
            return self._set_running()
        if now < self.submitted_at + latency:
            return self._set_running()
        if self._caller.realtime:  # paced to wall time: never wait on the tick thread
            if self._future.done():
                return self._finish_from_future(max(latency, now - self.submitted_at))
            if self.timeout is not None and now >= self.submitted_at + self.timeout:
                self._future.cancel()
                return self._finish(CallStatus.TIMED_OUT, self.timeout, error=self._timeout_reason())
            return self._set_running()
        # wait() rather than result(): a provider's own TimeoutError must not pass for the wall limit.
        wait([self._future], timeout=self._caller.wall_timeout)
        if not self._future.done():
            self._future.cancel()
            return self._finish(CallStatus.TIMED_OUT, latency, error=(
                f"{self.provider}: the provider did not finish within "
                f"{self._caller.wall_timeout:g} s of wall time (simulated latency {latency:g} s); "
                "check that the model server answers"))
        return self._finish_from_future(latency)

    def _poll_real(self, now: float) -> CallStatus:
        if self._future.done():
            finished = self.finished_at if self.finished_at is not None else now
            return self._finish_from_future(max(0.0, finished - self.submitted_at))
        if self.timeout is not None and now - self.submitted_at >= self.timeout:
            self._future.cancel()
            return self._finish(CallStatus.TIMED_OUT, self.timeout, error=self._timeout_reason())
        if self._future.running():
            return self._set_running()
        return self._status

    def _set_running(self) -> CallStatus:
        self._status = CallStatus.RUNNING
        return self._status

    def _timeout_reason(self) -> str:
        return (f"{self.provider}: no answer for role {self.role!r} within {self.timeout:g} s; "
                "raise the timeout or use a faster model")

    def _finish_from_future(self, latency: float) -> CallStatus:
        # The exception is read, not raised here: raising it (Future.result) would add this frame,
        # which holds the call, to its traceback, a cycle keeping the call's images until a gc pass.
        try:
            exc = self._future.exception(timeout=0)
        except CancelledError:
            return self._finish(CallStatus.CANCELLED, latency, error="cancelled")
        if exc is not None:
            self._exception = exc
            status = CallStatus.TIMED_OUT if isinstance(exc, ModelTimeoutError) else CallStatus.FAILED
            return self._finish(status, latency, error=_describe(exc, self.provider))
        self._result = self._future.result(timeout=0)
        return self._finish(CallStatus.SUCCEEDED, latency)

    def _finish(self, status: CallStatus, latency: float, error: str = "") -> CallStatus:
        self._status = status
        self._latency = latency
        self._error = error
        fields: dict[str, Any] = {
            "role": self.role, "provider": self.provider, "latency": round(latency, 6),
            "outcome": status.value,
        }
        if self.node:
            fields["node"] = self.node
        if error:
            fields["error"] = error
        for source in (self._result, self._exception):
            attempts = getattr(source, "attempts", None)
            if isinstance(attempts, int):
                fields["attempts"] = attempts
            rejected = getattr(source, "rejected", None)
            if rejected:
                fields["rejected"] = list(rejected)
        if status is not CallStatus.SUCCEEDED or self.log_success:
            self._caller.events.emit("model_call", **fields)
        return status

    # -- results ---------------------------------------------------------------------------------

    @property
    def done(self) -> bool:
        """True once the call has ended (polls)."""
        return self.status().done

    @property
    def latency(self) -> float | None:
        """Seconds from submit to the outcome (simulated seconds in the simulator), None until done."""
        return self._latency

    def result(self) -> Any:
        """The provider's return value once SUCCEEDED, else None."""
        return self._result if self.status() is CallStatus.SUCCEEDED else None

    def error(self) -> str:
        """Why the call did not succeed (names the provider), empty while running or on success."""
        self.status()
        return self._error

    def exception(self) -> BaseException | None:
        """The exception the provider raised, when FAILED."""
        self.status()
        return self._exception

    def cancel(self) -> None:
        """Stop caring about the call: it ends CANCELLED unless already done. Idempotent.

        A provider already running on a worker finishes in the background; its result is dropped.
        """
        if self._status.done:
            return
        self._future.cancel()
        now = self._caller.clock()
        self._finish(CallStatus.CANCELLED, max(0.0, now - self.submitted_at), error="cancelled")


def _stamp_finished(holder: list[weakref.ref[ModelCall]], clock: Callable[[], float]) -> None:
    """Note when a real call's worker finished, if the call is still wanted."""
    call = holder[0]() if holder else None
    if call is not None:
        call.finished_at = clock()


class ModelCaller:
    """Runs model calls on a worker pool and hands out :class:`ModelCall` handles.

    Args:
        clock: The robot clock (``robot.now``).
        events: Tick-log sink for ``model_call`` events.
        simulated: True in the simulator: latency is modelled on ``clock`` (see module docstring).
        latency: Latency model per role (used only when ``simulated``).
        timeouts: Default timeout per role in seconds (``None``: no timeout).
        models: Providers by role, used by :meth:`call`.
        seed: Run seed; latency draws use ``Random(f"{seed}:{role}")``.
        workers: Worker threads.
        default_timeout: Timeout for roles without their own.
        wall_timeout: Wall-clock seconds the simulator waits for a worker past its due time.
        realtime: The simulated clock follows wall time: polls never wait for a worker (a slow
            model must not stall the tick); runs are then not reproducible byte for byte.
    """

    def __init__(
        self,
        clock: Callable[[], float],
        events: EventSink | None = None,
        *,
        simulated: bool = False,
        latency: Mapping[str, LatencyModel | None] | None = None,
        timeouts: Mapping[str, float | None] | None = None,
        models: Mapping[str, Any] | None = None,
        seed: int = 0,
        workers: int = 2,
        default_timeout: float | None = 30.0,
        wall_timeout: float = DEFAULT_WALL_TIMEOUT,
        realtime: bool = False,
    ) -> None:
        self.clock = clock
        self.events: EventSink = events if events is not None else NullEvents()
        self.simulated = simulated
        self.latency = dict(latency or {})
        self.timeouts = dict(timeouts or {})
        self.models = models if models is not None else {}
        self.seed = seed
        self.default_timeout = default_timeout
        self.wall_timeout = wall_timeout
        self.realtime = realtime
        self._workers = workers
        self._pool: ThreadPoolExecutor | None = None
        self._rngs: dict[str, random.Random] = {}
        self._lock = threading.Lock()

    @classmethod
    def for_context(cls, context: CallContext, settings: CallSettings | None = None,
                    events: EventSink | None = None, realtime: bool | None = None) -> ModelCaller:
        """A caller on the context's robot clock, models and seed, with ``settings``.

        ``events`` and ``realtime`` default to the context's own as they are now.
        """
        robot = context.robot
        settings = settings or CallSettings()
        return cls(robot.now, context.events if events is None else events,
                   simulated=bool(getattr(robot, "simulated", False)),
                   latency=settings.latency, timeouts=settings.timeouts, models=context.models,
                   seed=context.seed, workers=settings.workers, default_timeout=settings.default_timeout,
                   realtime=bool(getattr(context, "realtime", False)) if realtime is None else realtime)

    def submit(
        self,
        role: str,
        fn: Callable[..., Any],
        *args: Any,
        timeout: float | None | str = "default",
        provider: str | None = None,
        node: str = "",
        log_success: bool = True,
        **kwargs: Any,
    ) -> ModelCall:
        """Run ``fn(*args, **kwargs)`` on a worker and return its handle at once.

        Args:
            role: The model role (``vlm``, ``llm``, ``detector``, ...): picks latency and timeout.
            fn: The blocking function (usually a provider method or a checked-answer helper).
            *args: Its positional arguments.
            timeout: Seconds until TIMED_OUT; ``None`` for none; default: the role's or the caller's.
            provider: Name shown in events; default: the name of the provider configured for ``role``.
            node: The submitting node's name, for the event.
            log_success: False: a success ends without a ``model_call`` event (per-frame calls).
            **kwargs: Its keyword arguments.
        """
        limit = self.timeouts.get(role, self.default_timeout) if timeout == "default" else timeout
        if limit is not None and not isinstance(limit, int | float):
            raise ConfigError(f"timeout for role {role!r}: expected seconds or None, found {limit!r}")
        name = provider or (provider_name(self.models[role]) if role in self.models else role)
        submitted = self.clock()
        simulated_latency: float | None = None
        if self.simulated:
            model = self.latency.get(role)
            simulated_latency = model.draw(self._rng(role)) if model is not None else 0.0
        # A weak reference: a provider's exception keeps this function's frame in its traceback, and
        # the call keeps the exception; a strong one made a cycle holding the call's images (frames)
        # until the cyclic garbage collector ran (numpy buffers do not count towards its thresholds:
        # the two-hour soak held up to ~9 MiB of frames of failed calls at a time).
        holder: list[weakref.ref[ModelCall]] = []

        def run() -> Any:
            try:
                return fn(*args, **kwargs)
            finally:
                if not self.simulated:
                    _stamp_finished(holder, self.clock)  # no local here may hold the call

        future = self._executor().submit(run)
        call = ModelCall(self, role, name, node, future, submitted, limit, simulated_latency)
        call.log_success = log_success
        holder.append(weakref.ref(call))
        return call

    def call(self, role: str, method: str, *args: Any, timeout: float | None | str = "default",
             node: str = "", **kwargs: Any) -> ModelCall:
        """Submit ``models[role].<method>(*args, **kwargs)``.

        Raises:
            ConfigError: No provider configured for ``role`` (names the configured roles).
        """
        provider = self._provider(role)
        return self.submit(role, getattr(provider, method), *args, timeout=timeout,
                           provider=provider_name(provider), node=node, **kwargs)

    def ask(self, role: str, images: Sequence[Any], prompt: str, schema: type[BaseModel] | None = None, *,
            valid_ids: Collection[str] | None = None, timeout: float | None | str = "default",
            node: str = "") -> ModelCall:
        """Ask the VLM of ``role`` about ``images``; with a schema the answer is checked.

        The result is the answer text without a schema, else a
        :class:`~missiontree.reasoning.checks.CheckedAnswer` (validated, ids grounded in
        ``valid_ids``, retried once with the error fed back).
        """
        if schema is None:
            return self.call(role, "ask", list(images), prompt, timeout=timeout, node=node)
        from missiontree.reasoning.checks import ask_checked

        provider = self._provider(role)
        return self.submit(role, ask_checked, provider, list(images), prompt, schema, valid_ids=valid_ids,
                           timeout=timeout, provider=provider_name(provider), node=node)

    def chat(self, role: str, messages: Sequence[Any], schema: type[BaseModel] | None = None, *,
             valid_ids: Collection[str] | None = None, timeout: float | None | str = "default",
             node: str = "") -> ModelCall:
        """Ask the language model of ``role``; with a schema the answer is checked (as :meth:`ask`)."""
        if schema is None:
            return self.call(role, "chat", list(messages), timeout=timeout, node=node)
        from missiontree.reasoning.checks import chat_checked

        provider = self._provider(role)
        return self.submit(role, chat_checked, provider, list(messages), schema, valid_ids=valid_ids,
                           timeout=timeout, provider=provider_name(provider), node=node)

    def _provider(self, role: str) -> Any:
        if role not in self.models:
            known = ", ".join(sorted(r for r in self.models if not r.startswith("_"))) or "none"
            raise ConfigError(
                f"no model configured for role {role!r} (configured: {known}); "
                "add it to the models config (config/models/*.yaml)")
        return self.models[role]

    def close(self) -> None:
        """Stop accepting calls; queued calls are dropped, running ones finish in the background."""
        with self._lock:
            if self._pool is not None:
                self._pool.shutdown(wait=False, cancel_futures=True)
                self._pool = None

    def _executor(self) -> ThreadPoolExecutor:
        with self._lock:
            if self._pool is None:
                self._pool = ThreadPoolExecutor(max_workers=self._workers, thread_name_prefix="model-call")
            return self._pool

    def _rng(self, role: str) -> random.Random:
        if role not in self._rngs:
            self._rngs[role] = random.Random(f"{self.seed}:{role}")
        return self._rngs[role]


def model_caller(context: CallContext) -> ModelCaller:
    """The mission's ModelCaller: the one the session bound (``context.calls``), else made on first use.

    A session binds the caller before any leaf is set up
    (:meth:`missiontree.reasoning.models.Models.bind`). A context made by hand (a test, an example)
    gets one here on first use, from its models and their call settings, and the providers marked
    ``needs_robot`` are bound then (see :func:`bind_providers`).
    """
    calls = getattr(context, "calls", None)  # a context made before it had the field
    if isinstance(calls, ModelCaller):
        return calls
    caller = context.models.get(CALLER_KEY)
    if not isinstance(caller, ModelCaller):
        settings = context.models.get(SETTINGS_KEY)
        caller = ModelCaller.for_context(context, settings if isinstance(settings, CallSettings) else None)
        bind_providers(context.models, context.robot)
        context.models[CALLER_KEY] = caller
    context.calls = caller
    return caller


def bind_providers(models: dict[str, Any], robot: Robot) -> None:
    """Bind the providers marked ``needs_robot`` (the simulation oracle detector) to ``robot``.

    One that refuses the robot is replaced by a :class:`BrokenProvider` carrying the reason, so the
    leaves that use it fail with that reason.
    """
    for role, provider in list(models.items()):
        if role.startswith("_") or getattr(provider, "needs_robot", False) is not True:
            continue
        try:
            provider.bind(robot)
        except MissionTreeError as exc:
            models[role] = BrokenProvider(role, provider_name(provider), str(exc))


def _describe(exc: BaseException, provider: str) -> str:
    text = str(exc) if isinstance(exc, MissionTreeError) else f"{type(exc).__name__}: {exc}"
    return text if provider in text else f"{provider}: {text}"
