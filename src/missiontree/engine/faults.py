"""Errors are not conditions: a node that failed because of an error carries a *fault*.

py_trees knows SUCCESS, FAILURE, RUNNING and INVALID; it has no error status. A leaf that raises
(a non-finite sensor reading, a plugin's bug, a lost connection) ends FAILURE like a condition that
does not hold, and an ``Inverter`` or ``ForceSuccess`` above it would turn that into SUCCESS: a NaN
battery reading under ``Inverter(IsBatteryLow)`` would read as "battery fine". So such a node also
carries a fault (:func:`mark_fault`: the reason, on the node), kept until the node is ticked afresh.

- Composites treat a faulted child as failed (a Selector may still try its next child, a Retry may
  run it again: an alternative that succeeds is a recovery).
- The decorators that turn FAILURE into SUCCESS (:class:`FaultKeepingInverter`,
  :class:`FaultKeepingForceSuccess`) pass a faulted child's FAILURE up unchanged.
- The runner reports a FAILURE whose subtree holds a fault as a fault (``summary.json``'s
  ``fault``), and the run exits 1.

A leaf's FAILURE may also be a *verdict* (:func:`mark_verdict`): an answer, not a fault, that running
the leaf again cannot change (a search's "not found" once the reachable space is looked at). A Retry
above it stops at once and fails with the verdict's reason instead of spending its attempts.
"""

from __future__ import annotations

import inspect
import os
import traceback
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import py_trees

from missiontree.events import EventSink

Behaviour = py_trees.behaviour.Behaviour
Status = py_trees.common.Status

_ATTRIBUTE = "missiontree_fault"
_VERDICT = "missiontree_verdict"
#: How a Retry stopped by a verdict begins its reason (the run's reason then quotes no older attempt).
VERDICT_WORDS = "Retry: stopped by a verdict below it"

#: Longest exception message kept in a reason (a message may carry a model's or a peer's text).
MAX_MESSAGE = 300
#: Frames kept in an error event's traceback (the innermost ones).
MAX_FRAMES = 12


@dataclass(frozen=True)
class ErrorSite:
    """Where an exception was raised, for a reason and the tick log.

    Attributes:
        reason: ``ValueError: message (at plugin/leaves.py:42 in update)``.
        where: ``plugin/leaves.py:42`` (the frame in the node's own file when the error passed
            through it, else the innermost frame), or empty.
        function: That frame's function.
        frames: The traceback, innermost last, as ``file:line in function`` (no source text, no values).
    """

    reason: str
    where: str
    function: str
    frames: tuple[str, ...]


def error_site(error: BaseException, own_file: str | None = None) -> ErrorSite:
    """Describe ``error``: its type, message (one line, capped) and where it was raised.

    Only file names, line numbers and function names are taken from the traceback, never source
    lines or local values; the message is the one part the error's raiser wrote, so it is flattened
    to one line and cut at :data:`MAX_MESSAGE` characters.

    Args:
        error: The exception caught.
        own_file: The node's own source file: when a frame is in it, that frame is named (the plugin
            line that called into a library), else the innermost frame.
    """
    message = " ".join(str(error).split())
    if len(message) > MAX_MESSAGE:
        message = message[:MAX_MESSAGE - 1] + "…"
    text = f"{type(error).__name__}: {message}" if message else type(error).__name__
    frames = traceback.extract_tb(error.__traceback__) if error.__traceback__ is not None else []
    if not frames:
        return ErrorSite(text, "", "", ())
    chosen = frames[-1]
    if own_file is not None:
        own = [frame for frame in frames if _same_file(frame.filename, own_file)]
        if own:
            chosen = own[-1]
    where = f"{shown_file(chosen.filename)}:{chosen.lineno}"
    listed = tuple(f"{shown_file(f.filename)}:{f.lineno} in {f.name}" for f in frames[-MAX_FRAMES:])
    return ErrorSite(f"{text} (at {where} in {chosen.name})", where, chosen.name, listed)


def source_file(node: object) -> str | None:
    """The file that defines ``node``'s class (None for a class made at run time): its error site."""
    try:
        return inspect.getsourcefile(type(node))
    except TypeError:
        return None


@dataclass
class ErrorFrames:
    """The traceback frames of each node's last error, for the summary's ``fault``.

    A non-Leaf node's error is described here (:meth:`node_error`); a leaf reports its own as an
    ``error`` event, whose frames the sink made by :meth:`noting` keeps on its way to the log.
    """

    by_node: dict[Behaviour, tuple[str, ...]] = field(default_factory=dict)
    by_name: dict[str, tuple[str, ...]] = field(default_factory=dict)

    def node_error(self, node: Behaviour, error: BaseException) -> ErrorSite:
        """Describe a non-Leaf node's ``error`` (where it was raised) and keep its frames."""
        site = error_site(error, source_file(node))
        self.by_node[node] = site.frames
        return site

    def of(self, node: Behaviour) -> tuple[str, ...]:
        """The frames of the error behind ``node``'s fault: its own (non-Leaf) or its leaf event's."""
        return self.by_node.get(node) or self.by_name.get(node.name, ())

    def noting(self, sink: EventSink) -> EventSink:
        """An event sink that writes to ``sink`` and keeps each ``error`` event's frames."""
        return _NotingSink(sink, self.by_name)


class _NotingSink:
    """The context's event sink: ``sink``, noting each leaf ``error`` event's traceback frames."""

    def __init__(self, sink: EventSink, frames: dict[str, tuple[str, ...]]) -> None:
        self._sink = sink
        self._frames = frames

    def emit(self, event: str, /, **fields: Any) -> None:
        """Note an error's frames, then pass the event on."""
        if event == "error" and isinstance(fields.get("traceback"), list):
            self._frames[str(fields.get("node"))] = tuple(str(f) for f in fields["traceback"])
        self._sink.emit(event, **fields)

    def __getattr__(self, name: str) -> Any:
        return getattr(self._sink, name)


def shown_file(filename: str) -> str:
    """A source file as a reader finds it: relative to the working directory, else from site-packages."""
    path = Path(filename)
    try:
        return str(path.resolve().relative_to(Path.cwd().resolve()))
    except (ValueError, OSError):
        pass
    parts = path.parts
    if "site-packages" in parts:
        return "/".join(parts[parts.index("site-packages") + 1:])
    return filename


def _same_file(a: str, b: str) -> bool:
    try:
        return os.path.samefile(a, b)
    except OSError:
        return a == b


def mark_fault(node: Behaviour, reason: str) -> None:
    """Record that ``node`` failed because of an error (``reason``), not because a condition was false."""
    setattr(node, _ATTRIBUTE, reason or "error")


def clear_fault(node: Behaviour) -> None:
    """Forget ``node``'s fault (it is being ticked afresh)."""
    if getattr(node, _ATTRIBUTE, ""):
        setattr(node, _ATTRIBUTE, "")


def fault_of(node: Behaviour) -> tuple[Behaviour, str] | None:
    """The faulted node (and its reason) behind ``node``'s FAILURE: itself or a failed descendant.

    None when ``node`` did not fail, or failed only because conditions did not hold.
    """
    return _failed_with(node, _ATTRIBUTE)


def mark_verdict(node: Behaviour, reason: str) -> None:
    """Record that ``node``'s FAILURE is a verdict (``reason``): an answer running it again cannot change."""
    setattr(node, _VERDICT, reason or "verdict")


def clear_verdict(node: Behaviour) -> None:
    """Forget ``node``'s verdict (it is being ticked afresh)."""
    if getattr(node, _VERDICT, ""):
        setattr(node, _VERDICT, "")


def verdict_of(node: Behaviour) -> tuple[Behaviour, str] | None:
    """The node (and its reason) whose verdict is behind ``node``'s FAILURE: itself or a failed descendant."""
    return _failed_with(node, _VERDICT)


def _failed_with(node: Behaviour, attribute: str) -> tuple[Behaviour, str] | None:
    """The first failed node at or below ``node`` (through failed nodes only) carrying ``attribute``."""
    if node.status != Status.FAILURE:
        return None
    reason = getattr(node, attribute, "")
    if reason:
        return node, reason
    for child in node.children:
        found = _failed_with(child, attribute)
        if found is not None:
            return found
    return None


def kept_fault(decorator: py_trees.decorators.Decorator, undone: str) -> Status | None:
    """FAILURE (saying what was ``undone`` and why) when the decorated child's FAILURE is a fault."""
    found = fault_of(decorator.decorated)
    if found is None:
        return None
    decorator.feedback_message = f"error, not {undone}: {found[1]}"
    return Status.FAILURE


class FaultKeepingInverter(py_trees.decorators.Inverter):
    """py_trees' Inverter, except that a child's FAILURE caused by an error stays FAILURE."""

    def update(self) -> Status:
        """Swap SUCCESS and FAILURE, unless the FAILURE is a fault."""
        return kept_fault(self, "inverted") or super().update()


class FaultKeepingForceSuccess(py_trees.decorators.FailureIsSuccess):
    """py_trees' FailureIsSuccess, except that a child's FAILURE caused by an error stays FAILURE."""

    def update(self) -> Status:
        """Turn FAILURE into SUCCESS, unless the FAILURE is a fault."""
        return kept_fault(self, "forced to success") or super().update()
