"""Tests of the mission loader: top level, run section, includes with parameters, substitution."""

from __future__ import annotations

from pathlib import Path

import pytest

from missiontree.engine.loader import load_mission
from missiontree.engine.nodes import register_nodes
from missiontree.engine.ports import BlackboardRef
from missiontree.engine.registry import NodeRegistry
from missiontree.errors import MissionFileError

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture
def registry() -> NodeRegistry:
    reg = NodeRegistry()
    register_nodes(reg)
    return reg


def write(folder: Path, name: str, text: str) -> Path:
    path = folder / name
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return path


def test_example_mission_loads_with_run_section_and_blackboard(registry: NodeRegistry) -> None:
    """The shipped timer example loads: run defaults, blackboard defaults and a checked tree."""
    spec = load_mission(REPO / "trees/examples/timer_and_blackboard.yaml", registry)
    assert spec.run.tick_hz == 10 and spec.run.max_duration == 60 and spec.run.seed is None
    assert spec.blackboard == {"armed": True, "phase": "idle"}
    assert spec.root.type == "Sequence" and spec.root.name == "main"
    assert all(node.params is not None for node in spec.nodes())


def test_param_substitution_keeps_types_and_interpolates_text(tmp_path: Path, registry: NodeRegistry) -> None:
    """A whole-value ${p} keeps the parameter's type; inside text it is interpolated; $${ is literal."""
    path = write(tmp_path, "m.yaml", """
params: {pause: 1.5, who: world}
root:
  Sequence:
    memory: true
    children:
      - Wait: {seconds: "${pause}"}
      - SetBlackboard: {key: greeting, value: "hello ${who}, costs $${price}"}
""")
    wait, setter = load_mission(path, registry).root.children
    assert wait.params.seconds == 1.5  # type: ignore[union-attr]
    assert setter.params.value == "hello world, costs ${price}"  # type: ignore[union-attr]


def test_include_passes_parameters_and_names_its_root(tmp_path: Path, registry: NodeRegistry) -> None:
    """An Include expands the subtree with the given parameters; its `name` renames the subtree root."""
    write(tmp_path, "sub/pause.yaml", """
params: {seconds: 1.0}
required: [key]
blackboard: {from_sub: 1, shared: sub}
root:
  Sequence:
    memory: true
    children:
      - Wait: {seconds: "${seconds}"}
      - SetBlackboard: {key: "${key}", value: done}
""")
    path = write(tmp_path, "m.yaml", """
blackboard: {shared: mission}
root:
  Include: {file: sub/pause.yaml, name: pause_twice, params: {key: door, seconds: 3}}
""")
    spec = load_mission(path, registry)
    assert spec.root.name == "pause_twice"
    wait, setter = spec.root.children
    assert wait.params.seconds == 3.0  # type: ignore[union-attr]
    assert setter.params.key == "door"  # type: ignore[union-attr]
    assert spec.blackboard == {"from_sub": 1, "shared": "mission"}  # the mission's own defaults win
    assert wait.source.file.endswith("pause.yaml") and wait.source.included_from
    assert len(spec.files) == 2


def test_blackboard_reference_passes_through_include(tmp_path: Path, registry: NodeRegistry) -> None:
    """A {bb: key} given as a subtree parameter reaches the leaf as a BlackboardRef."""
    write(tmp_path, "sub.yaml", "required: [s]\nroot:\n  Wait: {seconds: \"${s}\"}\n")
    path = write(tmp_path, "m.yaml", "blackboard: {delay: 2}\nroot:\n"
                                     "  Include: {file: sub.yaml, params: {s: {bb: delay}}}\n")
    spec = load_mission(path, registry)
    assert spec.root.params.seconds == BlackboardRef("delay")  # type: ignore[union-attr]


def test_include_found_in_shipped_trees_folder(registry: NodeRegistry) -> None:
    """`file: subtrees/x.yaml` from trees/examples/ resolves to trees/subtrees/x.yaml."""
    spec = load_mission(REPO / "trees/examples/subtree_include.yaml", registry)
    names = [node.name for node in spec.nodes()]
    assert "countdown_door" in names and "countdown_lights" in names


def test_include_outside_mission_folder_needs_permission(tmp_path: Path, registry: NodeRegistry) -> None:
    """A subtree outside the mission's folder is refused, unless allow_outside is given."""
    write(tmp_path, "shared/leaf.yaml", "root: Succeed\n")
    path = write(tmp_path, "missions/m.yaml", "root:\n  Include: {file: ../shared/leaf.yaml}\n")
    with pytest.raises(MissionFileError) as info:
        load_mission(path, registry)
    assert "inside the mission's folder" in str(info.value)
    assert load_mission(path, registry, allow_outside=True).root.type == "Succeed"


def test_every_problem_is_reported_at_once(tmp_path: Path, registry: NodeRegistry) -> None:
    """Problems in the mission and in an included subtree come back together, mission first."""
    write(tmp_path, "sub.yaml", "root:\n  Wait: {seconds: never}\n")
    path = write(tmp_path, "m.yaml", """
root:
  Sequence:
    memory: maybe
    children:
      - Include: {file: sub.yaml}
      - Nope
""")
    with pytest.raises(MissionFileError) as info:
        load_mission(path, registry)
    problems = info.value.problems
    assert len(problems) == 3
    assert [p.line for p in problems[:2]] == [4, 7]
    assert problems[2].file.endswith("sub.yaml") and problems[2].line == 2


def test_bare_name_and_empty_parameters_are_nodes(tmp_path: Path, registry: NodeRegistry) -> None:
    """`- Succeed` and `- Succeed:` (no parameters) are both nodes."""
    path = write(tmp_path, "m.yaml", "root:\n  Selector:\n    memory: false\n    children:\n"
                 "      - Fail\n      - Succeed:\n")
    spec = load_mission(path, registry)
    assert [c.type for c in spec.root.children] == ["Fail", "Succeed"]


def test_node_paths_name_types_names_and_positions(tmp_path: Path, registry: NodeRegistry) -> None:
    """Node paths read root/Type(name)[index] so problems point into the tree."""
    path = write(tmp_path, "m.yaml", "root:\n  Sequence:\n    name: main\n    memory: true\n"
                 "    children:\n      - Succeed\n      - Retry: {attempts: 2, child: Fail}\n")
    spec = load_mission(path, registry)
    assert [n.path for n in spec.nodes()] == [
        "root/Sequence(main)", "root/Sequence(main)/Succeed[0]", "root/Sequence(main)/Retry[1]",
        "root/Sequence(main)/Retry[1]/Fail",
    ]
    assert (spec.root.children[1].source.line, spec.root.children[1].source.col) == (7, 9)
