"""Every shipped mission runs in CI with its perception substituted (tests/substitutions/<mission>.yaml)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from missiontree.cli.log import format_summary, summarize
from missiontree.cli.main import main
from missiontree.cli.run import run_substituted
from missiontree.engine.substitute import load_rules
from missiontree.paths import REPO_ROOT
from missiontree.session import MissionRequest
from missiontree.testing import clean_state

TREES = sorted((REPO_ROOT / "trees").glob("*.yaml"))
RULES = REPO_ROOT / "tests" / "substitutions"
#: What each mission is given beyond its defaults (the intent missions need a command).
PARAMS = {"go_to_intent": {"command": "bring me a cup"},
          "map_and_go_to_intent": {"command": "bring me a cup"}}


def test_every_shipped_mission_has_substitution_rules() -> None:
    """A new mission under trees/ without a rules file fails here."""
    assert TREES
    missing = [tree.name for tree in TREES if not (RULES / tree.name).is_file()]
    assert not missing


@pytest.mark.parametrize("tree", TREES, ids=[tree.stem for tree in TREES])
def test_shipped_mission_succeeds_with_its_perception_substituted(tree: Path, tmp_path: Path) -> None:
    """The mission ends SUCCESS by its own logic, with every substitution in the summary and the tick log."""
    clean_state()
    out = tmp_path / "run"
    result = run_substituted(
        MissionRequest(mission=tree, out=out, params=PARAMS.get(tree.stem), max_duration=120.0, quiet=True,
                       handle_signals=False),
        load_rules(RULES / tree.name))
    clean_state()
    assert (result.status.name, result.stopped_by) == ("SUCCESS", "status"), result.summary.get("failures")
    substituted = {entry["node"] for entry in result.summary["substitutions"]}
    logged = [json.loads(line) for line in (out / "ticks.jsonl").read_text().splitlines()]
    assert {line["node"] for line in logged if line["event"] == "substituted"} == substituted
    assert substituted


def test_cli_run_substitute_and_a_rule_matching_nothing(tmp_path: Path,
                                                        capsys: pytest.CaptureFixture[str]) -> None:
    """`run --substitute` with a rule that matches no node exits 2 naming the rule's file:line:col."""
    rules = tmp_path / "rules.yaml"
    rules.write_text("rules:\n  - match: Explore\n    status: SUCCESS\n"
                     "  - match: '*/nowhere'\n    status: SUCCESS\n")
    code = main(["run", str(REPO_ROOT / "trees" / "explore.yaml"), "--substitute", str(rules), "--out",
                 str(tmp_path / "run"), "-q"])
    assert code == 2
    assert f"{rules}:4:5: rules[1].match" in capsys.readouterr().err


def test_run_watch_reloads_an_edited_subtree_on_the_simulator(tmp_path: Path) -> None:
    """`run --watch` through the session: an included subtree edited at 2 s is running by 3 s, count kept."""
    import py_trees

    mission = tmp_path / "main.yaml"
    mission.write_text("blackboard: {count: 0}\nroot:\n  Sequence:\n    name: main\n    memory: true\n"
                       "    children:\n      - Include: {file: sub.yaml}\n      - Wait: {seconds: 100}\n")
    sub = tmp_path / "sub.yaml"
    sub.write_text("root:\n  Script: {code: 'count = count + 1'}\n")
    edited: list[float] = []

    def edit(session: object) -> None:
        now = session.robot.now()  # type: ignore[attr-defined]
        if not edited and now >= 2.0:
            sub.write_text("root:\n  Script: {code: 'count = count + 10'}\n")
            edited.append(now)

    clean_state()
    out = tmp_path / "run"
    result = run_substituted(MissionRequest(mission=mission, out=out, max_duration=5.0, quiet=True,
                                            handle_signals=False, on_tick=edit), watch=True)
    count = py_trees.blackboard.Blackboard.get("/count")
    clean_state()
    assert result.stopped_by == "limit"
    lines = [json.loads(line) for line in (out / "ticks.jsonl").read_text().splitlines()]
    (reloaded,) = [line for line in lines if line["event"] == "reloaded"]
    assert reloaded["files"] == [str(sub)] and reloaded["t"] - edited[0] <= 1.0
    assert count == 11
    assert f"reloaded {sub} at " in format_summary(summarize(lines))


def test_a_substituted_run_says_so_on_the_terminal_and_in_its_summary(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """An outcome reached with stubs is marked: the result line counts them, `log summarize` lists them."""
    rules = tmp_path / "rules.yaml"
    rules.write_text("rules:\n  - match: Explore\n    status: SUCCESS\n    after: 1\n")
    out = tmp_path / "run"
    clean_state()
    assert main(["run", str(REPO_ROOT / "trees" / "explore.yaml"), "--substitute", str(rules),
                 "--out", str(out), "-q"]) == 0
    assert "SUCCESS (1 node(s) substituted)" in capsys.readouterr().out
    assert main(["log", "summarize", str(out)]) == 0
    said = capsys.readouterr().out
    assert "substituted (stubs ran, not these nodes):" in said
    assert f"explore (Explore): SUCCESS after 1.0 s, rule at {rules}:2:5" in said
