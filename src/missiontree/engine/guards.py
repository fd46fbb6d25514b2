"""Exceptions escaping a node become FAILURE of that node: the guards the runner puts on a tree.

An exception escaping a behaviour that is not a :class:`~missiontree.engine.leaf.Leaf` (those
handle their own) becomes FAILURE of that node, its reason naming the error and where it was
raised (``file:line in function``, in the node's own file when the error passed through it, as a
leaf's reason does), reported through ``on_error``; a halt whose cancel
raises is reported the same way. py_trees' own composites and decorators, which only manage their
children, are trusted and ticked without a wrapper (:data:`TRUSTED_TYPES`).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator

import py_trees

from missiontree.engine.faults import (
    FaultKeepingForceSuccess,
    FaultKeepingInverter,
    clear_fault,
    error_site,
    mark_fault,
    source_file,
)
from missiontree.engine.leaf import Leaf

Status = py_trees.common.Status
Behaviour = py_trees.behaviour.Behaviour

#: py_trees classes whose code only manages children or returns a fixed status: an exception cannot
#: start in them (their children are guarded themselves), so they are ticked without a wrapper —
#: wrapping every node would add a generator frame per node per tick. Exact types only: a subclass
#: may override anything. EternalGuard is absent on purpose: it calls a user-given condition.
TRUSTED_TYPES: frozenset[type] = frozenset({
    py_trees.composites.Sequence, py_trees.composites.Selector, py_trees.composites.Parallel,
    py_trees.decorators.Inverter, py_trees.decorators.Retry, py_trees.decorators.Repeat,
    py_trees.decorators.OneShot, py_trees.decorators.Timeout, py_trees.decorators.Condition,
    py_trees.decorators.FailureIsSuccess, py_trees.decorators.FailureIsRunning,
    py_trees.decorators.SuccessIsFailure, py_trees.decorators.SuccessIsRunning,
    py_trees.decorators.RunningIsFailure, py_trees.decorators.RunningIsSuccess,
    py_trees.behaviours.Success, py_trees.behaviours.Failure, py_trees.behaviours.Running,
    py_trees.behaviours.Dummy, FaultKeepingInverter, FaultKeepingForceSuccess,
})


def guard_exceptions(root: Behaviour, on_error: Callable[[Behaviour, Exception], None]) -> None:
    """Make an exception escaping any non-Leaf behaviour under ``root`` FAILURE of that behaviour.

    Each such node's ``tick`` is wrapped on the instance (composites call ``child.tick()``, so the
    wrapper sits exactly where py_trees calls it). Leaves already fail safely on their own, and
    :data:`TRUSTED_TYPES` need no wrapper.
    """
    for node in root.iterate():
        if isinstance(node, Leaf) or type(node) in TRUSTED_TYPES:
            continue
        if getattr(node, "_missiontree_guarded", False):
            continue
        node.tick = _guarded_tick(node, node.tick, on_error)  # type: ignore[method-assign]
        node.stop = _guarded_stop(node, node.stop, on_error)  # type: ignore[method-assign,assignment]
        node._missiontree_guarded = True  # type: ignore[attr-defined]


def _guarded_tick(
    node: Behaviour, original: Callable[[], Iterator[Behaviour]],
    on_error: Callable[[Behaviour, Exception], None],
) -> Callable[[], Iterator[Behaviour]]:
    def tick() -> Iterator[Behaviour]:
        if node.status != Status.RUNNING:
            clear_fault(node)
        try:
            yield from original()
        except Exception as error:  # noqa: BLE001 - a node's bug must not kill the mission
            reason = error_site(error, source_file(node)).reason  # "...: message (at file:line in f)"
            try:
                node.stop(Status.INVALID)  # halt its children so their work is cancelled
            except Exception:  # noqa: BLE001 - already failing; the first error is the one to report
                pass
            node.feedback_message = reason
            node.status = Status.FAILURE
            mark_fault(node, reason)
            node.iterator = node.tick()
            on_error(node, error)
            yield node

    return tick


def _guarded_stop(
    node: Behaviour, original: Callable[[Status], None], on_error: Callable[[Behaviour, Exception], None],
) -> Callable[[Status], None]:
    """A halt (stop with INVALID) whose terminate() raises reports the error instead of raising."""

    def stop(new_status: Status) -> None:
        if new_status != Status.INVALID:
            original(new_status)  # inside the node's own tick: the tick guard makes it FAILURE
            return
        try:
            original(new_status)
        except Exception as error:  # noqa: BLE001 - a failed cancel must not kill the mission
            node.status = Status.INVALID
            node.iterator = node.tick()
            on_error(node, error)

    return stop
