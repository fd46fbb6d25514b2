"""Tests of the tick's own cost: py_trees' debug lines formatted only when logged, same effects."""

from __future__ import annotations

from typing import Any

import py_trees
import pytest

from missiontree.engine.context import MissionContext
from missiontree.engine.leaf import Leaf, Status
from missiontree.engine.runner import Runner
from missiontree.testing import ClockRobot, clean_state


@pytest.fixture(autouse=True)
def _clean() -> None:
    clean_state()


class _Twice(Leaf):
    """RUNNING on its first tick, SUCCESS on the next."""

    def initialise(self) -> None:
        self.ticked = False

    def update(self) -> Status:
        if self.ticked:
            return Status.SUCCESS
        self.ticked = True
        return Status.RUNNING


def _debug_lines(node: py_trees.behaviour.Behaviour, monkeypatch: pytest.MonkeyPatch) -> list[str]:
    lines: list[str] = []
    monkeypatch.setattr(node.logger, "debug", lines.append)
    return lines


def test_a_leaf_formats_no_debug_line_unless_py_trees_logs_debug(monkeypatch: pytest.MonkeyPatch) -> None:
    """At py_trees' default level a leaf's tick and stop build no debug line (they were most of its cost)."""
    leaf = _Twice("twice")
    lines = _debug_lines(leaf, monkeypatch)
    leaf.tick_once()
    leaf.tick_once()
    leaf.stop(Status.INVALID)
    assert leaf.status is Status.INVALID and lines == []


def test_at_debug_level_a_leaf_logs_what_py_trees_logs(monkeypatch: pytest.MonkeyPatch) -> None:
    """With py_trees at debug level, a leaf's tick and stop log py_trees' own lines."""
    monkeypatch.setattr(py_trees.logging, "level", py_trees.logging.Level.DEBUG)
    leaf = _Twice("twice")
    lines = _debug_lines(leaf, monkeypatch)
    leaf.tick_once()
    leaf.tick_once()
    assert lines == ["_Twice.tick()", "_Twice.tick()", "_Twice.stop(Status.RUNNING->Status.SUCCESS)"]


def test_an_invalid_status_from_update_is_still_made_invalid() -> None:
    """A leaf whose update returns no status ends INVALID, as in py_trees."""

    class _Bad(Leaf):
        def update(self) -> Any:
            return "done"

    leaf = _Bad("bad")
    leaf.tick_once()
    assert leaf.status is Status.INVALID


def _wide_selector() -> tuple[py_trees.composites.Selector, list[py_trees.behaviour.Behaviour]]:
    children: list[py_trees.behaviour.Behaviour] = [py_trees.behaviours.Failure(f"f{i}") for i in range(20)]
    children.append(py_trees.behaviours.Running("run"))
    children.append(py_trees.behaviours.Success("after"))
    return py_trees.composites.Selector("root", memory=False, children=children), children


def test_watched_children_of_a_wide_composite_format_no_debug_line(monkeypatch: pytest.MonkeyPatch) -> None:
    """In the runner, the stops of a wide Selector's watched children build no debug line by default."""
    root, children = _wide_selector()
    lines = _debug_lines(children[0], monkeypatch)
    runner = Runner(root, MissionContext(robot=ClockRobot()), tick_hz=10, max_duration=0.3,
                    handle_signals=False, profile=False)
    result = runner.run()
    assert result.ticks == 3
    assert lines and not [line for line in lines if ".stop(" in line]  # py_trees' tick still logs its own


def test_a_watched_halt_clears_the_feedback_and_is_logged(monkeypatch: pytest.MonkeyPatch) -> None:
    """A halted watched child loses its feedback message (as py_trees' terminate does) and the log says so."""
    root, children = _wide_selector()
    running = children[20]
    runner = Runner(root, MissionContext(robot=ClockRobot()), tick_hz=10, max_duration=1.0,
                    handle_signals=False, profile=False)
    runner.setup()
    runner.tick()
    running.feedback_message = "busy"
    children[0].__class__.update = lambda self: Status.SUCCESS  # type: ignore[method-assign]
    try:
        runner.tick()  # the first child now succeeds: the running one is halted
    finally:
        del children[0].__class__.update
    assert running.status is Status.INVALID and running.feedback_message == ""
    runner.halt()
