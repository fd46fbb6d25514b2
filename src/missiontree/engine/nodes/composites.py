"""Composite node types: Sequence, Selector (memory stated explicitly) and Parallel with its policy.

``memory`` is required on Sequence and Selector because it is the most common confusion of
behaviour-tree users (see docs/mission-format.md):

- ``memory: true`` — a child that returned RUNNING is resumed on the next tick; children before
  it are not ticked again. A step-by-step plan.
- ``memory: false`` — every tick starts again from the first child, so earlier children are
  re-checked each tick (conditions that must keep holding) and a RUNNING child further down is
  halted as soon as an earlier one changes its answer.
"""

from __future__ import annotations

from typing import Literal

import py_trees
from pydantic import BaseModel, ConfigDict, Field

from missiontree.engine.registry import NodeType
from missiontree.errors import MissionFileError, Problem

Behaviour = py_trees.behaviour.Behaviour

MEMORY_DOC = (
    "Required. true: resume the RUNNING child on the next tick (a step-by-step plan); "
    "false: restart from the first child every tick (earlier children are re-checked)."
)


class SequenceParams(BaseModel):
    """Parameters of Sequence."""

    model_config = ConfigDict(extra="forbid")

    memory: bool = Field(description=MEMORY_DOC)


class SelectorParams(BaseModel):
    """Parameters of Selector."""

    model_config = ConfigDict(extra="forbid")

    memory: bool = Field(description=MEMORY_DOC)


class ParallelParams(BaseModel):
    """Parameters of Parallel."""

    model_config = ConfigDict(extra="forbid")

    policy: Literal["success_on_all", "success_on_one", "success_on_selected"] = Field(
        "success_on_all",
        description="success_on_all: every child succeeds; success_on_one: the first success wins; "
        "success_on_selected: the children named in `selected` succeed. Any failure fails the Parallel.",
    )
    synchronise: bool = Field(
        True, description="Do not tick children that already succeeded until the policy is met "
        "(success_on_all and success_on_selected).",
    )
    selected: list[str | int] = Field(
        default_factory=list,
        description="For success_on_selected: the children that must succeed, by name or 0-based index.",
    )


def build_sequence(name: str, params: SequenceParams, children: list[Behaviour]) -> Behaviour:
    """A py_trees Sequence."""
    return py_trees.composites.Sequence(name=name, memory=params.memory, children=children)


def build_selector(name: str, params: SelectorParams, children: list[Behaviour]) -> Behaviour:
    """A py_trees Selector."""
    return py_trees.composites.Selector(name=name, memory=params.memory, children=children)


def selected_children(params: ParallelParams, names: list[str]) -> tuple[list[int], list[str]]:
    """Indices of the children ``selected`` names, and the entries that match no child."""
    indices: list[int] = []
    unknown: list[str] = []
    for entry in params.selected:
        if isinstance(entry, int):
            if 0 <= entry < len(names):
                indices.append(entry)
            else:
                unknown.append(str(entry))
        elif entry in names:
            indices.append(names.index(entry))
        else:
            unknown.append(entry)
    return indices, unknown


def build_parallel(name: str, params: ParallelParams, children: list[Behaviour]) -> Behaviour:
    """A py_trees Parallel with the chosen success policy."""
    policy: py_trees.common.ParallelPolicy.Base
    if params.policy == "success_on_one":
        policy = py_trees.common.ParallelPolicy.SuccessOnOne()
    elif params.policy == "success_on_selected":
        indices, unknown = selected_children(params, [c.name for c in children])
        if unknown or not indices:
            found = ", ".join(unknown) or "none"
            raise MissionFileError([Problem(
                "", 0, 0, name, f"expected `selected` to name children of the Parallel, found {found}")])
        policy = py_trees.common.ParallelPolicy.SuccessOnSelected(
            children=[children[i] for i in indices], synchronise=params.synchronise)
    else:
        policy = py_trees.common.ParallelPolicy.SuccessOnAll(synchronise=params.synchronise)
    return py_trees.composites.Parallel(name=name, policy=policy, children=children)


COMPOSITES = [
    NodeType("Sequence", "composite", SequenceParams, build_sequence,  # type: ignore[arg-type]
             "Tick children in order; fail at the first failure, succeed when all succeed."),
    NodeType("Selector", "composite", SelectorParams, build_selector,  # type: ignore[arg-type]
             "Tick children in order; succeed at the first success, fail when all fail (a fallback)."),
    NodeType("Parallel", "composite", ParallelParams, build_parallel,  # type: ignore[arg-type]
             "Tick every child each tick; succeed or fail according to the policy."),
]
