"""Sensors from plugins: the hook, the generic leaves, a mission reacting to a plugin sensor, the log."""

from __future__ import annotations

import importlib.metadata
import json
import sys
import types
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import pytest

from missiontree.engine.context import MissionContext
from missiontree.engine.leaf import Status
from missiontree.engine.nodes.sensors import SensorCondition, WaitForSensor
from missiontree.errors import ConfigError
from missiontree.plugins import manager
from missiontree.plugins.hookspecs import hookimpl
from missiontree.plugins.manager import load_plugins
from missiontree.robot.sensors import SensorKind, SimSource, SimState
from missiontree.testing import ClockRobot, clean_state


@pytest.fixture(autouse=True)
def _clean() -> None:
    clean_state()


class Clock:
    """A test sensor model: the simulated time, as a number (rises steadily)."""

    def __init__(self, options: Mapping[str, Any], seed: int) -> None:
        self.scale = float(options.get("scale", 1.0))

    def sample(self, state: SimState) -> float:
        return self.scale * state.t


TICKER = SensorKind(name="ticker", value_type=float, sim=SimSource(model=Clock, rate=5.0), log_period=1.0)


def _module(name: str, **hooks: Callable[..., Any]) -> types.ModuleType:
    module = types.ModuleType(name)
    for hook_name, function in hooks.items():
        setattr(module, hook_name, hookimpl(function))
    return module


@pytest.fixture
def entry_points(monkeypatch: pytest.MonkeyPatch) -> Callable[..., None]:
    """Install fake modules as the only ``missiontree`` entry points."""

    def install(**modules: types.ModuleType) -> None:
        eps = []
        for ep_name, module in modules.items():
            monkeypatch.setitem(sys.modules, module.__name__, module)
            eps.append(importlib.metadata.EntryPoint(name=ep_name, value=module.__name__,
                                                     group="missiontree"))
        monkeypatch.setattr(manager, "discover_entry_points", lambda: eps)

    return install


def _sensor_plugin(name: str, *kinds: Any) -> types.ModuleType:
    def missiontree_register_sensors(sensors: dict[str, Any]) -> None:
        for kind in kinds:
            sensors[getattr(kind, "name", "bogus")] = kind

    return _module(name, missiontree_register_sensors=missiontree_register_sensors)


def test_plugin_registers_a_sensor_under_its_name(entry_points: Callable) -> None:
    entry_points(tick=_sensor_plugin("mt_test_ticker", TICKER))
    plugins = load_plugins(autoload=True)
    assert plugins.sensors["ticker"] is TICKER and plugins.provided_by("sensors", "ticker") == "tick"
    assert "ticker" not in load_plugins(autoload=False).sensors


def test_sensor_that_is_not_a_sensor_kind_leaves_the_plugin_out(entry_points: Callable) -> None:
    entry_points(bad=_sensor_plugin("mt_test_bad_sensor", {"name": "ticker"}))
    plugins = load_plugins(autoload=True)
    assert plugins.sensors == {} or "bogus" not in plugins.sensors
    assert "registered sensor 'bogus' as dict" in plugins.broken[0].error


def test_same_sensor_from_two_plugins_names_both(entry_points: Callable) -> None:
    entry_points(first=_sensor_plugin("mt_test_s1", TICKER), second=_sensor_plugin("mt_test_s2", TICKER))
    plugins = load_plugins(autoload=True)
    assert plugins.provided_by("sensors", "ticker") == "first"
    assert "sensor 'ticker' registered twice: by 'first' and by 'second'" in plugins.broken[0].error


# -- the generic leaves ----------------------------------------------------------------------------


class Events:
    def __init__(self) -> None:
        self.lines: list[tuple[str, dict[str, Any]]] = []

    def emit(self, event: str, /, **fields: Any) -> None:
        self.lines.append((event, fields))


def _set_up(leaf: Any, robot: ClockRobot, events: Events | None = None) -> Any:
    leaf.setup(context=MissionContext(robot=robot, events=events or Events()))
    return leaf


def _robot() -> ClockRobot:
    robot = ClockRobot(start=10.0)
    robot.add_sensor(TICKER)
    return robot


def test_sensor_condition_is_a_threshold_with_a_staleness_limit() -> None:
    robot, events = _robot(), Events()
    low = _set_up(SensorCondition("low", SensorCondition.Params(sensor="ticker", threshold=5.0, max_age=2.0)),
                  robot, events)
    assert low.update() == Status.FAILURE and "no reading yet" in low.failure_reason
    robot.set_sensor("ticker", 4.0)
    assert low.update() == Status.SUCCESS
    robot.set_sensor("ticker", 6.0)
    assert low.update() == Status.FAILURE and low.failure_reason == "not ticker 6 < 5"
    robot.spin_until(13.0)
    assert low.update() == Status.FAILURE and "3.0 s old (max_age 2 s)" in low.failure_reason
    lenient = SensorCondition.Params(sensor="ticker", threshold=5.0, max_age=2.0, stale="succeed")
    assert _set_up(SensorCondition("x", lenient), robot).update() == Status.SUCCESS
    high = SensorCondition.Params(sensor="ticker", op=">=", threshold=6.0, max_age=10.0)
    assert _set_up(SensorCondition("high", high), robot).update() == Status.SUCCESS
    # one tick-log sample per log_period of stamps: both readings were stamped at t = 10
    assert [(e, f["value"], f["stamp"]) for e, f in events.lines] == [("sensor", 4.0, 10.0)]


def test_wait_for_sensor_waits_for_a_fresh_value() -> None:
    robot = _robot()
    wait = _set_up(WaitForSensor("w", WaitForSensor.Params(sensor="ticker", value=3.0, max_age=1.0,
                                                            stale_timeout=5.0)), robot)
    wait.initialise()
    assert wait.update() == Status.RUNNING and "no reading yet" in wait.feedback_message
    robot.set_sensor("ticker", 1.0)
    assert wait.update() == Status.RUNNING and "waiting for >= 3" in wait.feedback_message
    robot.set_sensor("ticker", 3.5)
    assert wait.update() == Status.SUCCESS
    wait.initialise()
    robot.spin_until(12.0)  # the reading is 2 s old: stale
    assert wait.update() == Status.RUNNING and "stale" in wait.feedback_message
    robot.spin_until(17.5)
    assert wait.update() == Status.FAILURE and "no fresh reading for 5 s" in wait.failure_reason


def test_sensor_leaves_refuse_unknown_sensors_and_fields_at_setup() -> None:
    robot = _robot()
    with pytest.raises(ConfigError, match="no sensor 'battery'; its plugin sensors: ticker"):
        _set_up(SensorCondition("c", SensorCondition.Params(sensor="battery", threshold=1.0)), robot)
    with pytest.raises(ConfigError, match="no numeric field 'percentage'"):
        params = WaitForSensor.Params(sensor="ticker", field="percentage", value=1.0)
        _set_up(WaitForSensor("w", params), robot)


# -- a mission that reacts to a plugin sensor, in the simulator --------------------------------------

MISSION = """\
version: 1
description: Wait until the ticker sensor passes 2, then check it is above 1.5.
run: {backend: sim, world: conformance, tick_hz: 10, max_duration: 20}
root:
  Sequence:
    memory: true
    children:
      - WaitForSensor: {name: wait, sensor: ticker, value: 2.0}
      - SensorCondition: {name: check, sensor: ticker, op: ">", threshold: 1.5}
"""


def test_mission_reacts_to_a_plugin_sensor_and_the_log_and_viewer_show_it(
        entry_points: Callable, tmp_path: Path) -> None:
    from missiontree.runlog.html import page_data
    from missiontree.runlog.replay import open_run
    from missiontree.session import MissionRequest, run_mission

    entry_points(tick=_sensor_plugin("mt_test_ticker_mission", TICKER))
    mission = tmp_path / "ticker.yaml"
    mission.write_text(MISSION, encoding="utf-8")
    result = run_mission(MissionRequest(mission=mission, out=tmp_path / "run", quiet=True,
                                        plugins=load_plugins(autoload=True)))
    assert result.status.name == "SUCCESS"
    log = (tmp_path / "run" / "ticks.jsonl").read_text(encoding="utf-8")
    lines = [json.loads(x) for x in log.splitlines()]
    finished = [x for x in lines if x.get("event") == "mission_finished"]
    assert 2.0 <= finished[0]["t"] <= 2.5  # the ticker passes 2 at t = 2 (sampled at 5 Hz)
    samples = [x for x in lines if x.get("event") == "sensor"]
    assert samples and samples[0]["sensor"] == "ticker" and "value" in samples[0] and "stamp" in samples[0]
    assert [s["stamp"] for s in samples] == sorted(s["stamp"] for s in samples)
    data = page_data(open_run(tmp_path / "run"), tmp_path / "run")
    kinds = {data["s"][e[1]] for e in data["events"]}
    assert "sensor" in kinds


class NotANumber:
    """A test sensor model that reads NaN (a broken sensor driver)."""

    def __init__(self, options: Mapping[str, Any], seed: int) -> None:
        pass

    def sample(self, state: SimState) -> float:
        return float("nan")


BROKEN = SensorKind(name="broken", value_type=float, sim=SimSource(model=NotANumber, rate=5.0))

INVERTED = """\
version: 1
description: Succeed when the broken sensor is NOT below 1 (a NaN reading is an error, not "not below").
run: {backend: sim, world: conformance, tick_hz: 10, max_duration: 5}
root:
  Sequence:
    memory: true
    children:
      - Wait: {seconds: 0.5}
      - DECORATOR:
          child:
            SensorCondition: {name: low, sensor: broken, threshold: 1.0}
"""


@pytest.mark.parametrize("decorator", ["Inverter", "ForceSuccess"])
def test_a_nan_reading_under_an_inverter_is_a_fault_not_success(
        decorator: str, entry_points: Callable, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A non-finite plugin reading under Inverter/ForceSuccess ends the run FAILURE with a fault, exit 1."""
    from missiontree.cli.main import main

    entry_points(broken=_sensor_plugin("mt_test_broken_sensor", BROKEN))
    mission = tmp_path / "inverted.yaml"
    mission.write_text(INVERTED.replace("DECORATOR", decorator), encoding="utf-8")
    assert main(["run", str(mission), "--out", str(tmp_path / "run"), "--quiet"]) == 1
    summary = json.loads((tmp_path / "run" / "summary.json").read_text(encoding="utf-8"))
    assert summary["status"] == "FAILURE"
    assert summary["fault"]["node"].endswith("low") and "non-finite" in summary["fault"]["error"]
    capsys.readouterr()
    assert main(["log", "summarize", str(tmp_path / "run")]) == 0
    assert "fault: " in capsys.readouterr().out


def test_a_stale_reading_under_an_inverter_is_not_success() -> None:
    """A sensor that went quiet fails its condition with a fault, so Inverter(condition) stays FAILURE."""
    import py_trees

    from missiontree.engine.faults import FaultKeepingInverter

    robot = _robot()
    robot.set_sensor("ticker", 4.0)
    condition = SensorCondition("low", SensorCondition.Params(sensor="ticker", threshold=5.0, max_age=2.0))
    root = FaultKeepingInverter("not_low", condition)
    py_trees.trees.setup(root, context=MissionContext(robot=robot, events=Events()))  # type: ignore[arg-type]
    root.tick_once()
    assert root.status == Status.FAILURE  # 4 < 5 holds: inverted
    robot.spin_until(13.0)  # the reading is 3 s old: the sensor is lost
    root.tick_once()
    assert root.status == Status.FAILURE and "3.0 s old" in root.feedback_message
