"""Hot reload: a changed mission replaces the running tree within a second of robot time, blackboard kept."""

from __future__ import annotations

import io
from pathlib import Path
from typing import Any

import py_trees
import pytest

from missiontree.engine.build import build_tree
from missiontree.engine.context import MissionContext
from missiontree.engine.loader import load_mission
from missiontree.engine.reload import TreeWatcher
from missiontree.engine.runner import Runner
from missiontree.testing import ClockRobot, clean_state, fresh_plugins

FIRST = """\
blackboard: {count: 0}
root:
  Sequence:
    name: main
    memory: true
    children:
      - Script: {code: "count = count + 1"}
      - Wait: {seconds: 100}
"""
SECOND = FIRST.replace("count + 1", "count + 10").replace("name: main", "name: main_v2")
BROKEN = FIRST.replace("Wait:", "Wiat:")


@pytest.fixture(autouse=True)
def _clean() -> None:
    clean_state()


def _run(tmp_path: Path, edit: str, at: float = 2.0) -> tuple[Runner, list[dict[str, Any]], str, float]:
    """Run FIRST for 6 s of robot time, writing ``edit`` over the file at robot time ``at``."""
    import json

    mission = tmp_path / "m.yaml"
    mission.write_text(FIRST)
    registry = fresh_plugins().nodes
    spec = load_mission(mission, registry)
    printed = io.StringIO()
    watcher = TreeWatcher(spec, lambda: load_mission(mission, registry), lambda s: build_tree(s, registry),
                          out=printed)
    edited: list[float] = []

    def on_tick(runner: Runner) -> None:
        if not edited and runner.robot.now() >= at:
            mission.write_text(edit)
            edited.append(runner.robot.now())
        watcher(runner)

    stream = io.StringIO()
    runner = Runner(build_tree(spec, registry), MissionContext(robot=ClockRobot()), tick_hz=10,
                    max_duration=6.0, log_stream=stream, blackboard=spec.blackboard, handle_signals=False,
                    on_tick=on_tick)
    runner.run()
    lines = [json.loads(line) for line in stream.getvalue().splitlines()]
    return runner, lines, printed.getvalue(), edited[0]


def test_a_changed_mission_is_reloaded_within_a_second_keeping_the_blackboard(tmp_path: Path) -> None:
    """The new tree runs its script on the kept count (1 + 10), a halt and a `reloaded` event in between."""
    runner, lines, printed, edited = _run(tmp_path, SECOND)
    (reloaded,) = [line for line in lines if line["event"] == "reloaded"]
    assert 0.0 <= reloaded["t"] - edited <= 1.0
    halts = [line for line in lines if line["event"] == "halted"]
    assert halts and halts[0]["t"] == reloaded["t"]
    assert py_trees.blackboard.Blackboard.get("/count") == 11
    assert runner.root.name == "main_v2"
    assert "reloaded" in printed
    ticked = {change["node"] for line in lines if line["event"] == "tick" and line["t"] > reloaded["t"]
              for change in line.get("changed", [])}
    assert "main_v2" in ticked and "main" not in ticked


def test_a_broken_edit_keeps_the_old_tree_running(tmp_path: Path) -> None:
    """A change that fails its check is printed and logged; the old tree is not halted, nothing reruns."""
    runner, lines, printed, _ = _run(tmp_path, BROKEN)
    (refused,) = [line for line in lines if line["event"] == "reload_refused"]
    assert refused["count"] == 1 and "Wiat" in refused["problems"][0]
    assert "Wiat" in printed and "not reloaded" in printed
    assert [line["event"] for line in lines].count("halted") == 1  # only the run's own final halt
    assert py_trees.blackboard.Blackboard.get("/count") == 1
    assert runner.root.name == "main"


def test_an_unchanged_write_is_not_a_reload(tmp_path: Path) -> None:
    """Writing the same content again (a save without edits) reloads nothing."""
    _, lines, _, _ = _run(tmp_path, FIRST)
    assert not [line for line in lines if line["event"] in ("reloaded", "reload_refused")]


class _Broken(py_trees.behaviour.Behaviour):
    """A plain py_trees behaviour (not a Leaf) whose update raises."""

    def update(self) -> py_trees.common.Status:
        raise ZeroDivisionError("in a reloaded tree")


def test_a_reloaded_trees_non_leaf_error_is_reported_as_the_first_trees(tmp_path: Path) -> None:
    """After a reload, a non-Leaf error event has its path, file:line and frames (Runner.replace_tree)."""
    import json

    mission = tmp_path / "m.yaml"
    mission.write_text(FIRST)
    registry = fresh_plugins().nodes
    spec = load_mission(mission, registry)

    def build(new: Any) -> Any:
        if new is spec:
            return build_tree(new, registry)
        return py_trees.composites.Selector("top", memory=False, children=[_Broken("plain")])

    watcher = TreeWatcher(spec, lambda: load_mission(mission, registry), build, out=io.StringIO())

    def on_tick(runner: Runner) -> None:
        if runner.robot.now() >= 1.0 and mission.read_text() == FIRST:
            mission.write_text(SECOND)
        watcher(runner)

    stream = io.StringIO()
    runner = Runner(build(spec), MissionContext(robot=ClockRobot()), tick_hz=10, max_duration=4.0,
                    log_stream=stream, blackboard=spec.blackboard, handle_signals=False, on_tick=on_tick)
    runner.run()
    lines = [json.loads(line) for line in stream.getvalue().splitlines()]
    assert any(line["event"] == "reloaded" for line in lines)
    error = next(line for line in lines if line["event"] == "error")
    assert error["node"] == "top/plain"
    assert error["where"].startswith("tests/engine/test_reload.py:")
    assert error["traceback"][-1].endswith(" in update")
