"""Generic leaves for any numeric plugin sensor: a threshold condition and a wait for a value.

Plugin sensors (:mod:`missiontree.robot.sensors`) are read with ``robot.sensor(name)``: the latest
value with its stamp. These leaves test one number of it — the value itself, or one of the kind's
numeric ``fields`` — against a threshold, with a staleness limit:

- :class:`SensorCondition` has the shape of Nav2's ``IsBatteryLow`` condition: SUCCESS while the
  number is on the asked side of the threshold, FAILURE otherwise, and FAILURE with a fault (an error,
  not a false condition: no Inverter turns it into SUCCESS, see :mod:`missiontree.engine.faults`) when
  the sensor never spoke, its reading is older than ``max_age`` (a quiet sensor shows as a stale
  stamp) or its number is not finite.
- :class:`WaitForSensor` stays RUNNING until the number reaches the value (wrap it in ``Timeout``);
  a stale reading keeps it waiting (and says so), or fails it with a fault after ``stale_timeout``.

Both send the reading to the tick log as a ``sensor`` event at most every ``log_period`` of the
sensor's kind (the viewer lists these events), so a run's log shows the sensor while a leaf watches it.
"""

from __future__ import annotations

import math
import operator
import weakref
from collections.abc import Callable
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field

from missiontree.engine.context import MissionContext
from missiontree.engine.leaf import Leaf, Status
from missiontree.engine.registry import NodeRegistry
from missiontree.errors import ConfigError
from missiontree.robot.sensors import SensorKind, SensorReading, UnknownSensorError

Comparison = Literal["<", "<=", ">", ">="]
_OPS: dict[str, Callable[[float, float], bool]] = {
    "<": operator.lt, "<=": operator.le, ">": operator.gt, ">=": operator.ge,
}
# when each mission context last logged each sensor (keyed by id, the context is not hashable):
# leaves share it so a sensor is sampled once per period whichever leaf reads it
_LOGGED: dict[int, tuple[weakref.ref[object], dict[str, float]]] = {}


def _logged_for(context: object) -> dict[str, float]:
    entry = _LOGGED.get(id(context))
    if entry is None or entry[0]() is not context:
        for key in [k for k, (ref, _) in _LOGGED.items() if ref() is None]:
            del _LOGGED[key]
        entry = _LOGGED[id(context)] = (weakref.ref(context), {})
    return entry[1]


class _SensorLeaf(Leaf):
    """Shared by the sensor leaves: resolve the sensor at setup, read one number, log samples."""

    params: _SensorParams

    def on_setup(self) -> None:
        """Check that the robot has the sensor and that the asked field is a number."""
        self._kind: SensorKind | None = None
        if self.ctx is None:
            return
        robot = self.ctx.robot
        if not hasattr(robot, "sensor_kind"):
            raise ConfigError(f"{self.name}: robot {getattr(robot, 'name', robot)!r} has no plugin sensors")
        try:
            self._kind = robot.sensor_kind(self.params.sensor)
        except UnknownSensorError as error:
            raise ConfigError(f"{self.name}: {error}") from None
        self._kind.check_field(self.params.field)

    def _read(self) -> tuple[SensorReading | None, float]:
        """The latest reading and its age (inf before the first); log it as a sample if due."""
        robot = self.context.robot
        try:
            reading = robot.sensor(self.params.sensor)
        except UnknownSensorError as error:
            raise ConfigError(f"{self.name}: {error}") from None
        now = robot.now()
        if reading is None:
            return None, math.inf
        self._log_sample(reading, now)
        return reading, now - reading.stamp

    def _number(self, reading: SensorReading) -> float:
        value = reading.number(self.params.field)
        if not math.isfinite(value):
            raise ValueError(f"sensor {self.params.sensor!r} gave a non-finite number ({value})")
        return value

    def _log_sample(self, reading: SensorReading, now: float) -> None:
        if self._kind is not None and self.ctx is not None:
            log_sample(self.ctx, self._kind, reading, now)

    def _what(self) -> str:
        return f"{self.params.sensor}.{self.params.field}" if self.params.field else self.params.sensor


def log_sample(context: MissionContext, kind: SensorKind, reading: SensorReading, now: float) -> bool:
    """Send ``reading`` to the tick log as a ``sensor`` event if ``kind.log_period`` has passed.

    Any leaf that reads a plugin sensor may call it (the generic leaves do, and the battery plugin's
    IsBatteryLow); leaves share the period, so a sensor is sampled once per period per run. Returns
    whether an event went out.
    """
    if kind.log_period <= 0:
        return False
    logged = _logged_for(context)
    last = logged.get(kind.name)
    if last is not None and reading.stamp - last < kind.log_period - 1e-9:
        return False
    logged[kind.name] = reading.stamp
    context.events.emit("sensor", sensor=kind.name, age=round(now - reading.stamp, 3), unit=kind.unit,
                        **kind.summary(reading))
    return True


class _SensorParams(BaseModel):
    model_config = ConfigDict(extra="forbid")

    sensor: str = Field(description="The plugin sensor to read (`missiontree plugins` lists them).")
    field: str = Field("", description="Its numeric field to test (percentage...); empty: the value itself.")
    op: Comparison = Field("<", description="How the number compares with `threshold`/`value`.")
    max_age: float = Field(5.0, gt=0, description="A reading older than this many seconds is stale.")


class SensorCondition(_SensorLeaf):
    """Succeed while a sensor's number is past a threshold (Nav2 IsBatteryLow's shape); stale fails."""

    class Params(_SensorParams):
        threshold: float = Field(description="The threshold the number is compared with.")
        stale: Literal["fail", "succeed"] = Field(
            "fail", description="What a stale or missing reading gives (succeed: taken as holding).")

    params: Params

    def update(self) -> Status:
        """Compare the latest reading once."""
        reading, age = self._read()
        if reading is None or age > self.params.max_age:
            why = ("no reading yet" if reading is None
                   else f"reading is {age:.1f} s old (max_age {self.params.max_age:g} s)")
            if self.params.stale == "succeed":
                return self.succeed(f"{self._what()}: {why}, taken as holding")
            return self.fault(f"{self._what()}: {why}")
        value = self._number(reading)
        holds = _OPS[self.params.op](value, self.params.threshold)
        text = f"{self._what()} {value:g} {self.params.op} {self.params.threshold:g}"
        return self.succeed(text) if holds else self.fail(f"not {text}")


class WaitForSensor(_SensorLeaf):
    """Stay RUNNING until a sensor's number reaches a value (wrap in Timeout to bound it)."""

    class Params(_SensorParams):
        op: Comparison = Field(">=", description="How the number must compare with `value` to succeed.")
        value: float = Field(description="The value to wait for.")
        stale_timeout: float | None = Field(
            None, gt=0, description="Fail once no fresh reading came for this many s; default: wait on.")

    params: Params

    def initialise(self) -> None:
        """Start waiting; no staleness seen yet."""
        self._stale_since: float | None = None

    def update(self) -> Status:
        """Succeed once a fresh reading reaches the value."""
        reading, age = self._read()
        if reading is None or age > self.params.max_age:
            now = self.context.robot.now()
            if self._stale_since is None:
                self._stale_since = now
            limit = self.params.stale_timeout
            if limit is not None and now - self._stale_since >= limit:
                return self.fault(f"{self._what()}: no fresh reading for {limit:g} s")
            return self.running(f"{self._what()}: " + ("no reading yet" if reading is None
                                                       else f"stale ({age:.1f} s)"))
        self._stale_since = None
        value = self._number(reading)
        if _OPS[self.params.op](value, self.params.value):
            return self.succeed(f"{self._what()} {value:g} {self.params.op} {self.params.value:g}")
        return self.running(f"{self._what()} {value:g}, waiting for {self.params.op} {self.params.value:g}")


LEAVES = [SensorCondition, WaitForSensor]


def register_nodes(registry: NodeRegistry) -> None:
    """Add the sensor leaves (listed in ``missiontree.plugins.builtin.NODE_MODULES``)."""
    for leaf in LEAVES:
        registry.add(leaf, provider="builtin")
