"""The shipped example plugins are templates: installable on every Python missiontree supports."""

from __future__ import annotations

import ast
import tomllib
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
PLUGINS = sorted(p for p in (REPO / "plugins").iterdir() if (p / "pyproject.toml").is_file())


def test_both_example_plugins_are_here() -> None:
    assert {p.name for p in PLUGINS} >= {"missiontree-example", "missiontree-battery"}


@pytest.mark.parametrize("plugin", PLUGINS, ids=lambda p: p.name)
def test_template_supports_every_python_missiontree_does(plugin: Path) -> None:
    """Same requires-python as missiontree (no upper cap), the entry point group, and 3.11 syntax."""
    ours = tomllib.loads((REPO / "pyproject.toml").read_text(encoding="utf-8"))["project"]
    meta = tomllib.loads((plugin / "pyproject.toml").read_text(encoding="utf-8"))["project"]
    assert meta["requires-python"] == ours["requires-python"] == ">=3.11"
    assert "missiontree" in meta["dependencies"]
    [(name, target)] = meta["entry-points"]["missiontree"].items()
    module = plugin / "src" / (target.replace(".", "/") + ".py")
    assert module.is_file(), f"entry point {name} = {target} names no module"
    for source in (plugin / "src").rglob("*.py"):
        ast.parse(source.read_text(encoding="utf-8"), str(source), feature_version=(3, 11))
