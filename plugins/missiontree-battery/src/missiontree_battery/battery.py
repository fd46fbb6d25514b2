"""The ``battery`` sensor: its value, its ROS 2 conversions and its simulator model.

Over ROS 2 it is ``sensor_msgs/BatteryState`` on ``/battery_state``, as the TurtleBot 4 (its Create 3
base) publishes it: ``percentage`` in [0, 1], ``voltage`` in volts, ``current`` in amperes (negative
while discharging), ``power_supply_status`` CHARGING (1) on the dock. The conversions are pure
functions of the message, so they are tested without ROS.

In the simulator the charge drains with time (electronics, ``drain_per_s``) and with distance
driven (motors, ``drain_per_m``), and fills at ``charge_per_s`` while the robot stands within
``dock.radius`` of the dock pose. The world file configures it in its ``plugins:`` section::

    plugins:
      battery:
        dock: {x: 0.6, y: -1.0}
        start: 0.6            # charge at the start (fraction)
        drain_per_m: 0.02     # fraction per metre driven
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from pydantic import BaseModel, ConfigDict, Field, ValidationError

from missiontree.errors import ConfigError
from missiontree.robot.sensors import Ros2Source, SensorKind, SimSource, SimState

#: sensor_msgs/BatteryState.power_supply_status values.
STATUS_UNKNOWN, STATUS_CHARGING, STATUS_DISCHARGING, STATUS_NOT_CHARGING, STATUS_FULL = 0, 1, 2, 3, 4
#: The Create 3's pack: four Li-ion cells in series.
VOLTS_EMPTY, VOLTS_FULL = 12.0, 16.8


@dataclass(frozen=True)
class BatteryReading:
    """What the battery says.

    Attributes:
        percentage: Charge in [0, 1] (NaN when the robot does not know).
        voltage: Pack voltage (V).
        current: Current (A), negative while discharging.
        charging: True while on the charger.
    """

    percentage: float
    voltage: float
    current: float
    charging: bool


#: The numeric fields generic leaves (SensorCondition, WaitForSensor) may test.
FIELDS = ("percentage", "voltage", "current")


def battery_from_msg(msg: Any) -> BatteryReading:
    """A ``sensor_msgs/BatteryState`` as a :class:`BatteryReading` (pure: reads the message only).

    ROS leaves unknown numbers NaN; a percentage published in 0-100 (some drivers do) is scaled to
    [0, 1].
    """
    percentage = float(msg.percentage)
    if math.isfinite(percentage) and percentage > 1.0:
        percentage /= 100.0
    return BatteryReading(percentage=percentage, voltage=float(msg.voltage), current=float(msg.current),
                          charging=int(msg.power_supply_status) in (STATUS_CHARGING, STATUS_FULL))


def battery_to_msg(reading: BatteryReading, stamp: float) -> Any:
    """A :class:`BatteryReading` as a ``sensor_msgs/BatteryState`` stamped ``stamp`` (for sim-ros)."""
    from builtin_interfaces.msg import Time
    from sensor_msgs.msg import BatteryState

    msg = BatteryState()
    sec = math.floor(stamp)
    msg.header.stamp = Time(sec=int(sec), nanosec=min(int(round((stamp - sec) * 1e9)), 999_999_999))
    msg.header.frame_id = "base_link"
    msg.percentage = float(reading.percentage)
    msg.voltage = float(reading.voltage)
    msg.current = float(reading.current)
    msg.charge = math.nan
    msg.capacity = math.nan
    msg.design_capacity = 2.6  # Ah, the Create 3's pack
    msg.temperature = math.nan
    if reading.charging:
        msg.power_supply_status = STATUS_FULL if reading.percentage >= 1.0 else STATUS_CHARGING
    else:
        msg.power_supply_status = STATUS_DISCHARGING
    msg.power_supply_health = 1  # GOOD
    msg.power_supply_technology = 2  # LION
    msg.present = True
    return msg


class DockSpec(BaseModel):
    """Where the robot charges."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)

    x: float
    y: float
    radius: float = Field(0.35, gt=0, le=5, description="standing this close to (x, y) charges")


class BatteryOptions(BaseModel):
    """The world file's ``plugins: {battery: ...}`` section."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)

    start: float = Field(1.0, ge=0, le=1, description="charge at the start (fraction)")
    drain_per_s: float = Field(0.0005, ge=0, le=1, description="fraction lost per second (electronics)")
    drain_per_m: float = Field(0.005, ge=0, le=1, description="fraction lost per metre driven (motors)")
    charge_per_s: float = Field(0.01, ge=0, le=1, description="fraction gained per second on the dock")
    dock: DockSpec | None = Field(None, description="the charging dock; none: the battery never charges")
    max_dock_speed: float = Field(0.02, ge=0, description="moving faster than this (m/s) does not charge")


class BatteryModel:
    """The simulated battery: drains with time and distance, charges standing on the dock.

    Args:
        options: The world's ``plugins.battery`` section (checked: unknown keys and bad numbers are
            a :class:`~missiontree.errors.ConfigError` naming them).
        seed: The run's seed (unused: the model is exact).
    """

    def __init__(self, options: Mapping[str, Any], seed: int = 0) -> None:
        try:
            self.options = BatteryOptions.model_validate(dict(options))
        except ValidationError as error:
            problems = "; ".join(f"{'.'.join(str(p) for p in e['loc']) or 'battery'}: {e['msg']}"
                                 for e in error.errors())
            raise ConfigError(f"world plugins.battery: {problems}; known keys: "
                              f"{', '.join(BatteryOptions.model_fields)}") from None
        self.charge = self.options.start

    def on_dock(self, state: SimState) -> bool:
        """True when the robot stands on the dock."""
        dock = self.options.dock
        if dock is None or abs(state.v) > self.options.max_dock_speed:
            return False
        return math.hypot(state.pose[0] - dock.x, state.pose[1] - dock.y) <= dock.radius

    def sample(self, state: SimState) -> BatteryReading:
        """Advance the charge by the time and distance since the last sample; the reading now."""
        o = self.options
        charging = self.on_dock(state)
        if charging:
            self.charge = min(1.0, self.charge + o.charge_per_s * state.dt)
        else:
            self.charge = max(0.0, self.charge - o.drain_per_s * state.dt - o.drain_per_m * state.distance)
        voltage = VOLTS_EMPTY + (VOLTS_FULL - VOLTS_EMPTY) * self.charge
        current = 1.5 if charging and self.charge < 1.0 else -(0.3 + 0.8 * abs(state.v))
        return BatteryReading(percentage=round(self.charge, 6), voltage=round(voltage, 4),
                              current=round(current, 4), charging=charging)


#: The sensor kind the plugin registers.
BATTERY = SensorKind(
    name="battery",
    value_type=BatteryReading,
    description="battery charge (sensor_msgs/BatteryState on /battery_state; simulated with a dock)",
    fields=FIELDS,
    ros2=Ros2Source(topic="/battery_state", message="sensor_msgs.msg:BatteryState",
                    from_msg=battery_from_msg, to_msg=battery_to_msg, qos="sensor"),
    sim=SimSource(model=BatteryModel, rate=1.0),
    log_period=10.0,
    unit="fraction",
)
