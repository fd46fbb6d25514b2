"""Leaves that set, check and wait for blackboard keys."""

from __future__ import annotations

from typing import Annotated, Any

from pydantic import BaseModel, ConfigDict, Field

from missiontree.engine.leaf import Leaf, Status
from missiontree.engine.nodes.conditions import ConditionFields, evaluate, read_key
from missiontree.engine.ports import Input, Output


class SetBlackboard(Leaf):
    """Write a value to a blackboard key and succeed."""

    class Params(BaseModel):
        model_config = ConfigDict(extra="forbid")

        key: Annotated[str, Output("the key written")] = Field(description="Blackboard key to write.")
        value: Any = Field(description="Value to write (a `{bb: other}` copies another key).")

    params: Params

    def update(self) -> Status:
        """Write the value (read now if it references another key) and succeed."""
        value = self.value("value")
        self.write("key", value)
        return self.succeed(f"{self.params.key} = {value!r}")


class _ConditionLeaf(Leaf):
    """Shared by CheckBlackboard and WaitForBlackboard: evaluate the condition now."""

    class Params(ConditionFields):
        key: Annotated[str, Input("the key tested")] = Field(
            description="Blackboard key to test.")

    def holds(self) -> tuple[bool, str]:
        """Whether the condition holds now, and why not."""
        params: Any = self.params
        found = read_key(self.bb, params.key)
        holds, reason = evaluate(params.effective_op(), found, self.value("value"))
        return holds, f"{params.describe()}: {reason}" if reason else params.describe()


class CheckBlackboard(_ConditionLeaf):
    """Succeed when a blackboard condition holds, fail otherwise (checked once per tick)."""

    def update(self) -> Status:
        """Compare once."""
        holds, reason = self.holds()
        return self.succeed(reason) if holds else self.fail(reason)


class WaitForBlackboard(_ConditionLeaf):
    """Stay RUNNING until a blackboard condition holds, then succeed (wrap in Timeout to bound it)."""

    def update(self) -> Status:
        """Compare; keep running while the condition does not hold."""
        holds, reason = self.holds()
        return self.succeed(reason) if holds else self.running(f"waiting: {reason}")
