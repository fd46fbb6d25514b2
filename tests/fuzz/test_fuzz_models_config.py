"""Fuzzing models configs: every generated config is accepted or reported as located problems."""

from __future__ import annotations

import yaml
from hypothesis import given
from hypothesis import strategies as st
from strategies import SCALARS, mutations, values

from missiontree.errors import ProblemsError
from missiontree.paths import REPO_ROOT
from missiontree.plugins.manager import load_plugins
from missiontree.session.models import check_models_config
from missiontree.yamlio import parse_yaml

PROVIDERS = load_plugins(autoload=False).providers
SHIPPED = [yaml.safe_load(p.read_text()) for p in sorted((REPO_ROOT / "config" / "models").glob("*.yaml"))]
KEYS = st.sampled_from(["roles", "calls", "provider", "timeout", "latency", "workers", "uniform", "detector",
                        "vlm", "model", *sorted(PROVIDERS)])


def _check(data: object) -> None:
    try:
        text = yaml.safe_dump(data, sort_keys=False, allow_unicode=True)
    except yaml.YAMLError:
        return
    try:
        check_models_config(parse_yaml(text, "<fuzz models>"), PROVIDERS, strict=True)
    except ProblemsError:
        pass


@given(mutations(SHIPPED))
def test_mutated_models_configs_never_crash(config: object) -> None:
    """The shipped models configs with values replaced, dropped or added pass or report problems."""
    _check(config)


@given(st.one_of(SCALARS, values(keys=KEYS, depth=4)))
def test_random_models_documents_never_crash(doc: object) -> None:
    """Random documents made of the models format's keys pass or report problems."""
    _check(doc)
