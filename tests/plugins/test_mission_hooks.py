"""Mission hooks of several plugins: one that raises stops neither the others nor the run's outcome."""

from __future__ import annotations

import importlib.metadata
import json
import sys
import types
from pathlib import Path
from typing import Any

import pytest

from missiontree.cli.main import main
from missiontree.plugins import manager
from missiontree.plugins.hookspecs import hookimpl
from missiontree.testing import clean_state

MISSION = """\
version: 1
run: {backend: sim, world: conformance, tick_hz: 10, max_duration: 5}
root:
  Wait: {seconds: 1.0}
"""


@pytest.fixture(autouse=True)
def _clean() -> None:
    clean_state()


def test_a_raising_mission_finished_hook_leaves_the_builtin_one_and_the_outcome(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    """A plugin's mission_finished raises: runview.json keeps the trajectory, the run exits 1 saying why."""
    module = types.ModuleType("mt_test_broken_finish")

    def missiontree_mission_finished(context: Any, summary: dict[str, Any]) -> None:
        raise RuntimeError("uploader crashed")

    module.missiontree_mission_finished = hookimpl(missiontree_mission_finished)  # type: ignore[attr-defined]
    monkeypatch.setitem(sys.modules, module.__name__, module)
    entry = importlib.metadata.EntryPoint(name="broken_finish", value=module.__name__, group="missiontree")
    monkeypatch.setattr(manager, "discover_entry_points", lambda: [entry])
    mission = tmp_path / "wait.yaml"
    mission.write_text(MISSION, encoding="utf-8")
    out = tmp_path / "run"
    assert main(["run", str(mission), "--out", str(out), "--quiet"]) == 1
    captured = capsys.readouterr()
    assert "broken_finish" in captured.out and "uploader crashed" in captured.out
    view = json.loads((out / "runview.json").read_text(encoding="utf-8"))
    assert view.get("poses"), "the built-in hook wrote no trajectory"
    summary = json.loads((out / "summary.json").read_text(encoding="utf-8"))
    assert summary["status"] == "SUCCESS" and "uploader crashed" in summary["plugin_error"]
