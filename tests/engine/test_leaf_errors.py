"""An exception in a (plugin's) leaf names its file and line in the reason, the tick log and the summary."""

from __future__ import annotations

import inspect
import json

import py_trees

from missiontree.engine.context import MissionContext
from missiontree.engine.faults import MAX_MESSAGE, error_site, shown_file
from missiontree.engine.leaf import Leaf, Status
from missiontree.testing import ClockRobot, capture_tick_log, clean_state


class ParsesReply(Leaf):
    """Parses a reply that is not JSON: the error is raised inside the json module."""

    def update(self) -> Status:
        json.loads("{not json")  # the line the reason names
        return Status.SUCCESS


LINE = next(n for n, text in enumerate(inspect.getsource(ParsesReply).splitlines(), 0)
            if "json.loads" in text) + inspect.getsourcelines(ParsesReply)[1]


def test_the_reason_names_the_leafs_own_file_and_line() -> None:
    """The error passed through the leaf's update(): that line is named, not json's internals."""
    clean_state()
    root = py_trees.composites.Sequence("main", memory=True, children=[ParsesReply("parse")])
    result, lines = capture_tick_log(root, MissionContext(robot=ClockRobot()))
    where = f"{shown_file(__file__)}:{LINE}"
    assert result.status is Status.FAILURE
    assert result.summary["fault"]["node"] == "main/parse"
    assert f"(at {where} in update)" in result.summary["fault"]["error"]
    (event,) = [line for line in lines if line["event"] == "error"]
    assert event["where"] == where and event["function"] == "update"
    assert "json" in event["traceback"][-1]  # the innermost frame: where json raised it
    assert any(frame.startswith(where) for frame in event["traceback"])


def test_a_message_is_one_line_and_capped() -> None:
    """A raiser's text (a model's reply, a peer's) is flattened to one line and cut, never echoed whole."""
    try:
        raise ValueError("line one\nline two\x1b[2J" + "x" * 5000)
    except ValueError as error:
        site = error_site(error)
    message = site.reason.split(" (at ")[0]
    assert "\n" not in site.reason
    assert len(message) <= len("ValueError: ") + MAX_MESSAGE
    assert site.where.endswith(f":{inspect.currentframe().f_lineno - 6}")  # type: ignore[union-attr]
