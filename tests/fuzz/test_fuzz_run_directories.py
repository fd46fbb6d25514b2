"""Fuzzing what reads a run directory: `log summarize`, `view` and `log export` end in an exit code.

A run directory comes from anywhere: a killed run, a copy, an editor, another version. Its tick log,
summary.json, runview.json and scene_graph.json are each replaced by mutated JSON, arbitrary lines or
bytes; every command that reads it must end with exit 0 (read what it could), 1 or 2 (a clear error),
never a traceback. Budget: the ``ci`` profile in CI, ``MISSIONTREE_FUZZ=nightly`` for 10,000 cases.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given
from hypothesis import strategies as st
from strategies import mutations, values

from missiontree.cli.main import main
from missiontree.testing_runs import synthesize_run

_BASE: dict[str, Any] = {}


def _base(tmp: Path) -> Path:
    """A small synthetic run (built once per session) that each case copies and damages."""
    if "dir" not in _BASE:
        run = tmp / "base"
        synthesize_run(run, 60)
        scene = {"nodes": [{"id": 0, "type": "building", "label": "Building"},
                           {"id": "room_1", "type": "room", "label": "kitchen"},
                           {"id": "cup_1", "type": "object", "label": "cup", "coordinates": [1.0, 2.0, 0.8]}],
                 "edges": [{"source_id": "room_1", "target_id": "cup_1", "relation": "contains"}]}
        (run / "scene_graph.json").write_text(json.dumps(scene))
        _BASE["dir"] = run
        _BASE["lines"] = [json.loads(x) for x in (run / "ticks.jsonl").read_text().splitlines()]
        _BASE["json"] = {name: json.loads((run / name).read_text())
                         for name in ("summary.json", "runview.json", "scene_graph.json")}
    return Path(_BASE["dir"])


def _text(value: Any) -> str:
    try:
        return json.dumps(value, allow_nan=True)
    except (TypeError, ValueError):
        return "{"


_DAMAGE = st.one_of(
    st.tuples(st.just("line"), st.integers(0, 59), values()),          # a tick-log line replaced by JSON
    st.tuples(st.just("bytes"), st.integers(0, 59), st.binary(max_size=60)),   # ... or by arbitrary bytes
    st.tuples(st.just("cut"), st.integers(0, 59), st.none()),          # the log cut after a line
    st.tuples(st.sampled_from(["summary.json", "runview.json", "scene_graph.json"]), st.just(0), values()),
)


def _damage(run: Path, damage: tuple[str, int, Any], mutated: dict[str, Any]) -> None:
    kind, index, value = damage
    lines = [json.dumps(x) for x in _BASE["lines"]]
    if kind == "line":
        lines[index % len(lines)] = _text(value)
    elif kind == "bytes":
        raw = "\n".join(lines).encode()
        (run / "ticks.jsonl").write_bytes(raw + b"\n" + value if index % 2 else value + b"\n" + raw)
        return
    elif kind == "cut":
        lines = lines[: index % len(lines)]
    else:
        (run / kind).write_text(_text(value))
    (run / "ticks.jsonl").write_text("\n".join(lines) + ("\n" if lines else ""))
    for name, data in mutated.items():
        (run / name).write_text(_text(data))


@pytest.fixture(scope="module")
def base_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return _base(tmp_path_factory.mktemp("fuzz_runs"))


@pytest.fixture(scope="module")
def work_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("fuzz_work")


def _mutated_files() -> st.SearchStrategy[dict[str, Any]]:
    """Some of the run's JSON files mutated (values replaced, keys dropped or added)."""
    names = ["summary.json", "runview.json", "scene_graph.json"]
    return st.dictionaries(st.sampled_from(names), st.sampled_from(names).flatmap(
        lambda name: mutations([_BASE["json"][name]])), max_size=2)


@given(damage=_DAMAGE, data=st.data())
def test_damaged_run_directories_are_read_or_refused(
    base_dir: Path, work_dir: Path, damage: tuple[str, int, Any], data: st.DataObject,
    capsys: pytest.CaptureFixture[str],
) -> None:
    """Each reader of a damaged run directory exits 0, 1 or 2 with no traceback."""
    run = work_dir / "run"
    shutil.rmtree(run, ignore_errors=True)
    shutil.copytree(base_dir, run)
    _damage(run, damage, data.draw(_mutated_files()))
    for argv in (["log", "summarize", str(run)], ["log", "summarize", str(run), "--json"],
                 ["view", str(run), "--out", str(work_dir / "page.html")],
                 ["log", "export", str(run), "--format", "btlog", "--out", str(work_dir / "run.btlog")]):
        code = main(argv)
        assert code in (0, 1, 2), (argv, code)
    captured = capsys.readouterr()
    assert "Traceback" not in captured.err
