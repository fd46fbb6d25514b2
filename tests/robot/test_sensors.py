"""Plugin sensors on robots: kinds, the store, the simulator's models, the world's plugin sections."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import pytest

from missiontree.backends.sim import create_robot
from missiontree.errors import ConfigError, PluginError, WorldFileError
from missiontree.paths import find_config
from missiontree.robot.sensors import (
    Ros2Source,
    SensorKind,
    SensorReading,
    SensorStore,
    SimSource,
    SimState,
    UnknownSensorError,
    sensor_kinds_from_options,
)
from missiontree.testing import ClockRobot


class Odometer:
    """A test sensor model: metres driven, offset by the world's ``plugins.odometer.offset``."""

    def __init__(self, options: Mapping[str, Any], seed: int) -> None:
        self.offset = float(options.get("offset", 0.0))
        self.states: list[SimState] = []

    def sample(self, state: SimState) -> float:
        self.states.append(state)
        return self.offset + state.odometer


ODOMETER = SensorKind(name="odometer", value_type=float, description="metres driven", unit="m",
                      sim=SimSource(model=Odometer, rate=2.0), log_period=1.0)


def test_kind_checks_its_name_qos_and_rate() -> None:
    with pytest.raises(PluginError, match="lowercase"):
        SensorKind(name="Battery", value_type=float)
    with pytest.raises(PluginError, match="qos 'fast'"):
        SensorKind(name="x", value_type=float,
                   ros2=Ros2Source("/x", "std_msgs.msg:Float32", lambda m: m.data, qos="fast"))  # type: ignore[arg-type]
    with pytest.raises(PluginError, match="rate"):
        SensorKind(name="x", value_type=float, sim=SimSource(model=Odometer, rate=0.0))


def test_kind_says_which_fields_generic_leaves_may_test() -> None:
    ODOMETER.check_field("")
    with pytest.raises(ConfigError, match="no numeric field 'speed'"):
        ODOMETER.check_field("speed")
    structured = SensorKind(name="b", value_type=dict, fields=("level",))
    structured.check_field("level")
    with pytest.raises(ConfigError, match="not a number; name one of its numeric fields with `field:`"):
        structured.check_field("")


def test_message_type_that_does_not_import_is_a_plugin_error() -> None:
    with pytest.raises(PluginError, match="does not import"):
        Ros2Source("/x", "no_such_msgs.msg:Thing", lambda m: m).message_type()
    with pytest.raises(PluginError, match="not 'package.msg:Type'"):
        Ros2Source("/x", "Thing", lambda m: m).message_type()


def test_store_keeps_the_latest_and_names_unknown_sensors() -> None:
    store = SensorStore([ODOMETER])
    assert store.get("odometer") is None
    store.put("odometer", 2.0, 1.5)
    store.put("odometer", 1.0, 9.9)  # older: ignored
    assert store.get("odometer") == SensorReading(2.0, 1.5)
    with pytest.raises(UnknownSensorError, match="no sensor 'battery'; its plugin sensors: odometer"):
        store.get("battery")
    with pytest.raises(PluginError, match="given twice"):
        SensorStore([ODOMETER, ODOMETER])


def test_reading_number_and_age() -> None:
    reading = SensorReading(3.0, 2.5)
    assert reading.age(5.0) == 2.0 and reading.number() == 2.5
    with pytest.raises(TypeError, match="not a number"):
        SensorReading(0.0, "high").number()


def test_sim_robot_samples_at_the_rate_with_time_and_motion() -> None:
    robot = create_robot({"world": "conformance", "sensors": [ODOMETER]})
    assert robot.sensor_names() == ["odometer"] and robot.sensor_kind("odometer") is ODOMETER
    robot.drive(0.2, 0.0)
    robot.spin_until(3.0)
    reading = robot.sensor("odometer")
    assert reading is not None and reading.stamp == pytest.approx(3.0)
    assert 0.3 < reading.value < 0.62  # 0.2 m/s for up to 3 s, after accelerating
    model = robot.plugin_sensors._models["odometer"]
    stamps = [s.t for s in model.states]
    assert stamps[:3] == pytest.approx([0.0, 0.5, 1.0])  # 2 Hz
    assert all(s.dt == pytest.approx(0.5) for s in model.states[1:])
    assert sum(s.distance for s in model.states) == pytest.approx(model.states[-1].odometer)
    robot.close()


def test_silenced_plugin_sensor_goes_stale_and_resumes() -> None:
    robot = create_robot({"world": "conformance", "sensors": [ODOMETER]})
    robot.spin_until(1.0)
    robot.silence("odometer")
    robot.spin_until(4.0)
    assert robot.sensor("odometer").stamp == pytest.approx(1.0)
    robot.silence("odometer", quiet=False)
    robot.spin_until(5.0)
    assert robot.sensor("odometer").stamp == pytest.approx(5.0)
    with pytest.raises(ValueError, match="expected one of lidar, camera, odometer"):
        robot.silence("sonar")
    robot.close()


def test_unknown_sensor_on_the_simulator_lists_its_sensors() -> None:
    robot = create_robot({"world": "conformance", "sensors": [ODOMETER]})
    with pytest.raises(UnknownSensorError, match="no sensor 'battery'; its plugin sensors: odometer"):
        robot.sensor("battery")
    robot.close()


def _world_with(tmp_path: Path, section: str) -> Path:
    text = find_config("worlds", "conformance").read_text(encoding="utf-8")
    path = tmp_path / "world.yaml"
    path.write_text(text + section, encoding="utf-8")
    return path


def test_world_plugin_section_reaches_the_sensor_model(tmp_path: Path) -> None:
    world = _world_with(tmp_path, "plugins:\n  odometer: {offset: 100.0}\n")
    robot = create_robot({"world": str(world), "sensors": [ODOMETER]})
    robot.spin_until(0.5)
    assert robot.sensor("odometer").value == pytest.approx(100.0)
    robot.close()


def test_world_plugin_section_must_be_a_mapping(tmp_path: Path) -> None:
    world = _world_with(tmp_path, "plugins:\n  odometer: 3\n")
    with pytest.raises(WorldFileError, match="plugins"):
        create_robot({"world": str(world), "sensors": [ODOMETER]})


def test_sensor_model_that_fails_names_the_sensor() -> None:
    def broken(options: Mapping[str, Any], seed: int) -> Any:
        raise KeyError("dock")

    kind = SensorKind(name="flaky", value_type=float, sim=SimSource(model=broken))
    with pytest.raises(PluginError, match="sensor 'flaky': its simulator model failed to start: KeyError"):
        create_robot({"world": "conformance", "sensors": [kind]})


def test_backend_option_sensors_is_checked_and_defaults_to_none() -> None:
    assert sensor_kinds_from_options({"sensors": [ODOMETER]}) == [ODOMETER]
    assert sensor_kinds_from_options({"sensors": {"odometer": ODOMETER}}) == [ODOMETER]
    with pytest.raises(ConfigError, match="SensorKind"):
        sensor_kinds_from_options({"sensors": ["odometer"]})
    assert sensor_kinds_from_options({}) == []  # the session passes the plugins' sensors


def test_clock_robot_carries_plugin_sensors_for_leaf_tests() -> None:
    robot = ClockRobot(start=4.0)
    assert robot.sensor_names() == []
    robot.add_sensor(ODOMETER)
    robot.set_sensor("odometer", 1.25)
    assert robot.sensor("odometer") == SensorReading(4.0, 1.25)
    with pytest.raises(UnknownSensorError):
        robot.sensor("battery")
