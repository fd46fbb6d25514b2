"""Numbers that are not numbers, and blackboard defaults of the wrong type, are found before the run."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import pytest
from pydantic import BaseModel

from missiontree.engine.leaf import Leaf, Status
from missiontree.engine.loader import check_mission, load_mission
from missiontree.engine.nodes import register_nodes
from missiontree.engine.ports import Input
from missiontree.engine.registry import NodeRegistry
from missiontree.errors import MissionFileError


class Goto(Leaf):
    """Drive to a point (a stand-in for NavigateTo)."""

    class Params(BaseModel):
        x: float
        y: float = 0.0
        target: Annotated[str, Input("what to follow", type="dict")] = "target"

    def update(self) -> Status:
        return self.succeed()


@pytest.fixture
def registry() -> NodeRegistry:
    reg = NodeRegistry()
    register_nodes(reg)
    reg.add(Goto)
    return reg


def _problems(tmp_path: Path, registry: NodeRegistry, text: str) -> list[str]:
    path = tmp_path / "m.yaml"
    path.write_text(text)
    with pytest.raises(MissionFileError) as caught:
        load_mission(path, registry)
    return [str(p) for p in caught.value.problems]


@pytest.mark.parametrize("value", [".nan", ".inf", "-.inf", ".NaN"])
def test_non_finite_parameters_are_refused_at_their_line(tmp_path: Path, registry: NodeRegistry,
                                                         value: str) -> None:
    """`x: .nan` (or an infinity) is a problem at the value, saying a finite number is expected."""
    (problem,) = _problems(tmp_path, registry, f"root:\n  Goto: {{x: {value}}}\n")
    assert ":2:13: root/Goto: x: expected a finite number" in problem


def test_non_finite_numbers_inside_lists_and_defaults_are_refused(
    tmp_path: Path, registry: NodeRegistry
) -> None:
    """NaN deep in a list parameter or a blackboard default is found where it is written."""
    problems = _problems(tmp_path, registry, "blackboard:\n  limits: [1.0, .inf]\n"
                         "root:\n  Wait: {seconds: .nan}\n")
    assert any(":2:" in p and "limits[1]: expected a finite number" in p for p in problems), problems
    assert any(":4:" in p and "seconds: expected a finite number" in p for p in problems), problems


def test_a_default_read_by_a_number_parameter_must_be_a_number(
    tmp_path: Path, registry: NodeRegistry
) -> None:
    """`goal_x: "six"` read as `x: {bb: goal_x}` is reported at the reference, naming the default."""
    text = 'blackboard:\n  goal_x: "six"\nroot:\n  Goto: {x: {bb: goal_x}}\n'
    (problem,) = _problems(tmp_path, registry, text)
    assert ":4:13: root/Goto: x: expected number in the blackboard default 'goal_x'" in problem
    assert "found 'six'" in problem


def test_a_default_read_by_an_input_port_must_have_the_port_type(
    tmp_path: Path, registry: NodeRegistry
) -> None:
    """A blackboard default read through an input port declared as a dict must be a mapping."""
    (problem,) = _problems(tmp_path, registry, "blackboard:\n  target: 3\nroot:\n  Goto: {x: 1.0}\n")
    assert "target: expected the blackboard default 'target' to be dict" in problem


def test_good_defaults_pass(tmp_path: Path, registry: NodeRegistry) -> None:
    """Defaults of the right types load."""
    path = tmp_path / "m.yaml"
    path.write_text("blackboard:\n  goal_x: 6\n  target: {x: 1}\nroot:\n  Goto: {x: {bb: goal_x}}\n")
    assert load_mission(path, registry).blackboard["goal_x"] == 6


def test_check_mission_returns_the_spec_with_its_problems(tmp_path: Path, registry: NodeRegistry) -> None:
    """check_mission keeps the tree of a mission with problems, so its references can still be checked."""
    path = tmp_path / "m.yaml"
    path.write_text("root:\n  Sequence:\n    memory: true\n    children:\n"
                    "      - Goto: {x: .nan}\n      - Goto: {x: 1}\n")
    spec, problems = check_mission(path, registry)
    assert spec is not None and len(problems) == 1
    assert spec.root.children[1].params is not None and spec.root.children[0].params is None
