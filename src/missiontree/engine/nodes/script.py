"""``Script`` and ``ScriptCondition``: BT.CPP 4's scripting leaves, over the safe expression language.

``Script: {code: "visits = visits + 1; last = 'kitchen'"}`` runs assignments and succeeds;
``ScriptCondition: {code: "battery > 0.2 and not docked"}`` succeeds when the expression is true and
fails when it is false. An expression that cannot be evaluated (a key not set, a type mismatch) is a
fault, not a false condition (:mod:`missiontree.engine.expressions`).
"""

from __future__ import annotations

from typing import Any

from pydantic import BaseModel, ConfigDict, Field, PrivateAttr, field_validator

from missiontree.engine.conditions import read_key, write_key
from missiontree.engine.expressions import EvaluationError, Expression, Script, parse_expression, parse_script
from missiontree.engine.leaf import Leaf, Status


class _ScriptParams(BaseModel):
    model_config = ConfigDict(extra="forbid")

    code: str = Field(description="Assignments `key = expression` (or `:=`), separated by `;` or new lines.")
    _parsed: Script | None = PrivateAttr(default=None)

    @field_validator("code")
    @classmethod
    def _parses(cls, value: str) -> str:
        parse_script(value)  # an ExpressionError is a ValueError: pydantic reports it at `code`
        return value

    def script(self) -> Script:
        """The parsed script (parsed once)."""
        if self._parsed is None:
            self._parsed = parse_script(self.code)
        return self._parsed


class _ConditionParams(BaseModel):
    model_config = ConfigDict(extra="forbid")

    code: str = Field(description="An expression over blackboard keys that is true or false.")
    _parsed: Expression | None = PrivateAttr(default=None)

    @field_validator("code")
    @classmethod
    def _parses(cls, value: str) -> str:
        parse_expression(value)
        return value

    def expression(self) -> Expression:
        """The parsed expression (parsed once)."""
        if self._parsed is None:
            self._parsed = parse_expression(self.code)
        return self._parsed


class ScriptLeaf(Leaf):
    """Run assignments on the blackboard (`code: "a = b + 1; c := 'x'"`) and succeed."""

    Params = _ScriptParams
    params: Any

    def update(self) -> Status:
        """Run the assignments; an assignment that cannot be evaluated is a fault."""
        script = self.params.script()
        try:
            script.run(read_key, write_key)
        except EvaluationError as error:
            return self.fault(f"{script.text}: {error}")
        return self.succeed(script.text)


class ScriptCondition(Leaf):
    """Succeed when an expression over blackboard keys is true, fail when it is false."""

    Params = _ConditionParams
    params: Any

    def update(self) -> Status:
        """Evaluate once; an expression that cannot be evaluated is a fault, not false."""
        expression = self.params.expression()
        try:
            holds = expression.truth(read_key)
        except EvaluationError as error:
            return self.fault(f"{expression.text}: {error}")
        if holds:
            return self.succeed(f"`{expression.text}` is true")
        return self.fail(f"`{expression.text}` is false")


#: The node type names mission files use, and the written parameter holding the code.
SCRIPT_TYPES = {"Script": "code", "ScriptCondition": "code"}
