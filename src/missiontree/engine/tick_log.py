"""The tick log: one JSON line per tick, plus the typed events leaves emit.

Written through structlog (a ``JSONRenderer`` with sorted keys over a file); the mission and the
tick number are bound with :mod:`structlog.contextvars`, so anything logged through structlog
during a tick carries them. Lines look like::

    {"event":"tick","mission":"patrol","status":"RUNNING","t":12.3,"tick":124,
     "changed":[{"node":"Patrol/GoTo","status":"FAILURE","was":"RUNNING","reason":"no path"}],
     "bb":{"waypoint_index":3}}
    {"event":"goal_sent","mission":"patrol","node":"GoTo","t":12.3,"tick":124,"x":1.0,"y":2.0}

Two pieces:

- :class:`TickLog` writes lines (and is the :class:`~missiontree.engine.context.EventSink` that
  leaves emit to) through :mod:`~missiontree.engine.json_lines`. When the robot's time is simulated
  no wall-clock value is written, floats are rounded to 6 decimals and keys sorted, so the same seed
  gives the same file byte for byte.
- :class:`TickRecorder` is the post-tick handler: given the nodes ticked this tick, it finds the
  nodes whose status changed (visited ones plus those halted since the last tick) and the
  blackboard keys written, and keeps per-node SUCCESS/FAILURE counts for the run summary.
  Its cost follows the active part of the tree, never the whole tree (ARCHITECTURE §9).

**What the summary counts** (``missiontree log summarize`` counts the same from the log alone):
status *transitions* — a node that returns FAILURE on fifty ticks in a row (a guard re-checked
every tick) turned FAILURE once. Each failure is then classified at the end of its tick by
:func:`~missiontree.engine.node_words.absorber`: it *decided the outcome* when FAILURE reached the
root, and was *absorbed* when an ancestor did not fail (a Selector moving on to its next child, a
Retry trying again, an Inverter): the first such ancestor is named. The words py_trees' decorators
write ("success is failure") are replaced by the mission file's names
(:func:`~missiontree.engine.node_words.feedback_of`).
"""

from __future__ import annotations

import json
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any, TextIO

import py_trees
import structlog

from missiontree.engine.json_lines import (
    ENCODE,
    FLOAT_DIGITS,
    LineWriter,
    add_wall_time,
    dumps,
    plain,
    plain_event,
)
from missiontree.engine.node_words import BASE_CLASS, failure_reason, feedback_of, node_paths

#: Distinct failure reasons kept per node in the summary.
MAX_REASONS = 10

Status = py_trees.common.Status
Behaviour = py_trees.behaviour.Behaviour


class TickLog:
    """Writes the run's JSON lines; the event sink leaves emit to.

    Args:
        stream: Where lines go (``ticks.jsonl``, or a StringIO in tests).
        mission: The mission id bound to every line.
        clock: The backend's clock (``robot.now``), for event times.
        simulated: True to keep wall-clock values out of the log.
    """

    def __init__(self, stream: TextIO, mission: str, clock: Callable[[], float], simulated: bool) -> None:
        self.stream = stream
        self.mission = mission
        self.clock = clock
        self.simulated = simulated
        self.event_counts: dict[str, int] = {}
        #: The kind (and node) of the last event a leaf emitted, for progress lines.
        self.last_event = ""
        writer = LineWriter(stream, flush_each_line=not simulated)
        self._writer = writer
        render = structlog.processors.JSONRenderer(serializer=dumps)  # keys sorted by ENCODE
        stamp = [] if simulated else [add_wall_time]
        merge = structlog.contextvars.merge_contextvars
        #: Events from leaves: any fields, made JSON-ready and stable first.
        self._log = structlog.wrap_logger(writer, processors=[merge, *stamp, plain_event, render],
                                          context_class=dict).bind()  # bound once, not per call
        #: Tick lines: built here from plain values with the ids given explicitly, so they skip the
        #: conversion and the context merge (the hot path).
        self._tick_log = structlog.wrap_logger(writer, processors=[*stamp, render], context_class=dict).bind()
        self._tick = 0
        #: Events emitted off the tick thread wait here and are written on it, in arrival order.
        self._owner = threading.get_ident()
        self._pending: list[tuple[str, dict[str, Any]]] = []
        self._lock = threading.Lock()
        self._closed = False

    # -- binding -------------------------------------------------------------------------------

    def bind(self) -> None:
        """Bind the mission id for everything logged through structlog from now on (on this thread)."""
        self._owner = threading.get_ident()
        structlog.contextvars.bind_contextvars(mission=self.mission, tick=0)

    def set_tick(self, tick: int) -> None:
        """Bind the current tick number."""
        self._tick = tick
        structlog.contextvars.bind_contextvars(tick=tick)

    def unbind(self) -> None:
        """Write what other threads left, remove the ids from structlog's context; drop later events."""
        self.flush_pending()
        self._closed = True
        structlog.contextvars.unbind_contextvars("mission", "tick")

    # -- lines ---------------------------------------------------------------------------------

    def emit(self, event: str, /, **fields: Any) -> None:
        """Record a typed event (EventSink): its kind, the backend time and the leaf's fields.

        Called from another thread (a model call's worker), the event is written on the tick
        thread with the current tick's line (just before it), so lines never interleave. After the
        run it is dropped.
        """
        if self._closed:
            return
        if threading.get_ident() != self._owner:
            with self._lock:
                self._pending.append((event, fields))
            return
        self._write(event, fields)

    def _write(self, event: str, fields: dict[str, Any]) -> None:
        self.event_counts[event] = self.event_counts.get(event, 0) + 1
        node = fields.get("node")
        self.last_event = f"{event} ({node})" if node else event
        if "event" in fields:  # structlog's own key: keep the leaf's value under another name
            fields["event_field"] = fields.pop("event")
        fields.setdefault("t", self.clock())
        self._log.msg(event, **fields)

    def flush_pending(self) -> None:
        """Write the events other threads emitted since the last tick (call on the tick thread)."""
        with self._lock:
            pending, self._pending = self._pending, []
        for event, fields in pending:
            self._write(event, fields)

    def line(self, event: str, **fields: Any) -> None:
        """Write a line of the runner's own (not counted as a leaf event); empty fields left out."""
        fields = {k: v for k, v in fields.items() if v is not None and v != [] and v != {}}
        fields.setdefault("t", self.clock())
        self._log.msg(event, **fields)

    def tick(self, t: float, status: Status, changed: list[dict[str, Any]], bb: dict[str, Any],
             bb_unset: list[str]) -> None:
        """Write the line of one tick (empty change lists are left out)."""
        if self._pending:
            self.flush_pending()
        fields: dict[str, Any] = {"mission": self.mission, "tick": self._tick, "t": round(t, FLOAT_DIGITS),
                                  "status": status.name}
        if changed:
            fields["changed"] = changed
        if bb:
            fields["bb"] = bb
        if bb_unset:
            fields["bb_unset"] = bb_unset
        if self.simulated:  # what the structlog chain below renders, without its per-call machinery
            fields["event"] = "tick"
            self._writer.msg(ENCODE(fields))
            return
        self._tick_log.msg("tick", **fields)

    def flush(self) -> None:
        """Flush the underlying stream (a failure is kept in :attr:`write_error`, not raised)."""
        self._writer.flush()

    def redirect(self, stream: TextIO) -> None:
        """Write the following lines to ``stream`` (the runner's recovered log after a deleted directory)."""
        self.stream = stream
        self._writer.redirect(stream)

    @property
    def write_error(self) -> OSError | None:
        """The error that stopped the log's writing (a full disk), or None while it writes."""
        return self._writer.error


class _RecordingStorage(dict[str, Any]):
    """py_trees' blackboard storage that remembers which keys were written or removed.

    Installed in place of ``Blackboard.storage`` (a plain class-level dict every client writes
    through), so recording a write costs one set insertion and reads cost nothing.
    """

    def __init__(self, *args: Any) -> None:
        super().__init__(*args)
        self.written: set[str] = set()

    def __setitem__(self, key: str, value: Any) -> None:
        self.written.add(key)
        super().__setitem__(key, value)

    def __delitem__(self, key: str) -> None:
        self.written.add(key)
        super().__delitem__(key)

    def pop(self, key: str, *default: Any) -> Any:
        self.written.add(key)
        return super().pop(key, *default)


def _watched_class(cls: type, stopped: list[Behaviour]) -> type:
    """A subclass of ``cls`` whose ``terminate`` notes halts (every py_trees ``stop()`` calls it).

    Nodes are switched to it for the run (``node.__class__``) rather than given an instance
    attribute: an attribute added to (or removed from) an instance turns its shared-key ``__dict__``
    into a private one, which made every attribute lookup of every node slower. For classes that
    keep py_trees' empty ``terminate`` the note replaces the call instead of adding one. For classes
    that keep py_trees' own ``stop`` (its function-made behaviours: Success, Failure, ...), ``stop``
    itself notes the halt (:func:`_watched_stop`): one call a stop instead of three.
    """
    invalid = Status.INVALID
    original = cls.terminate  # type: ignore[attr-defined]
    if original is py_trees.behaviour.Behaviour.terminate:
        def terminate(self: Behaviour, new_status: Status) -> None:
            if new_status is invalid:  # a halt; SUCCESS/FAILURE ends a node's own tick (it was visited)
                stopped.append(self)
    else:
        def terminate(self: Behaviour, new_status: Status) -> None:
            if new_status is invalid:
                stopped.append(self)
            original(self, new_status)
    members: dict[str, Any] = {"terminate": terminate, "__module__": cls.__module__,
                               "__qualname__": cls.__qualname__, BASE_CLASS: cls}
    if cls.stop is py_trees.behaviour.Behaviour.stop:  # type: ignore[attr-defined]
        members["stop"] = _watched_stop(original, stopped)
    return type(cls.__name__, (cls,), members)


#: The code of the ``terminate`` py_trees gives its function-made behaviours
#: (``meta.create_behaviour_from_function``): on a halt it clears the feedback message, nothing else.
_META_TERMINATE = py_trees.behaviours.Success.terminate.__code__


def _watched_stop(original: Any, stopped: list[Behaviour]) -> Any:
    """py_trees' ``Behaviour.stop`` with the watched ``terminate`` inlined (same effects, same order).

    Its debug line is formatted only when py_trees logs at debug level (formatting two enum values
    was most of a stop's cost); a ``terminate`` that does nothing, or only clears the feedback on a
    halt as py_trees' function-made behaviours' does, is done here instead of called.
    """
    invalid = Status.INVALID
    debug = py_trees.logging.Level.DEBUG
    logging = py_trees.logging
    empty = original is py_trees.behaviour.Behaviour.terminate
    clears = getattr(original, "__code__", None) is _META_TERMINATE

    def log(self: Behaviour, new_status: Status) -> None:
        change = f"{self.status}->{new_status}" if self.status != new_status else f"{new_status}"
        self.logger.debug(f"{self.__class__.__name__}.stop({change})")

    if empty or clears:
        def stop(self: Behaviour, new_status: Status) -> None:
            if logging.level is debug:
                log(self, new_status)
            own = self.__dict__.get("terminate")  # one put on the instance (the run profile's timer)
            if own is not None:
                own(new_status)
            elif new_status is invalid:
                stopped.append(self)
                if clears:
                    self.feedback_message = ""
            self.status = new_status
            self.iterator = self.tick()
    else:
        def stop(self: Behaviour, new_status: Status) -> None:
            if logging.level is debug:
                log(self, new_status)
            self.terminate(new_status)
            self.status = new_status
            self.iterator = self.tick()
    return stop


#: Composites with more children than this have their children's halts watched, not scanned.
WATCH_SIBLINGS = 16


class TickRecorder:
    """Finds what changed in a tick and keeps the counts for the summary.

    Per tick it looks only at the nodes ticked and the nodes that were active (not INVALID)
    after the previous tick — a node can only change status by being ticked or by being
    halted, and a halted node was active before.

    Args:
        root: The tree's root.
        log: Where tick lines go.
    """

    def __init__(self, root: Behaviour, log: TickLog) -> None:
        self.root = root
        self.log = log
        self.paths = node_paths(root)
        self.ticks = 0
        #: node -> [SUCCESS count, FAILURE count], for every node up front (no lookups that miss)
        self._counts: dict[Behaviour, list[int]] = {node: [0, 0] for node in self.paths}
        self._reasons: dict[Behaviour, list[str]] = {}
        #: failures that reached the root, and failures absorbed: node -> {absorber path: count}
        self._decided: dict[Behaviour, int] = {}
        self._absorbed: dict[Behaviour, dict[str, int]] = {}
        #: Status of every node that is not INVALID, as of the end of the last tick.
        self._active: dict[Behaviour, Status] = {}
        self._bb_logged: dict[str, Any] = {}
        #: Nodes whose stop() ran since the last record (filled by the wrappers of watch_stops).
        self._stopped: list[Behaviour] = []
        self._watching: dict[Behaviour, type] = {}
        #: Active nodes that are not watched: looked at after a tick with a change.
        self._scanned: dict[Behaviour, None] = {}
        #: Nodes looked at by the last record (those ticked plus those stopped): the recorder's work.
        self.examined = 0
        storage = py_trees.blackboard.Blackboard.storage
        if not isinstance(storage, _RecordingStorage):
            storage = _RecordingStorage(storage)
            py_trees.blackboard.Blackboard.storage = storage
        self._storage = storage
        storage.written.clear()

    def watch_stops(self, min_siblings: int = WATCH_SIBLINGS) -> None:
        """Note the halts of the children of large composites, so they are found without a scan.

        py_trees' ``stop()`` calls ``terminate()``; each child of a composite with more than
        ``min_siblings`` children is switched for the run to a subclass of its class whose
        ``terminate`` notes a stop with INVALID (:func:`_watched_class`; :meth:`close` switches it
        back). Other nodes are cheaper to look at than to watch: they are scanned after a tick with
        a change. Nodes added to the tree later are found when ticked; the final halt checks all.
        """
        classes: dict[type, type] = {}
        for node in self.paths:
            if node in self._watching or node.parent is None or len(node.parent.children) <= min_siblings:
                continue
            cls = type(node)
            watched = classes.get(cls)
            if watched is None:
                watched = classes[cls] = _watched_class(cls, self._stopped)
            try:
                node.__class__ = watched
            except TypeError:  # a class that cannot be switched (its layout): found by scanning
                continue
            self._watching[node] = cls
            self._scanned.pop(node, None)

    def close(self) -> None:
        """Switch every node back to its own class (the tree can be ticked again without this recorder)."""
        for node, cls in self._watching.items():
            node.__class__ = cls
            if node in self._active:
                self._scanned[node] = None
        self._watching.clear()
        self._stopped.clear()

    def path(self, node: Behaviour) -> str:
        """The node's path (computed and kept for nodes added after the start)."""
        found = self.paths.get(node)
        if found is None:
            parent = self.path(node.parent) if node.parent is not None else ""
            found = self.paths[node] = f"{parent}/{node.name}" if parent else node.name
        return found

    def record(self, t: float, visited: list[Behaviour], event: str = "tick") -> None:
        """Write the line for a tick in which ``visited`` were ticked (or a halt when ``event`` says so)."""
        active = self._active
        changed: list[dict[str, Any]] = []
        failed: list[Behaviour] = []
        invalid = Status.INVALID
        for node in visited:  # the hot loop: subscripts rather than calls, a few a node
            status = node.status
            try:
                was = active[node]
            except KeyError:
                was = invalid
            if status is not was:
                changed.append(self._change(node, status, was))
                self._set_active(node, status)
                if status is not invalid:
                    self._count(node, status, failed)
        # A node not ticked can only have changed by being stopped (halted). Children of large
        # composites are watched (:meth:`watch_stops`): the ones halted this tick are noted, so the
        # finished children of a memory Sequence are never scanned. Other active nodes are looked
        # at after a tick in which a ticked node changed (a composite halts a child only then). A
        # halt line looks at every active node once.
        stopped = self._stopped
        if event != "tick":
            candidates: list[Behaviour] = list(active)
        else:
            candidates = []
            if changed:
                ticked = set(visited)
                candidates = [n for n in self._scanned if n not in ticked]
            if stopped:
                candidates.extend(stopped)
        stopped.clear()
        self.examined = len(visited) + len(candidates)
        if candidates:
            halted = [n for n in dict.fromkeys(candidates) if n in active and n.status is not active[n]]
            for node in sorted(halted, key=self.path):  # by path: independent of memory addresses
                status = node.status
                changed.append(self._change(node, status, active[node]))
                self._set_active(node, status)
                if status is not invalid:
                    self._count(node, status, failed)
        for node in failed:
            self._classify(node)
        bb, unset = self._blackboard_changes()
        if event == "tick":
            self.ticks += 1
            self.log.tick(t, self.root.status, changed, bb, unset)
        else:
            self.log.line(event, t=t, changed=changed, bb=bb, bb_unset=unset)

    def _set_active(self, node: Behaviour, status: Status) -> None:
        """Keep the node's status (dropped when INVALID); unwatched nodes are also kept to scan."""
        if status is Status.INVALID:
            del self._active[node]
            self._scanned.pop(node, None)
        else:
            self._active[node] = status
            if node not in self._watching:
                self._scanned[node] = None

    def _count(self, node: Behaviour, status: Status, failed: list[Behaviour]) -> None:
        """Count a transition into SUCCESS or FAILURE (a failure is classified after the tick)."""
        counts = self._counts.get(node)
        if counts is None:  # a node added to the tree after the start
            counts = self._counts[node] = [0, 0]
        if status is Status.SUCCESS:
            counts[0] += 1
        elif status is Status.FAILURE:
            counts[1] += 1
            failed.append(node)
            reason = failure_reason(node)
            if reason:
                self._keep_reason(node, reason)

    def _classify(self, node: Behaviour) -> None:
        """Decided the outcome, or absorbed by the first ancestor that did not fail (end of tick)."""
        parent = node.parent
        while parent is not None:
            if parent.status is not Status.FAILURE:
                by = self._absorbed.setdefault(node, {})
                where = self.path(parent)
                by[where] = by.get(where, 0) + 1
                return
            parent = parent.parent
        self._decided[node] = self._decided.get(node, 0) + 1

    def _change(self, node: Behaviour, status: Status, was: Status) -> dict[str, Any]:
        entry: dict[str, Any] = {"node": self.path(node), "status": status.name, "was": was.name}
        feedback = feedback_of(node)
        if feedback:
            entry["feedback"] = feedback
        if status is Status.FAILURE:
            reason = failure_reason(node)
            if reason:
                entry["reason"] = reason
        return entry

    def _keep_reason(self, node: Behaviour, reason: str) -> None:
        reasons = self._reasons.get(node)
        if reasons is None:
            reasons = self._reasons[node] = []
        if reason not in reasons and len(reasons) < MAX_REASONS:
            reasons.append(reason)

    def _blackboard_changes(self) -> tuple[dict[str, Any], list[str]]:
        storage = self._storage
        if py_trees.blackboard.Blackboard.storage is not storage:  # someone replaced it: take it back
            storage = self._storage = _RecordingStorage(py_trees.blackboard.Blackboard.storage)
            py_trees.blackboard.Blackboard.storage = storage
        if not storage.written:
            return {}, []
        written = sorted(storage.written)
        storage.written.clear()
        changes: dict[str, Any] = {}
        unset: list[str] = []
        for key in written:
            shown = key[1:] if key.startswith("/") else key  # as mission files write keys
            if key in storage:
                value = plain(storage[key])
                if key not in self._bb_logged or self._bb_logged[key] != value:
                    self._bb_logged[key] = value
                    changes[shown] = value
            else:
                self._bb_logged.pop(key, None)
                unset.append(shown)
        return changes, unset

    def summary(self) -> dict[str, Any]:
        """Per-node transitions into SUCCESS/FAILURE, failure reasons, and every failure's kind.

        ``failures``: node path → ``count`` (times it turned FAILURE), ``decided`` (how many of
        those reached the root and decided the outcome), ``absorbed_by`` (ancestor path → how many
        it absorbed) and ``reasons``. Everything sorted by node path.
        """
        nodes = {self.path(n): {"SUCCESS": c[0], "FAILURE": c[1]} for n, c in self._counts.items() if any(c)}
        reasons = {self.path(n): r for n, r in self._reasons.items() if r}
        failures = {
            self.path(n): {"count": c[1], "decided": self._decided.get(n, 0),
                           "absorbed_by": dict(sorted(self._absorbed.get(n, {}).items())),
                           "reasons": self._reasons.get(n, [])}
            for n, c in self._counts.items() if c[1]}
        return {
            "nodes": dict(sorted(nodes.items())),
            "failure_reasons": dict(sorted(reasons.items())),
            "failures": dict(sorted(failures.items())),
        }


def read_log(path: Path) -> list[dict[str, Any]]:
    """Read a ``ticks.jsonl`` back, one dict a line (a last line without its newline too).

    Raises:
        ConfigError: The file is missing or a line is not JSON (names the line).
    """
    return read_records(path, whole=True)[0]


def read_records(path: Path, start: int = 0, *, whole: bool = False) -> tuple[list[dict[str, Any]], int]:
    """The JSON lines of a tick log from byte ``start``; returns them and where the next read starts.

    A last line without its newline (a run still writing) is left for the next read, unless
    ``whole`` (a finished file): the one reader of tick logs, whole (:func:`read_log`) or as a
    growing file yields them (the live viewer).

    Raises:
        ConfigError: The file cannot be read or a line is not a JSON object (names the line).
    """
    from missiontree.errors import ConfigError

    try:
        with path.open("rb") as stream:
            stream.seek(start)
            data = stream.read()
    except OSError as error:
        raise ConfigError(f"cannot read tick log {str(path)!r}: {error.strerror}") from error
    end = len(data) if whole else data.rfind(b"\n") + 1
    where = f"{path}:{{}}:" if start == 0 else f"{path}: line {{}} after byte {start}:"
    records: list[dict[str, Any]] = []
    for number, line in enumerate(data[:end].split(b"\n"), start=1):
        if not line.strip():
            continue
        try:
            record = json.loads(line)
        except (json.JSONDecodeError, UnicodeDecodeError) as error:
            reason = error.msg if isinstance(error, json.JSONDecodeError) else "not UTF-8 text"
            raise ConfigError(f"{where.format(number)} not a tick log line (expected one JSON object): "
                              f"{reason}") from error
        if not isinstance(record, dict):
            raise ConfigError(f"{where.format(number)} expected a JSON object, found {type(record).__name__}")
        records.append(record)
    return records, start + end
