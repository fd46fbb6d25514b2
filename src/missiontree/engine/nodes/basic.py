"""Utility leaves: Wait on the mission clock, and Succeed/Fail/Running for shaping trees."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field

from missiontree.engine.leaf import Leaf, Status
from missiontree.engine.nodes.clock import Clock, clock_of


class Wait(Leaf):
    """Stay RUNNING for a number of seconds on the robot's clock (monotonic without a robot), then succeed."""

    class Params(BaseModel):
        model_config = ConfigDict(extra="forbid")

        seconds: float = Field(ge=0, description="How long to wait, in seconds.")

    def on_setup(self) -> None:
        """Take the clock from the mission context (the robot's), if there is one."""
        self._clock: Clock = clock_of(self.ctx)

    def initialise(self) -> None:
        """Start the wait now."""
        if not hasattr(self, "_clock"):
            self._clock = clock_of(self.ctx)
        self._deadline = self._clock() + float(self.value("seconds"))

    def update(self) -> Status:
        """Succeed once the deadline has passed."""
        left = self._deadline - self._clock()
        return self.succeed("waited") if left <= 0 else self.running(f"{left:.2f} s left")


class Succeed(Leaf):
    """Succeed at once."""

    class Params(BaseModel):
        model_config = ConfigDict(extra="forbid")

    def update(self) -> Status:
        """Succeed."""
        return self.succeed()


class Fail(Leaf):
    """Fail at once, with a reason."""

    class Params(BaseModel):
        model_config = ConfigDict(extra="forbid")

        reason: str = Field("failed on purpose", description="The failure reason recorded in the tick log.")

    params: Params

    def update(self) -> Status:
        """Fail with the reason."""
        return self.fail(self.params.reason)


class Running(Leaf):
    """Stay RUNNING forever (a placeholder, or to keep a Parallel branch alive)."""

    class Params(BaseModel):
        model_config = ConfigDict(extra="forbid")

    def update(self) -> Status:
        """Keep running."""
        return self.running()
