"""Tests of the Leaf base class: exceptions become FAILURE, ports bind blackboard keys."""

from __future__ import annotations

from typing import Annotated

import py_trees
from pydantic import BaseModel

from missiontree.engine.leaf import Leaf, Status
from missiontree.engine.ports import Output


class Counter(Leaf):
    """Counts ticks into its output port and raises on the second."""

    class Params(BaseModel):
        out: Annotated[str, Output("tick count")] = "count"

    def initialise(self) -> None:
        self.n = 0

    def update(self) -> Status:
        self.n += 1
        self.write("out", self.n)
        if self.n == 2:
            raise ValueError("kaboom")
        return Status.RUNNING


def test_exception_in_update_becomes_failure_with_reason() -> None:
    """A leaf that raises fails with the error as its feedback, and the tree keeps ticking."""
    leaf = Counter("counter")
    root = py_trees.composites.Sequence("root", memory=True, children=[leaf])
    root.setup()
    root.tick_once()  # n=1: RUNNING
    assert leaf.status == Status.RUNNING
    root.tick_once()  # n=2: raises -> FAILURE
    assert leaf.status == Status.FAILURE
    assert root.status == Status.FAILURE
    assert "kaboom" in leaf.feedback_message
    root.tick_once()  # restarts cleanly
    assert leaf.status == Status.RUNNING


def test_output_port_writes_bound_key() -> None:
    """An output port writes the blackboard key the mission bound it to."""
    leaf = Counter("counter", Counter.Params(out="ticks"))
    leaf.setup()
    leaf.tick_once()
    assert py_trees.blackboard.Blackboard.get("/ticks") == 1


def test_read_entries_keeps_the_mapping_entries_of_a_list() -> None:
    """A port's list gives its dict entries only; an unset key or a non-list gives none."""
    leaf = Counter("counter", Counter.Params(out="entries_here"))
    leaf.setup()
    assert leaf.read_entries("out") == []
    leaf.write("out", [{"a": 1}, "junk", 3, {"b": 2}])
    assert leaf.read_entries("out") == [{"a": 1}, {"b": 2}]
    leaf.write("out", {"a": 1})
    assert leaf.read_entries("out") == []
