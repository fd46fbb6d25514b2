"""Sensors added by plugins: what a sensor kind is, and how backends produce and hold its readings.

A plugin registers a :class:`SensorKind` through the ``missiontree_register_sensors`` hook. The kind
says what its value is (``value_type``, and which of its attributes are numbers), how the ROS 2
backend gets it (:class:`Ros2Source`: topic, message type, QoS and *pure* conversion functions, as in
``missiontree.backends.ros2.conversions``) and how the simulator produces it (:class:`SimSource`: a
model stepped with the simulator's state, time and motion). Leaves then read any sensor as they read
the built-in ones::

    reading = robot.sensor("battery")      # SensorReading(stamp, value) or None before the first
    if reading is None or robot.now() - reading.stamp > 5.0:
        ...                                # never heard, or quiet: a stale stamp, never an exception

Backends hold the readings in a :class:`SensorStore`; a sensor the backend was not given is an
:class:`UnknownSensorError` naming the ones it has.
"""

from __future__ import annotations

import importlib
import math
import threading
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any, Literal, Protocol

from missiontree.errors import ConfigError, PluginError

#: QoS names a :class:`Ros2Source` may use (the profiles of ``backends.ros2.robot``).
QOS_NAMES = ("sensor", "reliable", "latched")


class UnknownSensorError(ConfigError):
    """A sensor was asked for that the robot does not have (the message lists the ones it has)."""


@dataclass(frozen=True)
class SensorReading:
    """The latest value of a sensor with the time it was measured (backend clock, s).

    Attributes:
        stamp: When the value was measured; a sensor that went quiet keeps an old stamp.
        value: The value, of the kind's ``value_type``.
    """

    stamp: float
    value: Any

    def age(self, now: float) -> float:
        """Seconds since the value was measured."""
        return now - self.stamp

    def number(self, field_name: str = "") -> float:
        """The value (or its attribute ``field_name``) as a float.

        Raises:
            TypeError: It is not a number.
        """
        raw = getattr(self.value, field_name) if field_name else self.value
        if isinstance(raw, bool) or not isinstance(raw, int | float):
            what = f"field {field_name!r}" if field_name else "value"
            raise TypeError(f"sensor {what} is {type(raw).__name__}, not a number")
        return float(raw)


@dataclass(frozen=True)
class SimState:
    """What a simulated sensor model may look at on each sample (the physics, not the robot's estimate).

    Attributes:
        t: Simulated time now (s).
        dt: Seconds since this model's previous sample (0 at the first).
        pose: The robot's true pose (x, y, yaw) — sensors measure the world, not the estimate.
        v: Forward speed now (m/s).
        w: Turn rate now (rad/s).
        distance: Metres driven since this model's previous sample.
        odometer: Metres driven since the start.
    """

    t: float
    dt: float
    pose: tuple[float, float, float]
    v: float
    w: float
    distance: float
    odometer: float


class SimSensorModel(Protocol):
    """A simulated sensor: called at its rate with the simulator's state, returns the new value.

    Returning None publishes nothing this time (the sensor is quiet).
    """

    def sample(self, state: SimState) -> Any:
        """The value measured now, or None."""
        ...


@dataclass(frozen=True)
class SimSource:
    """How the simulator produces a sensor.

    Attributes:
        model: ``model(options, seed) -> SimSensorModel``; ``options`` is the world file's section
            for this plugin (``plugins: {<section>: {...}}``, empty when absent), ``seed`` the run's.
        rate: Samples per simulated second.
        section: The world file's ``plugins:`` section to hand the model; default the sensor name.
    """

    model: Callable[[Mapping[str, Any], int], SimSensorModel]
    rate: float = 1.0
    section: str = ""


@dataclass(frozen=True)
class Ros2Source:
    """How the ROS 2 backend gets a sensor, and how ``missiontree sim-ros`` publishes it.

    Attributes:
        topic: The topic (relative names resolve in the robot's namespace).
        message: The message type as ``"package.msg:Type"`` (imported only by the ROS 2 backend).
        from_msg: Pure conversion ``from_msg(msg) -> value``.
        to_msg: Pure conversion ``to_msg(value, stamp) -> msg`` for sim-ros; None if it cannot publish.
        qos: ``sensor`` (best effort), ``reliable`` or ``latched`` (transient local).
        stamp_from_header: Stamp readings with the message's ``header.stamp`` (else arrival time).
    """

    topic: str
    message: str
    from_msg: Callable[[Any], Any]
    to_msg: Callable[[Any, float], Any] | None = None
    qos: Literal["sensor", "reliable", "latched"] = "sensor"
    stamp_from_header: bool = True

    def message_type(self) -> type:
        """Import and return the message class.

        Raises:
            PluginError: The string is malformed or the class does not import.
        """
        module_name, _, attr = self.message.partition(":")
        if not module_name or not attr:
            raise PluginError(f"sensor topic {self.topic!r}: message {self.message!r} is not "
                              f"'package.msg:Type'")
        try:
            return getattr(importlib.import_module(module_name), attr)  # type: ignore[no-any-return]
        except (ImportError, AttributeError) as error:
            raise PluginError(f"sensor topic {self.topic!r}: message type {self.message!r} does not import: "
                              f"{error}") from error


@dataclass(frozen=True)
class SensorKind:
    """A kind of sensor a plugin adds.

    Attributes:
        name: The name leaves ask for (``robot.sensor(name)``); lowercase, digits and ``_``.
        value_type: The type of its values (a float, or a dataclass such as ``BatteryReading``).
        description: One line for ``missiontree plugins`` and the guide.
        fields: Numeric attributes of a structured value the generic leaves may test (empty when
            the value itself is a number).
        ros2: How the ROS 2 backend gets it; None: not available over ROS 2.
        sim: How the simulator produces it; None: not simulated.
        log_period: Seconds between the tick log's samples of it (0: never sampled).
        unit: Unit of its number(s), for messages and the viewer.
    """

    name: str
    value_type: type
    description: str = ""
    fields: tuple[str, ...] = ()
    ros2: Ros2Source | None = None
    sim: SimSource | None = None
    log_period: float = 1.0
    unit: str = ""

    def __post_init__(self) -> None:
        if not self.name or not all(c.islower() or c.isdigit() or c == "_" for c in self.name):
            raise PluginError(f"sensor name {self.name!r}: expected lowercase letters, digits and '_'")
        if self.ros2 is not None and self.ros2.qos not in QOS_NAMES:
            raise PluginError(f"sensor {self.name!r}: qos {self.ros2.qos!r} is not one of "
                              f"{', '.join(QOS_NAMES)}")
        if self.sim is not None and not (math.isfinite(self.sim.rate) and self.sim.rate > 0):
            raise PluginError(f"sensor {self.name!r}: sim rate must be a positive number, "
                              f"found {self.sim.rate!r}")

    @property
    def numeric(self) -> bool:
        """True when the value itself is a number."""
        return self.value_type in (int, float)

    def check_field(self, field_name: str) -> None:
        """Check that ``field_name`` (or the value itself, when empty) is a number generic leaves can test.

        Raises:
            ConfigError: It is not (the message lists the numeric fields).
        """
        if field_name:
            if field_name not in self.fields:
                known = ", ".join(self.fields) or "none"
                raise ConfigError(f"sensor {self.name!r} has no numeric field {field_name!r}; "
                                  f"numeric fields: {known}")
        elif not self.numeric:
            known = ", ".join(self.fields) or "none"
            raise ConfigError(f"sensor {self.name!r} gives a {self.value_type.__name__}, not a number; "
                              f"name one of its numeric fields with `field:` ({known})")

    def summary(self, reading: SensorReading) -> dict[str, Any]:
        """A reading as plain JSON values for the tick log: ``{"stamp", <field>: number...}`` or ``value``."""
        out: dict[str, Any] = {"stamp": round(reading.stamp, 3)}
        if self.fields:
            for name in self.fields:
                raw = getattr(reading.value, name, None)
                out[name] = _plain(raw)
        else:
            out["value"] = _plain(reading.value)
        return out


def _plain(raw: Any) -> Any:
    if isinstance(raw, bool) or raw is None or isinstance(raw, str):
        return raw
    if isinstance(raw, int | float):
        value = float(raw)
        return round(value, 6) if math.isfinite(value) else None
    return str(raw)


class SensorStore:
    """The latest reading of each of a robot's plugin sensors (thread-safe: ROS callbacks write it).

    Args:
        kinds: The sensor kinds the robot has.
    """

    def __init__(self, kinds: Iterable[SensorKind] = ()) -> None:
        self.kinds: dict[str, SensorKind] = {}
        for kind in kinds:
            if kind.name in self.kinds:
                raise PluginError(f"sensor {kind.name!r} given twice")
            self.kinds[kind.name] = kind
        self._latest: dict[str, SensorReading] = {}
        self._lock = threading.Lock()

    def names(self) -> list[str]:
        """The sensor names, sorted."""
        return sorted(self.kinds)

    def kind(self, name: str) -> SensorKind:
        """The kind of sensor ``name``.

        Raises:
            UnknownSensorError: The robot has no such sensor.
        """
        if name not in self.kinds:
            raise UnknownSensorError(unknown_sensor_message(name, self.names()))
        return self.kinds[name]

    def put(self, name: str, stamp: float, value: Any) -> None:
        """Record a new reading (an older stamp than the latest is ignored)."""
        with self._lock:
            latest = self._latest.get(name)
            if latest is None or stamp >= latest.stamp:
                self._latest[name] = SensorReading(float(stamp), value)

    def get(self, name: str) -> SensorReading | None:
        """The latest reading of ``name``, None before the first.

        Raises:
            UnknownSensorError: The robot has no such sensor.
        """
        if name not in self.kinds:
            raise UnknownSensorError(unknown_sensor_message(name, self.names()))
        with self._lock:
            return self._latest.get(name)


def unknown_sensor_message(name: str, known: Iterable[str]) -> str:
    """The message for a sensor the robot lacks."""
    listed = ", ".join(sorted(known)) or "none (no plugin registered a sensor)"
    return (f"this robot has no sensor {name!r}; its plugin sensors: {listed} "
            f"(sensors come from plugins: `missiontree plugins` lists them)")


def sensor_kinds_from_options(options: Mapping[str, Any]) -> list[SensorKind]:
    """The sensor kinds a backend factory should give its robot: ``options["sensors"]``, else none.

    The session passes the loaded plugins' sensors (``missiontree sim-ros`` too); a backend built
    without them has no plugin sensors.

    Raises:
        ConfigError: ``options["sensors"]`` is not a list (or mapping) of SensorKind.
    """
    given = options.get("sensors")
    if given is None:
        return []
    kinds = list(given.values()) if isinstance(given, Mapping) else list(given)
    bad = [k for k in kinds if not isinstance(k, SensorKind)]
    if bad:
        raise ConfigError(f"backend option sensors: expected SensorKind values, found {bad[0]!r}")
    return kinds


@dataclass
class SimSensors:
    """The simulator's plugin sensors: each kind's model, sampled at its rate.

    Args:
        kinds: The robot's sensor kinds (those without ``sim`` are listed but never produce).
        world_sections: The world file's ``plugins:`` mapping.
        seed: The run's seed (models derive their randomness from it).
    """

    kinds: list[SensorKind]
    world_sections: Mapping[str, Any]
    seed: int
    store: SensorStore = field(init=False)
    quiet: set[str] = field(default_factory=set)

    def __post_init__(self) -> None:
        self.store = SensorStore(self.kinds)
        self._models: dict[str, SimSensorModel] = {}
        self._next: dict[str, float] = {}
        self._last: dict[str, tuple[float, float]] = {}  # name -> (t, odometer) of the last sample
        for kind in self.kinds:
            if kind.sim is None:
                continue
            section = self.world_sections.get(kind.sim.section or kind.name) or {}
            if not isinstance(section, Mapping):
                raise ConfigError(f"world plugins.{kind.sim.section or kind.name}: expected a mapping, "
                                  f"found {type(section).__name__}")
            try:
                self._models[kind.name] = kind.sim.model(dict(section), self.seed)
            except ConfigError:
                raise
            except Exception as error:  # noqa: BLE001 - a plugin's model failing is the plugin's error
                raise PluginError(f"sensor {kind.name!r}: its simulator model failed to start: "
                                  f"{type(error).__name__}: {error}") from error
            self._next[kind.name] = 0.0

    def step(self, t: float, pose: tuple[float, float, float], v: float, w: float, odometer: float) -> None:
        """Sample every model whose time has come."""
        for name, model in self._models.items():
            if t < self._next[name] - 1e-9:
                continue
            rate = self.store.kinds[name].sim.rate  # type: ignore[union-attr]  # models exist only with sim
            self._next[name] = t + 1.0 / rate
            last_t, last_odo = self._last.get(name, (t, odometer))
            self._last[name] = (t, odometer)
            state = SimState(t=t, dt=t - last_t, pose=pose, v=v, w=w, distance=odometer - last_odo,
                             odometer=odometer)
            value = model.sample(state)
            if value is not None and name not in self.quiet:
                self.store.put(name, t, value)
