"""Blackboard conditions: the comparison that CheckBlackboard, WaitForBlackboard and Guard evaluate.

A condition names a key, an operator and (for comparisons) a value::

    {key: battery, op: ">", value: 0.2}     # compare
    {key: door_open, op: "==", value: true}
    {key: target}                           # no op and no value: the key is set

A missing key makes every operator false except ``unset``. A comparison between values that
cannot be compared (text with a number) is false, with the reason in the node's feedback.
"""

from __future__ import annotations

import operator
from collections.abc import Callable
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

Op = Literal["==", "!=", "<", "<=", ">", ">=", "in", "not_in", "set", "unset"]

_COMPARE: dict[str, Callable[[Any, Any], bool]] = {
    "==": operator.eq, "!=": operator.ne, "<": operator.lt, "<=": operator.le,
    ">": operator.gt, ">=": operator.ge,
    "in": lambda found, value: found in value, "not_in": lambda found, value: found not in value,
}
_MISSING = object()


class ConditionFields(BaseModel):
    """The fields of a blackboard condition (mixed into node parameters)."""

    model_config = ConfigDict(extra="forbid")

    key: str = Field(description="Blackboard key to test.")
    op: Op | None = Field(
        None, description="Operator; default `==` when a value is given, else `set` (the key exists).")
    value: Any = Field(None, description="Value to compare with (a `{bb: key}` compares with another key).",
                       json_schema_extra={"bb_ref": True})

    @model_validator(mode="after")
    def _value_needed(self) -> ConditionFields:
        if self.op in _COMPARE and "value" not in self.model_fields_set:
            raise ValueError(f"op {self.op!r} compares with a value: add `value:`")
        return self

    def effective_op(self) -> str:
        """The operator applied: ``op``, or its default."""
        if self.op is not None:
            return self.op
        return "==" if "value" in self.model_fields_set else "set"

    def describe(self) -> str:
        """The condition as text, e.g. ``battery > 0.2``."""
        op = self.effective_op()
        return f"{self.key} is {op}" if op in ("set", "unset") else f"{self.key} {op} {self.value!r}"


def evaluate(op: str, found: Any, value: Any) -> tuple[bool, str]:
    """Apply ``op`` to the value found on the blackboard (``MISSING`` if unset) and ``value``.

    Returns:
        (holds, reason) where reason says why it does not hold (empty when it holds).
    """
    if op == "set":
        return (found is not _MISSING, "" if found is not _MISSING else "key is not set")
    if op == "unset":
        return (found is _MISSING, "" if found is _MISSING else f"key is set (to {found!r})")
    if found is _MISSING:
        return False, "key is not set"
    try:
        holds = bool(_COMPARE[op](found, value))
    except TypeError:
        return False, f"cannot compare {found!r} {op} {value!r}"
    return holds, "" if holds else f"found {found!r}, expected {op} {value!r}"


def read_key(client: Any, key: str) -> Any:
    """Read ``key`` through a blackboard client, ``MISSING`` when it is not set."""
    try:
        return client.get(key)
    except (KeyError, AttributeError):
        return _MISSING


MISSING = _MISSING
