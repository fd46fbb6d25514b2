"""The intent benchmark's test split helpers: commands from a world's objects, split figures, the table."""

from __future__ import annotations

import sys
from pathlib import Path

from missiontree.backends.sim import load_world

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
import intent_eval  # noqa: E402


def test_referential_commands_come_from_the_world_and_are_judged_by_it() -> None:
    """Colour, room and resting-on commands name real objects; a colour the world lacks satisfies none."""
    world = load_world("office")
    cases = intent_eval.referential_cases(world, "office")
    satisfiable = [c for c in cases if c.group == "test_referential"]
    assert satisfiable and all(any(c.satisfies(o, world) for o in world.objects) for c in satisfiable)
    absent = [c for c in cases if c.group == "none"]
    assert absent and not any(c.satisfies(o, world) for c in absent for o in world.objects)
    assert not {c.command for c in cases} & {c.command for c in intent_eval.WRITTEN + intent_eval.TABLE2}


def test_test_words_use_no_dev_command() -> None:
    """The WordNet commands of the test split share no command with the dev split."""
    import json

    words = json.loads(intent_eval.WORDS.read_text(encoding="utf-8"))
    commands = {e["command"] for kind in ("needs", "objects", "absent") for e in words[kind]}
    assert len(commands) > 100
    assert not commands & {c.command for c in intent_eval.WRITTEN + intent_eval.TABLE2}


def trial(group: str, success: bool, wrong: bool = False) -> intent_eval.Trial:
    case = intent_eval.Case("office", "x", group, intent_eval._nothing)
    return intent_eval.Trial("ours", case, (0.0, 0.0, 0.0), success=success, wrong_served=wrong)


def test_split_figures_count_wrong_objects_and_give_a_wilson_interval() -> None:
    """3 of 4 succeed, one served a wrong object: 0.75 with an interval around it, 1 wrong object served."""
    figures = intent_eval.split_figures([trial("none", True), trial("test_need", True),
                                         trial("test_need", True), trial("test_need", False, wrong=True)])
    assert figures["success"] == 0.75 and figures["wrong_objects_served"] == 1
    low, high = figures["success_ci95"]
    assert low < 0.75 < high
    assert figures["groups"]["test_need"] == {"trials": 3, "success": 0.6667}
    assert "| test | 4 | 0.750 |" in intent_eval.markdown_table({"test": figures})


def test_perceived_table_sets_each_command_beside_the_truth_graph_and_the_paper() -> None:
    """Per Table II command: the perceived graph's rate, the ground-truth graph's, the paper's."""
    outcomes = {case.command: [True, False] for case in intent_eval.TABLE2}
    truth = [intent_eval.Trial("ours", intent_eval.TABLE2[3], (0.0, 0.0, 0.0), success=True)]
    table = intent_eval.perceived_table(outcomes, truth)
    assert "| I want the grey backpack | 50 (2) | 100 (1) | 60 |" in table
    assert "| I am thirsty | 50 (2) | - | 100 |" in table


def test_sitting_on_is_judged_by_the_rule_that_made_the_command() -> None:
    """Every "sitting on" command of the office is satisfied by an object resting on its anchor."""
    world = load_world("office")
    cases = [c for c in intent_eval.referential_cases(world, "office", k=10) if "sitting on" in c.command]
    assert cases and all(any(c.satisfies(o, world) for o in world.objects) for c in cases)
    on = {o.id for c in cases for o in world.objects if c.satisfies(o, world)}
    assert all(o.elevation > 0.1 for o in world.objects if o.id in on)


def test_dev_words_share_no_word_with_the_test_commands() -> None:
    """The dev split's commands come from a thesaurus that is not WordNet and share no word with test's."""
    import json
    import re

    dev = json.loads(intent_eval.DEV_WORDS.read_text(encoding="utf-8"))
    test = json.loads(intent_eval.WORDS.read_text(encoding="utf-8"))
    test_words = {w for kind in ("needs", "objects", "absent") for e in test[kind]
                  for w in re.findall(r"[a-z]+", e["command"].lower())}
    paraphrased = {e["term"] for kind in ("needs", "objects") for e in dev[kind]}
    assert len(dev["needs"]) >= 20 and paraphrased
    assert all(e["source"].startswith("aiksaurus ") for kind in ("needs", "objects") for e in dev[kind])
    assert not {w for p in paraphrased for w in re.findall(r"[a-z]+", p)} & test_words


def test_dev_referential_templates_are_not_the_test_splits() -> None:
    """On the same world the dev split's referential commands differ from the test split's, judged alike."""
    world = load_world("office")
    dev = intent_eval.referential_cases(world, "office", templates=intent_eval.DEV_TEMPLATES,
                                        group="dev_referential")
    test = intent_eval.referential_cases(world, "office")
    assert dev and not {c.command for c in dev} & {c.command for c in test}
    satisfiable = [c for c in dev if c.group == "dev_referential"]
    assert all(any(c.satisfies(o, world) for o in world.objects) for c in satisfiable)
