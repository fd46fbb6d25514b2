"""Tests of `missiontree plugins`: which plugins are loaded and what each provides."""

from __future__ import annotations

import json

import pytest

from missiontree.cli.main import main
from missiontree.testing import clean_state


@pytest.fixture(autouse=True)
def _clean() -> None:
    clean_state()


def test_json_lists_the_builtin_plugin_with_its_backends(capsys: pytest.CaptureFixture[str]) -> None:
    """The built-in plugin is always listed, with the sim and ros2 backends."""
    assert main(["plugins", "--json", "--no-plugins"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["autoload"] is False
    assert [p["name"] for p in data["plugins"]] == ["builtin"]
    assert {"sim", "ros2"} <= set(data["plugins"][0]["backends"])


def test_text_says_when_installed_plugins_were_skipped(capsys: pytest.CaptureFixture[str]) -> None:
    """The text listing notes that installed plugins were not loaded."""
    assert main(["plugins", "--no-plugins"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("builtin  (missiontree.plugins.builtin, built in)")
    assert "installed plugins not loaded" in out
