"""The scene-graph benchmark on the batch runner: a world whose evaluation fails is reported, not lost."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
import scene_graph_eval  # noqa: E402


def test_a_world_whose_run_fails_is_reported_on_stderr_and_left_out(
    capsys: pytest.CaptureFixture[str],
) -> None:
    shown: list[Any] = []
    options = scene_graph_eval.EvalOptions()
    rows = scene_graph_eval.run_worlds(
        [(0, "no_such_world")], "offline", 1, options, lambda row, text: shown.append(row)
    )
    assert rows == [] and shown == []
    err = capsys.readouterr().err
    assert "no_such_world: the evaluation did not finish (ERROR" in err
    assert "unknown world 'no_such_world'" in err


def test_the_probe_options_reach_the_worker_as_plain_data() -> None:
    import pickle

    options = scene_graph_eval.EvalOptions(changes_seed=3, diagnose=True)
    probe = pickle.loads(pickle.dumps(scene_graph_eval.SceneEvalProbe(options)))
    assert probe.options == options


def test_each_world_runs_the_shipped_scene_graph_mission() -> None:
    """The benchmark's mission is trees/map_scene.yaml itself: exploration and the graph on an unknown map."""
    import yaml

    mission = scene_graph_eval.MISSION
    assert mission.name == "map_scene.yaml" and mission.parent.name == "trees"
    text = mission.read_text(encoding="utf-8")
    assert "Explore" in text and "BuildSceneGraph" in text
    assert yaml.safe_load(text)["run"]["map"] == "unknown"
