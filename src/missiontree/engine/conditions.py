"""Pre- and post-conditions on any node, as BehaviorTree.CPP 4's ``_skipIf`` ... ``_post``.

A node in a mission file may carry, beside its parameters:

- before a tick, checked in BT.CPP's order ``fail_if``, ``succeed_if``, ``skip_if``, ``while``
  (expressions, :mod:`missiontree.engine.expressions`). When the node is not RUNNING (BT.CPP: IDLE),
  the first of ``fail_if``/``succeed_if``/``skip_if`` that is true decides without ticking it:
  FAILURE, SUCCESS, or (skip) SUCCESS; a false ``while`` does the same as a skip but ends FAILURE.
  While the node is RUNNING only ``while`` is checked: false halts the node and it ends FAILURE.
  BT.CPP returns SKIPPED for a skip and a false ``while``; py_trees has no such status, so a skip
  maps to SUCCESS (a Sequence goes on, as BT.CPP's does) and a false ``while`` to FAILURE (the work
  it guarded was not done).
- after a tick that ended SUCCESS or FAILURE (also one decided by ``fail_if``/``succeed_if``, as in
  BT.CPP; not after a skip or a false ``while``): ``on_success`` or ``on_failure``, then ``post``;
  ``on_halted`` when the node is halted while RUNNING (assignments ``key = expression``).

A condition or assignment that cannot be evaluated (a key not set, a type mismatch) fails the node
with a fault (:mod:`missiontree.engine.faults`) naming the reason; it is never read as false.

Recorded in the tick log through the event sink the runner gives every node at setup: a
``conditions`` event per conditioned node (its path and every condition's text: what the viewer and
the ``.btlog`` export show), all written when the first conditioned node is ticked (so after the
log's ``mission_started`` line, which stays first), and a ``condition`` event with the node, the key,
the expression, the status and the ``reason`` each time a pre-condition decides a node's status
(once while the same decision repeats tick after tick).

:func:`attach` switches a built behaviour to a subclass of its own class (:func:`conditioned_class`)
whose ``tick`` and ``stop`` do this (the runner's guards and
recorder wrap it like any node); the tree keeps its shape, so node paths are unchanged.
"""

from __future__ import annotations

import weakref
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any

import py_trees

from missiontree.engine.expressions import (
    EvaluationError,
    Expression,
    ExpressionError,
    Script,
    parse_expression,
    parse_script,
)
from missiontree.engine.faults import clear_fault, mark_fault
from missiontree.engine.node_words import BASE_CLASS
from missiontree.engine.spec import CONDITION_KEYS, POST_KEYS, PRE_KEYS

Behaviour = py_trees.behaviour.Behaviour
Status = py_trees.common.Status

_ATTRIBUTE = "missiontree_conditions"
_EVENTS = "missiontree_condition_events"
_DECIDED = "missiontree_condition_decided"
#: Conditions of the nodes set up with an event sink, written at the first tick of one of them.
_PENDING: weakref.WeakKeyDictionary[Any, list[tuple[str, dict[str, str]]]] = weakref.WeakKeyDictionary()


@dataclass
class NodeConditions:
    """A node's parsed pre-conditions (expressions) and post-conditions (scripts), by key."""

    pre: dict[str, Expression] = field(default_factory=dict)
    post: dict[str, Script] = field(default_factory=dict)

    @property
    def reads(self) -> frozenset[str]:
        """Every blackboard key read."""
        keys: set[str] = set()
        for expression in self.pre.values():
            keys |= expression.reads
        for script in self.post.values():
            keys |= script.reads
        return frozenset(keys)

    @property
    def writes(self) -> frozenset[str]:
        """Every blackboard key written."""
        return frozenset(k for script in self.post.values() for k in script.writes)


def parse_conditions(written: dict[str, Any]) -> tuple[NodeConditions, dict[str, ExpressionError]]:
    """Parse a node's written conditions; return them and the errors by key (those left out)."""
    parsed = NodeConditions()
    errors: dict[str, ExpressionError] = {}
    for key, text in written.items():
        try:
            if key in PRE_KEYS:
                parsed.pre[key] = parse_expression(text)
            elif key in POST_KEYS:
                parsed.post[key] = parse_script(text)
        except ExpressionError as exc:
            errors[key] = exc
    return parsed, errors


def read_key(key: str) -> Any:
    """Read a blackboard key (KeyError when it is not set)."""
    return py_trees.blackboard.Blackboard.get(f"/{key}")


def write_key(key: str, value: Any) -> None:
    """Write a blackboard key."""
    py_trees.blackboard.Blackboard.set(f"/{key}", value)


def attach(behaviour: Behaviour, conditions: NodeConditions) -> None:
    """Give a built behaviour its conditions (its class is switched to the conditioned subclass)."""
    if not conditions.pre and not conditions.post:
        return
    behaviour.__class__ = conditioned_class(type(behaviour))
    setattr(behaviour, _ATTRIBUTE, conditions)


def conditions_of(behaviour: Behaviour) -> NodeConditions | None:
    """The conditions attached to ``behaviour``, or None."""
    return getattr(behaviour, _ATTRIBUTE, None)


_CLASSES: dict[type, type] = {}


def conditioned_class(cls: type) -> type:
    """The subclass of ``cls`` whose tick checks pre-conditions and runs post-conditions (one per class)."""
    found = _CLASSES.get(cls)
    if found is None:
        base = getattr(cls, BASE_CLASS, cls)

        def tick(self: Behaviour) -> Iterator[Behaviour]:
            return _tick(self, cls.tick)  # type: ignore[attr-defined]

        def stop(self: Behaviour, new_status: Status) -> None:
            _stop(self, new_status, cls.stop)  # type: ignore[attr-defined]

        def setup(self: Behaviour, **kwargs: Any) -> None:
            _setup(self, kwargs.get("context"))
            cls.setup(self, **kwargs)  # type: ignore[attr-defined]

        found = _CLASSES[cls] = type(cls.__name__, (cls,), {
            "tick": tick, "stop": stop, "setup": setup, "__module__": cls.__module__,
            "__qualname__": cls.__qualname__, BASE_CLASS: base})
    return found


def _tick(self: Behaviour, parent_tick: Callable[[Behaviour], Iterator[Behaviour]]) -> Iterator[Behaviour]:
    conditions: NodeConditions = getattr(self, _ATTRIBUTE)
    _flush(getattr(self, _EVENTS, None))
    if self.status != Status.RUNNING:
        clear_fault(self)
    try:
        decided = _before(self, conditions)
    except EvaluationError as error:
        reason = f"condition: {error}"
        _announce(self, Status.FAILURE, reason, conditions)
        yield from _end(self, Status.FAILURE, reason, fault=True)
        return
    if decided is None:
        setattr(self, _DECIDED, None)
        done = False
        for node in parent_tick(self):
            if node is self and not done:  # a parent may stop iterating once it sees this node: act first
                done = True
                _after(self, conditions)
            yield node
        return
    status, reason, ran = decided
    _announce(self, status, reason, conditions)
    yield from _end(self, status, reason, conditions if ran else None)


def node_path(node: Behaviour) -> str:
    """The node's path as the tick log writes it (:func:`~missiontree.engine.node_words.node_paths`)."""
    parts: list[str] = []
    while node.parent is not None:
        siblings = node.parent.children
        index = next(i for i, child in enumerate(siblings) if child is node)
        repeated = sum(child.name == node.name for child in siblings) > 1
        parts.append(f"{node.name}[{index}]" if repeated else node.name)
        node = node.parent
    parts.append(node.name)
    return "/".join(reversed(parts))


def texts(conditions: NodeConditions) -> dict[str, str]:
    """Every condition's text as written, by key (BT.CPP's order: pre-conditions, then assignments)."""
    found = {key: conditions.pre[key].text for key in PRE_KEYS if key in conditions.pre}
    found.update({key: conditions.post[key].text for key in POST_KEYS if key in conditions.post})
    return found


def _setup(self: Behaviour, context: Any) -> None:
    """Keep the run's event sink and record the node's conditions in the tick log."""
    events = getattr(context, "events", None)
    setattr(self, _EVENTS, events)
    setattr(self, _DECIDED, None)
    if events is None:
        return
    announced = (node_path(self), texts(getattr(self, _ATTRIBUTE)))
    try:
        _PENDING.setdefault(events, []).append(announced)
    except TypeError:  # a sink that cannot be weakly referenced: written now
        events.emit("conditions", node=announced[0], conditions=announced[1])


def _flush(events: Any) -> None:
    """Write the ``conditions`` events waiting for ``events`` (at the first tick of a conditioned node)."""
    if events is None:
        return
    try:
        pending = _PENDING.pop(events, None)
    except TypeError:
        return
    for path, written in pending or ():
        events.emit("conditions", node=path, conditions=written)


def _announce(self: Behaviour, status: Status, reason: str, conditions: NodeConditions) -> None:
    """A ``condition`` event: which pre-condition decided the node's status and why (once per decision)."""
    events = getattr(self, _EVENTS, None)
    if events is None or getattr(self, _DECIDED, None) == (status, reason):
        return
    setattr(self, _DECIDED, (status, reason))
    key = reason.split(":", 1)[0]
    test = conditions.pre.get(key)
    events.emit("condition", node=node_path(self), key=key, expression=test.text if test is not None else "",
                status=status.name, reason=reason)


def _before(self: Behaviour, conditions: NodeConditions) -> tuple[Status, str, bool] | None:
    """The status decided by a pre-condition, why, and whether post-conditions run; None: tick it."""
    pre = conditions.pre
    if self.status == Status.RUNNING:
        test = pre.get("while")
        if test is not None and not test.truth(read_key):
            self.stop(Status.INVALID)  # halted: on_halted runs
            return Status.FAILURE, f"while: `{test.text}` became false, halted", False
        return None
    decisions = (("fail_if", True, Status.FAILURE, True), ("succeed_if", True, Status.SUCCESS, True),
                 ("skip_if", True, Status.SUCCESS, False), ("while", False, Status.FAILURE, False))
    for key, when, status, ran in decisions:
        test = pre.get(key)
        if test is not None and test.truth(read_key) is when:
            verb = "skipped" if key == "skip_if" else "not ticked"
            return status, f"{key}: `{test.text}` is {'true' if when else 'false'}, {verb}", ran
    return None


def _end(self: Behaviour, status: Status, reason: str, conditions: NodeConditions | None = None, *,
         fault: bool = False) -> Iterator[Behaviour]:
    """End this tick with ``status`` without ticking the node; run the post-conditions if given."""
    if fault and self.status == Status.RUNNING:
        self.stop(Status.INVALID)
    self.status = status
    self.feedback_message = reason
    if hasattr(self, "failure_reason"):
        self.failure_reason = reason if status == Status.FAILURE else ""
    if fault:
        mark_fault(self, reason)
    if conditions is not None:
        _after(self, conditions)
    yield self


def _after(self: Behaviour, conditions: NodeConditions) -> None:
    """Run on_success/on_failure then post after a SUCCESS or FAILURE; an error fails the node (a fault)."""
    if self.status not in (Status.SUCCESS, Status.FAILURE) or not conditions.post:
        return
    which = "on_success" if self.status == Status.SUCCESS else "on_failure"
    for key in (which, "post"):
        script = conditions.post.get(key)
        if script is None:
            continue
        try:
            script.run(read_key, write_key)
        except EvaluationError as error:
            reason = f"{key}: {error}"
            self.status = Status.FAILURE
            self.feedback_message = reason
            if hasattr(self, "failure_reason"):
                self.failure_reason = reason
            mark_fault(self, reason)
            return


def _stop(self: Behaviour, new_status: Status, parent_stop: Callable[[Behaviour, Status], None]) -> None:
    was_running = self.status == Status.RUNNING
    parent_stop(self, new_status)
    if new_status != Status.INVALID or not was_running:
        return
    conditions: NodeConditions = getattr(self, _ATTRIBUTE)
    script = conditions.post.get("on_halted")
    if script is not None:
        try:
            script.run(read_key, write_key)
        except EvaluationError as error:  # a halt cannot fail; the reason is kept as the fault
            self.feedback_message = f"on_halted: {error}"
            mark_fault(self, self.feedback_message)


__all__ = ["CONDITION_KEYS", "POST_KEYS", "PRE_KEYS", "NodeConditions", "attach", "conditioned_class",
           "conditions_of", "node_path", "parse_conditions", "texts"]
