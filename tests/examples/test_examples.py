"""Tests that the programs in examples/ run as their docstrings say, and the plugin walk-through holds."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
EXAMPLES = REPO / "examples"
GUIDE = REPO / "docs" / "plugins.md"  # the plugin guide (it replaced examples/write_a_plugin.md)
MISSIONTREE = Path(sys.executable).parent / "missiontree"


def _run(*args: str | Path, cwd: Path = REPO, timeout: float = 60.0) -> subprocess.CompletedProcess[str]:
    """Run a command with this interpreter's environment; keep its output for the assertions."""
    return subprocess.run([str(a) for a in args], cwd=cwd, capture_output=True, text=True, timeout=timeout,
                          check=False)


def test_every_python_example_is_covered_here() -> None:
    """Each examples/*.py has a test below and a module docstring that says how to run it."""
    tested = {"tick_from_python.py", "write_a_leaf.py"}
    found = {p.name for p in EXAMPLES.glob("*.py")}
    assert found == tested
    for name in found:
        text = (EXAMPLES / name).read_text(encoding="utf-8")
        assert text.startswith('"""') and f"examples/{name}" in text.split('"""')[1]


def test_tick_from_python_runs_the_mission_file_and_the_registry_tree(tmp_path: Path) -> None:
    """The timer-and-blackboard mission succeeds with a run directory, and the hand-ticked tree succeeds."""
    out = tmp_path / "run"
    done = _run(sys.executable, EXAMPLES / "tick_from_python.py", "--out", out)
    assert done.returncode == 0, done.stderr
    assert "timer_and_blackboard.yaml: SUCCESS (stopped by status)" in done.stdout
    assert "blackboard at the end: phase = 'done'" in done.stdout
    assert re.search(r"tick 4 t=0\.3: greet=SUCCESS, pause=SUCCESS, check=SUCCESS, tiny=SUCCESS", done.stdout)
    assert done.stdout.rstrip().endswith("tiny tree: SUCCESS")
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "SUCCESS"
    assert summary["nodes"]["main/report/CheckBlackboard"] == {"SUCCESS": 1, "FAILURE": 0}
    assert (out / "ticks.jsonl").is_file()


def test_write_a_leaf_drives_on_the_simulator_until_an_obstacle(tmp_path: Path) -> None:
    """The custom leaf moves the simulated robot forward and stops it under 0.6 m from an obstacle."""
    out = tmp_path / "run"
    done = _run(sys.executable, EXAMPLES / "write_a_leaf.py", "--out", out)
    assert done.returncode == 0, done.stderr
    stopped = re.search(r"drive: stopped (\d+\.\d+) m before an obstacle", done.stdout)
    assert stopped is not None, done.stdout
    assert 0.3 < float(stopped.group(1)) < 0.6
    moved = re.search(r"robot moved from \((\S+), (\S+)\) to \((\S+), (\S+)\)", done.stdout)
    assert moved is not None and float(moved.group(3)) - float(moved.group(1)) > 1.0  # it drove east
    lines = [json.loads(line) for line in (out / "ticks.jsonl").read_text().splitlines()]
    assert [r["event"] for r in lines if r["event"] in ("drive_started", "obstacle_reached")] == [
        "drive_started", "obstacle_reached"]
    bb = [r["bb"]["front_distance"] for r in lines if "front_distance" in r.get("bb", {})]
    assert bb[0] > bb[-1]  # the Output port published the front distance as it shrank


def test_plugin_walkthrough_names_only_files_that_exist() -> None:
    """Every repository path the plugin guide (docs/plugins.md) mentions exists."""
    text = GUIDE.read_text(encoding="utf-8")
    paths = set(re.findall(r"`((?:plugins|src|examples|tests)/[\w./-]+)`", text))
    paths |= {(GUIDE.parent / link).resolve().relative_to(REPO).as_posix()
              for link in re.findall(r"\]\(([^)#]+)\)", text)}
    assert "plugins/missiontree-battery/src/missiontree_battery/plugin.py" in paths
    assert "plugins/missiontree-battery/missions/patrol_and_charge.yaml" in paths
    missing = sorted(p for p in paths if not (REPO / p).exists())
    assert missing == []


def test_plugin_walkthrough_mission_runs_with_the_plugin_and_not_without(tmp_path: Path) -> None:
    """The walk-through's CountDown mission succeeds with the plugin and is refused with autoload off."""
    pytest.importorskip("missiontree_example", reason="the example plugin is not installed (make setup)")
    text = GUIDE.read_text(encoding="utf-8")
    [yaml_block] = [b for b in re.findall(r"```yaml\n(.*?)```", text, flags=re.S) if "CountDown" in b]
    mission = tmp_path / "countdown.yaml"
    mission.write_text(yaml_block, encoding="utf-8")
    done = _run(MISSIONTREE, "run", mission, "--out", tmp_path / "run")
    assert done.returncode == 0, done.stdout + done.stderr
    assert "countdown: SUCCESS after 4 ticks" in done.stdout
    refused = _run(MISSIONTREE, "validate", "--no-plugins", mission)
    assert refused.returncode == 2
    assert "expected a known node type, found 'CountDown'" in refused.stdout + refused.stderr
