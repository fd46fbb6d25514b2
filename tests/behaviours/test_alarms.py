"""Alarm records in the run directory: alarms.jsonl and the saved frames belong to one run."""

from __future__ import annotations

import json
import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from missiontree.behaviours.alarms import Alarm, record_alarm
from missiontree.engine.context import MissionContext


def _run(run_dir: Path, count: int) -> None:
    """One run's context recording ``count`` alarms with frames."""
    context = MissionContext(robot=SimpleNamespace(now=lambda: 1.0), run_dir=run_dir)  # type: ignore[arg-type]
    frame = np.zeros((24, 32, 3), np.uint8)
    for k in range(1, count + 1):
        alarm = Alarm(k, float(k), float(k) + 0.5, (0.0, 0.0, 0.0), 0.1, 2.0, "depth", (2.0, 0.2),
                      box=(4.0, 2.0, 10.0, 20.0))
        record_alarm(context, alarm, "watch", frame)


def test_a_second_run_into_the_same_directory_replaces_the_first_runs_alarms(tmp_path: Path) -> None:
    _run(tmp_path, 3)
    assert len((tmp_path / "alarms.jsonl").read_text().splitlines()) == 3
    (tmp_path / "notes.txt").write_text("mine")  # the user's own file stays
    _run(tmp_path, 2)
    lines = [json.loads(line) for line in (tmp_path / "alarms.jsonl").read_text().splitlines()]
    assert [a["id"] for a in lines] == [1, 2]
    frames = sorted(p.name for p in (tmp_path / "alarms").iterdir())
    assert frames == ["0001-detected.png", "0002-detected.png"]
    assert (tmp_path / "notes.txt").read_text() == "mine"


def test_alarms_of_one_run_are_appended_in_order(tmp_path: Path) -> None:
    _run(tmp_path, 4)
    lines = [json.loads(line) for line in (tmp_path / "alarms.jsonl").read_text().splitlines()]
    assert [a["id"] for a in lines] == [1, 2, 3, 4]
    assert lines[0]["image"] == "alarms/0001-detected.png"


def test_an_alarm_with_a_non_finite_box_or_position_is_recorded_without_drawing_it(tmp_path: Path) -> None:
    """NaN in a box or a position never crashes the record: the frame is saved, no marker is placed."""
    context = MissionContext(robot=SimpleNamespace(now=lambda: 1.0), run_dir=tmp_path)  # type: ignore[arg-type]
    alarm = Alarm(1, 0.0, 0.5, (0.0, 0.0, 0.0), 0.1, math.inf, "depth", (math.nan, 1.0),
                  box=(math.nan, 0.0, 10.0, 10.0))
    recorded = record_alarm(context, alarm, "watch", np.zeros((24, 32, 3), dtype=np.uint8))
    assert (tmp_path / recorded.image).is_file()
    line = json.loads((tmp_path / "alarms.jsonl").read_text())
    assert line["position"] == [None, 1.0] and line["box"][0] is None
    assert context.markers == []
