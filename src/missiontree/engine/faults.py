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
"""

from __future__ import annotations

import py_trees

Behaviour = py_trees.behaviour.Behaviour
Status = py_trees.common.Status

_ATTRIBUTE = "missiontree_fault"


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
    if node.status != Status.FAILURE:
        return None
    reason = getattr(node, _ATTRIBUTE, "")
    if reason:
        return node, reason
    for child in node.children:
        found = fault_of(child)
        if found is not None:
            return found
    return None


class FaultKeepingInverter(py_trees.decorators.Inverter):
    """py_trees' Inverter, except that a child's FAILURE caused by an error stays FAILURE."""

    def update(self) -> Status:
        """Swap SUCCESS and FAILURE, unless the FAILURE is a fault."""
        found = fault_of(self.decorated)
        if found is not None:
            self.feedback_message = f"error, not inverted: {found[1]}"
            return Status.FAILURE
        return super().update()


class FaultKeepingForceSuccess(py_trees.decorators.FailureIsSuccess):
    """py_trees' FailureIsSuccess, except that a child's FAILURE caused by an error stays FAILURE."""

    def update(self) -> Status:
        """Turn FAILURE into SUCCESS, unless the FAILURE is a fault."""
        found = fault_of(self.decorated)
        if found is not None:
            self.feedback_message = f"error, not forced to success: {found[1]}"
            return Status.FAILURE
        return super().update()
