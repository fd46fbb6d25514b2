"""IsBatteryLow: Nav2's condition of that name, on the plugin's ``battery`` sensor.

Nav2's ``IsBatteryLow`` subscribes to a BatteryState topic and succeeds when the charge (or the
voltage, with ``is_voltage``) is at or below ``min_battery``. Here the backend does the subscribing
(the ``battery`` sensor, :mod:`missiontree_battery.battery`) and the leaf reads
``robot.sensor("battery")``: the latest reading with its stamp. A reading older than ``max_age``
(the battery went quiet), none at all, or a NaN level (ROS's "unknown") is FAILURE with the reason,
unless ``stale_is_low``.
"""

from __future__ import annotations

import math

from pydantic import BaseModel, ConfigDict, Field

from missiontree.engine.leaf import Leaf, Status
from missiontree.engine.nodes.sensors import log_sample


class IsBatteryLow(Leaf):
    """Succeed when the battery is at or below min_battery (Nav2's IsBatteryLow); a stale reading fails."""

    class Params(BaseModel):
        model_config = ConfigDict(extra="forbid")

        min_battery: float = Field(0.2, ge=0, description="Low at or below this (fraction 0-1, or volts).")
        is_voltage: bool = Field(False, description="Compare the voltage instead of the percentage.")
        max_age: float = Field(5.0, gt=0, description="A reading older than this many seconds is stale.")
        stale_is_low: bool = Field(False, description="Take a stale or missing reading as low.")

    params: Params

    def on_setup(self) -> None:
        """Check that the robot has the battery sensor (a clear error names the sensors it has)."""
        if self.ctx is not None:
            self.ctx.robot.sensor_kind("battery")

    def update(self) -> Status:
        """Compare the latest reading once."""
        robot = self.context.robot
        reading = robot.sensor("battery")
        if reading is not None:  # a sample in the tick log every log_period (the viewer lists them)
            log_sample(self.context, robot.sensor_kind("battery"), reading, robot.now())
        age = None if reading is None else robot.now() - reading.stamp
        if age is None or age > self.params.max_age:
            why = "no battery reading yet" if age is None else f"battery reading is {age:.1f} s old"
            return self.succeed(f"{why}: taken as low") if self.params.stale_is_low else self.fail(why)
        level = reading.value.voltage if self.params.is_voltage else reading.value.percentage
        unit = " V" if self.params.is_voltage else ""
        if not math.isfinite(level):  # ROS leaves what the battery does not know NaN
            why = f"the battery does not report its {'voltage' if self.params.is_voltage else 'percentage'}"
            return self.succeed(f"{why}: taken as low") if self.params.stale_is_low else self.fail(why)
        if level <= self.params.min_battery:
            return self.succeed(f"battery low: {level:.3g}{unit} <= {self.params.min_battery:g}{unit}")
        return self.fail(f"battery ok: {level:.3g}{unit} > {self.params.min_battery:g}{unit}")
