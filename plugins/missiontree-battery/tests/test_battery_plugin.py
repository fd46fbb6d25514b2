"""The battery plugin: its sensor's conversions and model, IsBatteryLow, colour_blob, and its mission.

These run in ``make test`` with the plugin installed (``pip install -e plugins/missiontree-battery``).
A plugin made from this one keeps the same shape: pure conversion tests without ROS, a model test
on the simulator's state, a leaf test on :class:`missiontree.testing.ClockRobot`, the shipped
conformance suite for its provider, and its mission run end to end in the simulator.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest
from missiontree_battery.battery import (
    BATTERY,
    STATUS_CHARGING,
    STATUS_DISCHARGING,
    BatteryModel,
    BatteryReading,
    battery_from_msg,
)
from missiontree_battery.blob import ColourBlobDetector, create_colour_blob
from missiontree_battery.nodes import IsBatteryLow

from missiontree.engine.leaf import Status
from missiontree.errors import ConfigError, ModelConfigError
from missiontree.robot.sensors import SimState
from missiontree.testing import ClockRobot, clean_state, fresh_plugins
from missiontree.testing_models import DetectorConformance

PLUGIN = Path(__file__).resolve().parents[1]
MISSION = PLUGIN / "missions" / "patrol_and_charge.yaml"


@pytest.fixture(autouse=True)
def _clean() -> None:
    clean_state()


def _msg(percentage: float, voltage: float = 15.0, current: float = -0.5,
         status: int = STATUS_DISCHARGING) -> Any:
    return SimpleNamespace(percentage=percentage, voltage=voltage, current=current,
                           power_supply_status=status)


def _state(t: float, dt: float, x: float = 5.0, y: float = 0.0, v: float = 0.0,
           distance: float = 0.0) -> SimState:
    return SimState(t=t, dt=dt, pose=(x, y, 0.0), v=v, w=0.0, distance=distance, odometer=distance)


# -- the sensor ------------------------------------------------------------------------------------


def test_battery_state_converts_as_the_turtlebot_publishes_it() -> None:
    """Percentage 0-1 kept, 0-100 scaled, CHARGING read as charging, NaN stays NaN."""
    reading = battery_from_msg(_msg(0.42, 15.1, -0.8))
    assert reading == BatteryReading(0.42, 15.1, -0.8, False)
    assert battery_from_msg(_msg(87.0)).percentage == pytest.approx(0.87)
    assert battery_from_msg(_msg(0.5, status=STATUS_CHARGING)).charging is True
    assert math.isnan(battery_from_msg(_msg(math.nan)).percentage)


def test_battery_conversion_round_trips_through_the_ros_message() -> None:
    """to_msg then from_msg gives the reading back, stamped (sim-ros publishes with to_msg)."""
    pytest.importorskip("sensor_msgs.msg", reason="ROS 2 message packages not installed")
    reading = BatteryReading(0.73, 15.5, -0.6, False)
    source = BATTERY.ros2
    assert source is not None and source.to_msg is not None
    msg = source.to_msg(reading, 12.25)
    assert type(msg).__name__ == "BatteryState" and source.message_type() is type(msg)
    assert msg.header.stamp.sec == 12 and msg.header.stamp.nanosec == 250_000_000
    assert source.from_msg(msg) == reading
    assert source.topic == "/battery_state"


def test_simulated_battery_drains_with_time_and_distance_and_charges_on_the_dock() -> None:
    """Idle drain, motion drain and dock charge follow the world's numbers; charging only at the dock."""
    model = BatteryModel({"start": 0.5, "drain_per_s": 0.001, "drain_per_m": 0.01, "charge_per_s": 0.05,
                          "dock": {"x": 0.0, "y": 0.0, "radius": 0.3}})
    assert model.sample(_state(10.0, 10.0)).percentage == pytest.approx(0.49)          # 10 s idle
    assert model.sample(_state(20.0, 10.0, v=0.3, distance=3.0)).percentage == pytest.approx(0.45)
    on_dock = model.sample(_state(22.0, 2.0, x=0.1, y=0.1))
    assert on_dock.charging and on_dock.percentage == pytest.approx(0.55) and on_dock.current > 0
    driving_past = model.sample(_state(23.0, 1.0, x=0.1, y=0.1, v=0.3, distance=0.3))
    assert not driving_past.charging and driving_past.percentage < on_dock.percentage
    for i in range(100):
        full = model.sample(_state(30.0 + i, 1.0, x=0.0, y=0.0))
    assert full.percentage == 1.0 and full.voltage == pytest.approx(16.8)


def test_world_section_is_checked() -> None:
    """An unknown key or a bad number in the world's plugins.battery is a ConfigError naming it."""
    with pytest.raises(ConfigError, match=r"plugins\.battery: .*dok.*known keys: start"):
        BatteryModel({"dok": {"x": 0, "y": 0}})
    with pytest.raises(ConfigError, match="start"):
        BatteryModel({"start": 1.5})


def test_sim_robot_reads_the_battery_and_a_silenced_one_goes_stale(tmp_path: Path) -> None:
    """The simulator produces the reading at its rate; silenced, its stamp stops (no exception)."""
    from missiontree.backends.sim import create_robot

    world = PLUGIN / "worlds" / "corridor_dock.yaml"
    robot = create_robot({"world": str(world), "sensors": [BATTERY]})
    robot.spin_until(3.0)
    reading = robot.sensor("battery")
    assert reading is not None and reading.stamp == pytest.approx(3.0)
    assert reading.value.percentage == pytest.approx(0.5 - 3 * 0.0005, abs=1e-6)
    robot.silence("battery")
    robot.spin_until(6.0)
    assert robot.sensor("battery").stamp == pytest.approx(3.0)
    robot.silence("battery", quiet=False)
    robot.spin_until(7.0)
    assert robot.sensor("battery").stamp == pytest.approx(7.0)
    robot.close()


# -- IsBatteryLow ----------------------------------------------------------------------------------


def _leaf(robot: ClockRobot, **params: Any) -> IsBatteryLow:
    from missiontree.engine.context import MissionContext

    leaf = IsBatteryLow("low", IsBatteryLow.Params(**params))
    leaf.setup(context=MissionContext(robot=robot))
    return leaf


def test_is_battery_low_compares_percentage_or_voltage_and_fails_on_stale() -> None:
    """Low at or below min_battery (percentage, or volts); stale or missing readings fail unless asked."""
    robot = ClockRobot(start=100.0)
    robot.add_sensor(BATTERY)
    leaf = _leaf(robot, min_battery=0.25)
    assert leaf.update() == Status.FAILURE and "no battery reading" in leaf.failure_reason
    robot.set_sensor("battery", BatteryReading(0.2, 13.0, -0.5, False))
    assert leaf.update() == Status.SUCCESS
    robot.set_sensor("battery", BatteryReading(0.6, 15.0, -0.5, False))
    assert leaf.update() == Status.FAILURE
    assert _leaf(robot, min_battery=15.5, is_voltage=True).update() == Status.SUCCESS
    robot.spin_until(110.0)  # the reading is now 10 s old
    assert leaf.update() == Status.FAILURE and "10.0 s old" in leaf.failure_reason
    assert _leaf(robot, stale_is_low=True).update() == Status.SUCCESS
    robot.set_sensor("battery", BatteryReading(math.nan, 15.0, -0.5, False))
    assert leaf.update() == Status.FAILURE and "does not report its percentage" in leaf.failure_reason


def test_is_battery_low_on_a_robot_without_the_sensor_names_the_problem() -> None:
    """Setting the leaf up on a robot without the sensor is a clear error."""
    from missiontree.robot.sensors import UnknownSensorError

    with pytest.raises(UnknownSensorError, match="no sensor 'battery'"):
        _leaf(ClockRobot())


# -- colour_blob -----------------------------------------------------------------------------------


def test_colour_blob_boxes_the_named_colour_only() -> None:
    """One box round the red region, none round the blue; an alias and a label work."""
    image = np.full((120, 160, 3), 200, np.uint8)
    image[20:60, 30:80] = (220, 30, 30)      # red
    image[70:110, 100:150] = (30, 40, 220)   # blue
    found = create_colour_blob({"colour": "red", "min_area": 50}).detect(image)
    assert [d.label for d in found] == ["red blob"]
    assert found[0].box == (30.0, 20.0, 80.0, 60.0) and found[0].score == pytest.approx(1.0)
    assert create_colour_blob({"colour": "Navy", "label": "bin"}).detect(image)[0].label == "bin"


def test_colour_blob_options_are_checked_like_the_builtins() -> None:
    """Unknown colour, misspelt option, missing colour: ModelConfigError naming the provider."""
    with pytest.raises(ModelConfigError, match=r"'colour_blob'.*unknown colour 'mauve'"):
        create_colour_blob({"colour": "mauve"})
    with pytest.raises(ModelConfigError, match=r"'colour_blob'.*known options: colour"):
        create_colour_blob({"colour": "red", "min_aera": 3})
    with pytest.raises(ModelConfigError, match="colour"):
        create_colour_blob({})


def test_colour_blob_is_chosen_from_a_models_config_by_name(tmp_path: Path) -> None:
    """A models config naming provider colour_blob builds it from the installed plugin."""
    from missiontree.session.models import build_models

    config = tmp_path / "models.yaml"
    config.write_text("roles:\n  detector:\n    provider: colour_blob\n    colour: green\n", encoding="utf-8")
    models = build_models(str(config), providers=fresh_plugins(autoload=True).providers, seed=0)
    assert isinstance(models["detector"], ColourBlobDetector) and models["detector"].colour == "green"


class TestColourBlobConformance(DetectorConformance):
    """The shipped detector conformance suite, run on this plugin's provider."""

    @pytest.fixture
    def detector(self) -> ColourBlobDetector:
        """The provider as a models config would build it."""
        return create_colour_blob({"colour": "red", "min_area": 20})


# -- the mission -----------------------------------------------------------------------------------


def _events(run_dir: Path) -> list[dict[str, Any]]:
    return [json.loads(line) for line in (run_dir / "ticks.jsonl").read_text(encoding="utf-8").splitlines()]


def check_patrol_and_charge(run_dir: Path, laps: int = 2) -> None:
    """The run patrolled, broke off on a low battery, charged on the dock and resumed the same waypoint."""
    events = _events(run_dir)
    finished = [e for e in events if e.get("event") == "mission_finished"]
    assert finished and finished[-1]["status"] == "SUCCESS", finished
    assert sum(e.get("event") == "lap_done" for e in events) == laps
    preempted = [e for e in events if e.get("event") == "patrol_preempted"]
    assert preempted, "the battery never got low enough to break off the patrol"
    docked = [e for e in events if e.get("event") == "goal_result" and e.get("node") == "go_to_dock"]
    assert docked and docked[0]["status"] == "succeeded"
    samples = [e for e in events if e.get("event") == "sensor" and e.get("sensor") == "battery"]
    after = [s["percentage"] for s in samples if s["t"] >= docked[0]["t"]]
    assert after and max(after) > min(after) + 0.3, f"no charging seen on the dock: {after}"
    resumed = [e for e in events if e.get("event") == "goal_sent" and e.get("node") == "patrol"
               and e["t"] > docked[0]["t"]]
    assert resumed and resumed[0]["waypoint"] == preempted[0]["waypoint"], \
        "the patrol did not resume where it stopped"


def test_patrol_and_charge_in_the_simulator(tmp_path: Path) -> None:
    """The shipped mission ends SUCCESS after its laps, charging once on the way."""
    from missiontree.session import MissionRequest, run_mission

    result = run_mission(MissionRequest(mission=MISSION, out=tmp_path / "run", quiet=True,
                                        plugins=fresh_plugins(autoload=True)))
    assert result.status.name == "SUCCESS"
    check_patrol_and_charge(tmp_path / "run")
