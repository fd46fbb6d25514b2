"""Fuzzing the mission loader: every generated mission loads or ends in a MissionFileError."""

from __future__ import annotations

import pytest
import yaml
from hypothesis import given
from hypothesis import strategies as st
from strategies import NUMBERS, SCALARS, TEXT, mutations, values

from missiontree.engine.build import build_tree
from missiontree.engine.loader import load_mission
from missiontree.errors import ProblemsError
from missiontree.paths import REPO_ROOT
from missiontree.plugins.manager import load_plugins
from missiontree.yamlio import parse_yaml

REGISTRY = load_plugins(autoload=False).nodes
TYPE_NAMES = sorted(t.name for t in REGISTRY) + ["Include", "Nope"]
PARAM_NAMES = sorted({name for t in REGISTRY for name in t.params.model_fields}) + [
    "name", "child", "children", "bb", "file", "params"]
SHIPPED = [yaml.safe_load(p.read_text()) for p in sorted((REPO_ROOT / "trees").rglob("*.yaml"))]


def _param_value() -> st.SearchStrategy[object]:
    return st.one_of(SCALARS, NUMBERS, st.builds(lambda k: {"bb": k}, TEXT),
                     st.builds(lambda k: f"${{{k}}}", TEXT), values(depth=2))


nodes = st.recursive(
    st.sampled_from(TYPE_NAMES),
    lambda inner: st.builds(
        lambda t, params, kids, key: {t: {**params, **({key: kids} if kids is not None else {})}},
        st.sampled_from(TYPE_NAMES),
        st.dictionaries(st.sampled_from(PARAM_NAMES), _param_value(), max_size=4),
        st.one_of(st.none(), inner, st.lists(inner, max_size=4)),
        st.sampled_from(["child", "children"])),
    max_leaves=12)

missions = st.fixed_dictionaries(
    {"root": nodes},
    optional={"version": st.one_of(st.just(1), SCALARS),
              "params": st.dictionaries(TEXT, SCALARS, max_size=3),
              "required": st.lists(TEXT, max_size=2),
              "blackboard": st.dictionaries(TEXT, SCALARS, max_size=3),
              "run": st.dictionaries(st.sampled_from(["backend", "world", "tick_hz", "seed", "max_duration",
                                                      "realtime", "map", "models"]), SCALARS, max_size=3),
              "description": TEXT})


def _check(tmp_path_factory: pytest.TempPathFactory, data: object) -> None:
    try:
        text = yaml.safe_dump(data, sort_keys=False, allow_unicode=True)
    except yaml.YAMLError:
        return
    path = tmp_path_factory.getbasetemp() / "fuzz_mission.yaml"
    path.write_text(text, encoding="utf-8")
    try:
        spec = load_mission(path, REGISTRY)
        build_tree(spec, REGISTRY)
    except ProblemsError:
        pass


@given(missions)
def test_generated_missions_never_crash(tmp_path_factory: pytest.TempPathFactory, mission: object) -> None:
    """Missions built from every node type with hostile parameters load, or report problems."""
    _check(tmp_path_factory, mission)


@given(mutations(SHIPPED))
def test_mutated_shipped_missions_never_crash(tmp_path_factory: pytest.TempPathFactory,
                                              mission: object) -> None:
    """The shipped missions with values replaced, dropped or added load, or report problems."""
    _check(tmp_path_factory, mission)


@given(st.one_of(st.text(max_size=300), st.binary(max_size=300)))
def test_arbitrary_text_never_crashes_the_yaml_reader(source: str | bytes) -> None:
    """Any text or bytes parse, or end in located problems."""
    try:
        parse_yaml(source, "<fuzz>")
    except ProblemsError:
        pass
