"""CountDown: a leaf that stays RUNNING for a number of ticks, publishing what is left."""

from __future__ import annotations

from typing import Annotated

from pydantic import BaseModel, Field

from missiontree.engine.leaf import Leaf, Status
from missiontree.engine.ports import Output


class CountDown(Leaf):
    """Run for a number of ticks, writing the ticks left to the blackboard, then succeed.

    ``fail_at`` makes it fail when the count reaches that value (to rehearse failure handling).
    """

    class Params(BaseModel):
        ticks: int = Field(3, ge=0, description="ticks to run before succeeding")
        fail_at: int | None = Field(None, ge=0, description="fail when this many ticks are left")
        remaining: Annotated[str, Output("ticks left in the count", type="int")] = "countdown"

    def initialise(self) -> None:
        """Start counting from ``ticks``."""
        self.left = self.value("ticks")

    def update(self) -> Status:
        """Publish the ticks left; succeed at zero."""
        self.write("remaining", self.left)
        if self.params.fail_at is not None and self.left == self.params.fail_at:
            return self.fail(f"count stopped at {self.left} (fail_at)")
        if self.left <= 0:
            return self.succeed("lift-off")
        self.left -= 1
        return self.running(f"{self.left + 1} left")
