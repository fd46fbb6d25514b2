"""The base class of missiontree leaves: py_trees' lifecycle plus context, ports and safe failure.

Lifecycle, as in py_trees' ``Behaviour``, each piece of work in the method where it belongs:

- ``__init__(name, params)`` only stores the validated parameters; no robot is needed.
- ``setup(context=...)`` receives the :class:`~missiontree.engine.context.MissionContext`
  (kept as ``self.ctx``) and calls :meth:`Leaf.on_setup` to connect and check.
- ``initialise()`` starts the work (sends a goal, submits a model call).
- ``update()`` polls and returns at once; it ends with ``return self.fail("reason")`` for an
  expected failure, which sets the feedback message the tick log records.
- ``terminate(new_status)`` cancels what ``initialise()`` started when halted.

An exception raised in any of them becomes FAILURE of this leaf with the error and where it was
raised as the reason (``ValueError: ... (at my_plugin/leaves.py:42 in update)``), an ``error``
event carrying ``where`` (file:line) and the ``traceback`` (file, line and function of each frame;
no source text or values), and a fault (:mod:`missiontree.engine.faults`: no Inverter or ForceSuccess
turns it into SUCCESS); the run goes on.
"""

from __future__ import annotations

import inspect
from collections.abc import Iterator
from typing import Any, ClassVar

import py_trees
from pydantic import BaseModel, TypeAdapter

from missiontree.engine.context import MissionContext
from missiontree.engine.faults import clear_fault, clear_verdict, error_site, mark_fault, mark_verdict
from missiontree.engine.ports import BlackboardRef, ports_of

Status = py_trees.common.Status
RUNNING = Status.RUNNING
INVALID = Status.INVALID
DEBUG = py_trees.logging.Level.DEBUG
#: Every status, for py_trees' check of what ``update`` returned (a tuple: equality, like its list).
STATUSES = tuple(Status)


class NoParams(BaseModel):
    """The parameters of a leaf that takes none (pydantic's BaseModel itself cannot be instantiated)."""


class Leaf(py_trees.behaviour.Behaviour):
    """Base for every leaf node type.

    Subclasses set ``Params`` (a pydantic model: parameters and ports in one place) and a class
    docstring whose first line is the summary ``missiontree nodes`` prints.
    """

    Params: ClassVar[type[BaseModel]] = NoParams

    def __init__(self, name: str, params: BaseModel | None = None) -> None:
        super().__init__(name=name)
        self.params = params if params is not None else self.Params()
        self.ctx: MissionContext | None = None
        self.failure_reason = ""
        self._ports = ports_of(type(self.params))
        self.bb = self.attach_blackboard_client(name=name)
        access = py_trees.common.Access
        for field_name, port in self._ports.items():
            key = getattr(self.params, field_name)
            self.bb.register_key(key=key, access=access.WRITE if port.direction == "out" else access.READ)
        for field_name in type(self.params).model_fields:
            raw = getattr(self.params, field_name, None)
            if isinstance(raw, BlackboardRef):
                self.bb.register_key(key=raw.key, access=access.READ)

    # -- lifecycle ---------------------------------------------------------------------------

    def setup(self, **kwargs: Any) -> None:
        """Keep the mission context and let the subclass connect and check (``on_setup``)."""
        context = kwargs.get("context")
        if context is not None:
            self.ctx = context
        self.on_setup()

    def on_setup(self) -> None:
        """Connect and check; override. ``self.ctx`` is set when a context was given."""

    def tick(self) -> Iterator[py_trees.behaviour.Behaviour]:
        """Tick as py_trees does, turning an exception into FAILURE of this leaf (a fault).

        py_trees' ``Behaviour.tick`` inlined (one generator frame a tick fewer), with its debug line
        formatted only when py_trees logs at debug level and the status checked against a tuple
        rather than a list of the enum built every tick: the same calls in the same order.
        """
        try:
            if self.status is not RUNNING:
                clear_fault(self)
                clear_verdict(self)
                if py_trees.logging.level is DEBUG:
                    self.logger.debug(f"{self.__class__.__name__}.tick()")
                self.initialise()
            elif py_trees.logging.level is DEBUG:
                self.logger.debug(f"{self.__class__.__name__}.tick()")
            new_status = self.update()
            if new_status not in STATUSES:
                self.logger.error(f"A behaviour returned an invalid status, setting to INVALID "
                                  f"[{new_status}][{self.name}]")
                new_status = Status.INVALID
            if new_status is not RUNNING:
                self.stop(new_status)
            self.status = new_status
        except Exception as error:  # noqa: BLE001 - a leaf's bug must not kill the mission
            self._fail_on_exception(error)
        yield self

    def stop(self, new_status: Status) -> None:
        """Stop as py_trees does; when halted (INVALID), an exception in terminate() is reported, not raised.

        A parent halts its running children from inside its own tick; a cancel that raises must not
        escape into the parent (and from there end the run). Inside this leaf's own tick, stop()
        keeps raising so that :meth:`tick` turns the error into FAILURE. (py_trees' ``stop``
        inlined: its debug line is formatted only when logged.)
        """
        if new_status is not INVALID:
            if py_trees.logging.level is DEBUG:
                self._log_stop(new_status)
            self.terminate(new_status)
            self.status = new_status
            self.iterator = self.tick()
            return
        try:
            if py_trees.logging.level is DEBUG:
                self._log_stop(new_status)
            self.terminate(new_status)
            self.status = new_status
            self.iterator = self.tick()
        except Exception as error:  # noqa: BLE001 - a failed cancel must not kill the mission
            self._report_error(error)
            self.status = Status.INVALID
            self.iterator = self.tick()

    def _log_stop(self, new_status: Status) -> None:
        """py_trees' debug line of a stop."""
        change = f"{self.status}->{new_status}" if self.status != new_status else f"{new_status}"
        self.logger.debug(f"{self.__class__.__name__}.stop({change})")

    def _report_error(self, error: Exception) -> str:
        """Record ``error`` (and where it was raised) as this leaf's feedback; send an ``error`` event.

        Returns the reason: the error and the file:line in this leaf's own source that it passed
        through (else where it was raised).
        """
        try:
            own = inspect.getsourcefile(type(self))
        except TypeError:  # a class made at run time (a test's) has no file
            own = None
        site = error_site(error, own)
        self.feedback_message = site.reason
        if self.ctx is not None:
            self.ctx.events.emit("error", node=self.name, error=site.reason, where=site.where,
                                 function=site.function, traceback=list(site.frames))
        return site.reason

    def _fail_on_exception(self, error: Exception) -> None:
        self.failure_reason = self._report_error(error)
        mark_fault(self, self.failure_reason)
        try:
            if self.status == Status.RUNNING:
                self.terminate(Status.FAILURE)
        except Exception:  # noqa: BLE001 - already failing; the first error is the one to report
            pass
        self.status = Status.FAILURE
        self.iterator = self.tick()

    # -- helpers for subclasses ------------------------------------------------------------------

    @property
    def context(self) -> MissionContext:
        """The mission context; raises a clear error when the tree was not set up with one."""
        if self.ctx is None:
            raise RuntimeError(f"{self.name}: no mission context; call tree.setup(context=...) first")
        return self.ctx

    def fail(self, reason: str, verdict: bool = False) -> Status:
        """Record ``reason`` as this leaf's failure reason and return FAILURE.

        Args:
            reason: Why, in the mission's words.
            verdict: The FAILURE is an answer that running the leaf again cannot change ("not
                found" after the whole reachable space was looked at): a Retry above stops at once.
        """
        self.failure_reason = reason
        self.feedback_message = reason
        if verdict:
            mark_verdict(self, reason)
        return Status.FAILURE

    def fault(self, reason: str) -> Status:
        """Return FAILURE caused by an error, not by a condition (a lost sensor, a reading that is no number).

        The leaf carries a fault (:mod:`missiontree.engine.faults`): no Inverter or ForceSuccess
        above it turns this FAILURE into SUCCESS, and a run that ends on it reports the fault.
        """
        self.fail(reason)
        mark_fault(self, reason)
        return Status.FAILURE

    def running(self, message: str = "") -> Status:
        """Set the feedback message and return RUNNING."""
        self.feedback_message = message
        return Status.RUNNING

    def succeed(self, message: str = "") -> Status:
        """Set the feedback message and return SUCCESS."""
        self.failure_reason = ""
        self.feedback_message = message
        return Status.SUCCESS

    def value(self, field_name: str) -> Any:
        """A parameter's value, read from the blackboard now if the mission gave ``{bb: key}``."""
        raw = getattr(self.params, field_name)
        if not isinstance(raw, BlackboardRef):
            return raw
        value = self.bb.get(raw.key)
        annotation = type(self.params).model_fields[field_name].annotation
        return TypeAdapter(annotation).validate_python(value)  # type: ignore[arg-type]  # declared: annotated

    def read(self, port: str, default: Any = None) -> Any:
        """Read the blackboard key bound to input port ``port`` (``default`` when unset)."""
        key = getattr(self.params, port)
        try:
            return self.bb.get(key)
        except KeyError:
            return default

    def read_entries(self, port: str) -> list[dict[str, Any]]:
        """The mapping entries of the list on input port ``port`` (unset or not a list: none).

        The one reading of a record list a step appends to (tries, looks, rejected candidates).
        """
        value = self.read(port)
        return [e for e in value if isinstance(e, dict)] if isinstance(value, list) else []

    def write(self, port: str, value: Any) -> None:
        """Write ``value`` to the blackboard key bound to output port ``port``."""
        self.bb.set(getattr(self.params, port), value, overwrite=True)

    def emit(self, event: str, **fields: Any) -> None:
        """Send a typed event to the tick log, tagged with this node's name."""
        if self.ctx is not None:
            self.ctx.events.emit(event, node=self.name, **fields)
