"""Tests of `missiontree render`."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from missiontree.cli.main import main

REPO = Path(__file__).resolve().parents[2]
EXAMPLE = str(REPO / "trees/examples/subtree_include.yaml")


def test_text_tree_shows_types_names_params_and_origin(capsys: pytest.CaptureFixture[str]) -> None:
    """The unicode tree shows each node with its type, name, parameters and the subtree file it came from."""
    assert main(["render", "--no-plugins", EXAMPLE]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0] == "main (Sequence)  memory=true"
    assert out[1] == "├── both_countdowns (Parallel)  policy=success_on_all"
    assert out[2].startswith("│   ├── countdown_door (Sequence)  memory=true  [from ")
    assert "Wait  seconds={bb: first_delay}" in out[3]
    assert out[-1] == "└── CheckBlackboard  key=lights value=lit"


def test_dot_source_has_one_node_per_tree_node(capsys: pytest.CaptureFixture[str]) -> None:
    """The dot output declares every node and every parent-child edge."""
    assert main(["render", "--no-plugins", "--format", "dot", EXAMPLE]) == 0
    out = capsys.readouterr().out
    assert out.startswith("digraph mission {")
    assert out.count("shape=") == 10 and out.count(" -> ") == 9


def test_svg_without_graphviz_says_how_to_get_it(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """Without `dot` on PATH, --format svg exits 2 naming Graphviz and the dot alternative."""
    monkeypatch.setattr(shutil, "which", lambda name: None)
    assert main(["render", "--no-plugins", "--format", "svg", EXAMPLE]) == 2
    err = capsys.readouterr().err
    assert "Graphviz" in err and "--format dot" in err and "Traceback" not in err


@pytest.mark.skipif(shutil.which("dot") is None, reason="Graphviz is not installed")
def test_svg_with_graphviz(tmp_path: Path) -> None:
    """With Graphviz installed, --format svg writes an SVG file."""
    out = tmp_path / "tree.svg"
    assert main(["render", "--no-plugins", "--format", "svg", "--out", str(out), EXAMPLE]) == 0
    assert "<svg" in out.read_text()


def test_render_of_broken_mission_exits_two(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A broken mission is reported like validate does (file:line:col), exit 2, nothing drawn."""
    path = tmp_path / "m.yaml"
    path.write_text("root:\n  Sequence:\n    children: [Succeed]\n")
    assert main(["render", "--no-plugins", str(path)]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    assert "m.yaml:2:3: root/Sequence: expected `memory: true` or `memory: false`" in captured.err


def test_text_tree_shows_node_conditions(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A node's conditions are drawn after its parameters, expressions quoted."""
    mission = tmp_path / "m.yaml"
    mission.write_text('version: 1\nblackboard: {battery: 1.0, done: false}\nroot:\n  Sequence:\n'
                       '    name: main\n    memory: true\n    children:\n'
                       '      - Wait: {seconds: 1, skip_if: "battery < 0.2", on_success: "done = true"}\n',
                       encoding="utf-8")
    assert main(["render", "--no-plugins", str(mission)]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[1] == '└── Wait  seconds=1 skip_if="battery < 0.2" on_success="done = true"'
