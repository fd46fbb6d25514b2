"""The plugin guide's last section as a test: copy the battery plugin, rename it, add a sensor.

Then run a mission that reacts to the new sensor in the simulator, through the real CLI.

The copy is "installed" as pip would leave an editable install (a ``.dist-info`` with its entry
point, the source folder on the path), in a temporary folder, so the shared environment is untouched.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
BATTERY = REPO / "plugins" / "missiontree-battery"
MISSIONTREE = Path(sys.executable).parent / "missiontree"

THERMO = '''\
"""A thermometer: sensor_msgs/Temperature on /temperature; simulated as a room warming up."""

from __future__ import annotations

from missiontree.robot.sensors import Ros2Source, SensorKind, SimSource, SimState


class Warming:
    def __init__(self, options, seed):
        self.start = float(options.get("start", 20.0))
        self.rise = float(options.get("rise_per_s", 0.1))

    def sample(self, state: SimState) -> float:
        return self.start + self.rise * state.t


def temperature_from_msg(msg) -> float:
    return float(msg.temperature)


THERMO = SensorKind(name="thermo", value_type=float, unit="degC", log_period=1.0,
                    ros2=Ros2Source(topic="/temperature", message="sensor_msgs.msg:Temperature",
                                    from_msg=temperature_from_msg),
                    sim=SimSource(model=Warming, rate=2.0))
'''

PLUGIN = '''\
from missiontree.plugins.hookspecs import hookimpl
from missiontree_mything.thermo import THERMO


@hookimpl
def missiontree_register_sensors(sensors):
    sensors[THERMO.name] = THERMO
'''

MISSION = """\
version: 1
description: Wait until the room is warm, then check it is.
run: {backend: sim, world: world.yaml, tick_hz: 10, max_duration: 60}
root:
  Sequence:
    memory: true
    children:
      - WaitForSensor: {name: warm_up, sensor: thermo, op: ">=", value: 25.0}
      - SensorCondition: {name: warm, sensor: thermo, op: ">", threshold: 24.0}
"""


def test_a_copy_of_the_battery_plugin_with_its_own_sensor_runs_a_mission(tmp_path: Path) -> None:
    # 1. copy; 2. rename the distribution, the package and the entry point
    copy = tmp_path / "missiontree-mything"
    shutil.copytree(BATTERY, copy, ignore=shutil.ignore_patterns("*.egg-info", "__pycache__"))
    (copy / "src" / "missiontree_battery").rename(copy / "src" / "missiontree_mything")
    pyproject = (copy / "pyproject.toml").read_text(encoding="utf-8")
    pyproject = pyproject.replace('name = "missiontree-battery"', 'name = "missiontree-mything"')
    pyproject = pyproject.replace('battery = "missiontree_battery.plugin"',
                                  'mything = "missiontree_mything.plugin"')
    (copy / "pyproject.toml").write_text(pyproject, encoding="utf-8")
    for source in (copy / "src").rglob("*.py"):
        text = source.read_text(encoding="utf-8").replace("missiontree_battery", "missiontree_mything")
        source.write_text(text, encoding="utf-8")
    # 3. its own sensor, registered instead of the copied (clashing) names
    (copy / "src" / "missiontree_mything" / "thermo.py").write_text(THERMO, encoding="utf-8")
    (copy / "src" / "missiontree_mything" / "plugin.py").write_text(PLUGIN, encoding="utf-8")
    # 4. "pip install -e": a dist-info with the entry point, the source on the path
    site = tmp_path / "site"
    info = site / "missiontree_mything-0.1.0.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: missiontree-mything\nVersion: 0.1.0\n",
                                   encoding="utf-8")
    (info / "entry_points.txt").write_text("[missiontree]\nmything = missiontree_mything.plugin\n",
                                           encoding="utf-8")
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(site), str(copy / "src"), env.get("PYTHONPATH", "")])
    env.pop("MISSIONTREE_DISABLE_PLUGIN_AUTOLOAD", None)
    listed = subprocess.run([str(MISSIONTREE), "plugins"], env=env, cwd=REPO, capture_output=True, text=True,
                            timeout=120, check=False)
    assert "mything  (missiontree_mything.plugin, missiontree-mything 0.1.0)" in listed.stdout, listed.stderr
    assert "    sensors: thermo" in listed.stdout and "BROKEN" not in listed.stdout
    # 5. a mission that reacts to it, in a world whose plugins section configures the sensor
    world = (REPO / "config" / "worlds" / "conformance.yaml").read_text(encoding="utf-8")
    (tmp_path / "world.yaml").write_text(world + "plugins:\n  thermo: {start: 20.0, rise_per_s: 1.0}\n",
                                         encoding="utf-8")
    (tmp_path / "warm.yaml").write_text(MISSION, encoding="utf-8")
    command = [str(MISSIONTREE), "run", str(tmp_path / "warm.yaml"), "--out", str(tmp_path / "run")]
    done = subprocess.run(command, env=env, cwd=REPO, capture_output=True, text=True, timeout=300,
                          check=False)
    assert done.returncode == 0, done.stdout + done.stderr
    assert "warm: SUCCESS" in done.stdout
    log = (tmp_path / "run" / "ticks.jsonl").read_text(encoding="utf-8")
    assert '"event":"mission_finished"' in log and '"t":5.0' in log  # 20 + 1.0 * t reaches 25 at t = 5
