"""Tests of building model roles on first use: a mission builds only the models it calls."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

from missiontree.errors import ProblemsError
from missiontree.plugins.manager import load_plugins
from missiontree.reasoning.models import Models, PendingProvider
from missiontree.session import MissionRequest, run_mission
from missiontree.session.models import build_models
from missiontree.testing import clean_state

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(autouse=True)
def _clean() -> None:
    clean_state()


class _Counting:
    """A provider factory that counts the providers it built (and builds them as the real one would)."""

    def __init__(self, factory: Any) -> None:
        self.factory = factory
        self.built = 0
        for attr in ("wants_models", "wants_timeout", "options_model", "path_options"):
            if hasattr(factory, attr):
                setattr(self, attr, getattr(factory, attr))

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        self.built += 1
        return self.factory(*args, **kwargs)


def _counting(plugins: Any, name: str) -> _Counting:
    from missiontree.plugins.builtin import resolve_factory

    counting = _Counting(resolve_factory("provider", name, plugins.providers[name]))
    plugins.providers[name] = counting
    return counting


def test_a_patrol_builds_no_language_model(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The patrol asks no LLM, so its session never builds the offline LLM (nor its embedder)."""
    plugins = load_plugins()
    monkeypatch.setattr(plugins, "providers", dict(plugins.providers))
    llm, embedder = _counting(plugins, "offline_llm"), _counting(plugins, "minilm")
    result = run_mission(MissionRequest(mission=REPO / "trees" / "patrol.yaml", plugins=plugins,
                                        max_duration=1.0, out=tmp_path / "run", quiet=True))
    assert result.ticks > 0
    assert (llm.built, embedder.built) == (0, 0)
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert "llm" not in summary["profile"]["models"]


def test_a_role_is_built_once_when_first_looked_up() -> None:
    """A pending role is built on its first lookup, once, and the mapping then holds the provider."""
    made: list[object] = []

    def build() -> object:
        made.append(object())
        return made[-1]

    models = Models({"llm": PendingProvider("llm", "fake", build)})
    assert made == [] and isinstance(dict.__getitem__(models, "llm"), PendingProvider)
    first = models["llm"]
    assert models.get("llm") is first and models.provider("llm") is first and made == [first]
    assert dict.__getitem__(models, "llm") is first


def test_a_dependency_built_by_another_role_is_the_same_provider() -> None:
    """The VLM's detector, built when the VLM is, is the detector role's provider, not a second one."""
    models = build_models("offline", providers=load_plugins().providers)
    vlm = models["vlm"]
    assert not isinstance(dict.__getitem__(models, "detector"), PendingProvider)
    assert vlm.detector is models["detector"]
    assert isinstance(dict.__getitem__(models, "llm"), PendingProvider)


def test_a_misconfigured_unused_role_still_fails_before_the_first_tick(tmp_path: Path) -> None:
    """A bad option of a role the mission never calls is still refused at open, with its line."""
    models = tmp_path / "models.yaml"
    models.write_text("roles:\n  detector:\n    provider: sim_detector\n  llm:\n    provider: offline_llm\n"
                      "    embedder: embedder\n    no_such_option: 3\n  embedder:\n    provider: minilm\n",
                      encoding="utf-8")
    with pytest.raises(ProblemsError) as caught:
        run_mission(MissionRequest(mission=REPO / "trees" / "patrol.yaml", models=models,
                                   max_duration=1.0, out=tmp_path / "run", quiet=True))
    assert "no_such_option" in str(caught.value) and "models.yaml:7" in str(caught.value)
