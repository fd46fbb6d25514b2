"""Fuzzing a batch directory on resume: a damaged run record is run again or refused, never a crash.

``batch --resume`` trusts nothing in ``--out``: a run's ``record.json`` may be cut by a killed
process, edited, or come from another version. Resuming a batch whose every planned run has a
(mutated) record must end in records of the right shape, with the report, results.jsonl and
junit.xml written, or in a ConfigError naming the run; a record that is not a whole record is not
kept as a result (its run is done again, its directory set aside). Budget: a quarter of the ``ci``
profile in CI (each case builds a batch directory), ``MISSIONTREE_FUZZ=nightly`` for 10,000 cases.
"""

from __future__ import annotations

import json
import math
import shutil
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from strategies import mutations, values

from missiontree.errors import ConfigError
from missiontree.evaluation.batch import DAMAGED_SUFFIX, RUNS_DIR, run_batch
from missiontree.evaluation.engines import SerialEngine
from missiontree.evaluation.plan import expand_plan
from missiontree.evaluation.report import format_table, summarize, write_junit, write_results
from missiontree.evaluation.worker import RECORD_FILE, RunTask, whole_record

RECORD = {"run_id": "", "world": None, "seed": 0, "run_seed": 0, "params": {}, "status": "SUCCESS",
          "stopped_by": "status", "reason": "succeeded", "robot_time_s": 1.0, "wall_time_s": 0.01,
          "path_length_m": 0.0, "ticks": 10, "figures": {}, "attempt": 1}


def _rerun(task: RunTask) -> dict[str, Any]:
    """A run done again: a whole record (what a real worker writes)."""
    record = {**RECORD, "run_id": task.spec.run_id, "seed": task.spec.seed, "run_seed": task.spec.run_seed,
              "reason": "run again"}
    final = Path(task.runs_dir) / task.spec.run_id
    shutil.rmtree(final, ignore_errors=True)
    final.mkdir()
    (final / RECORD_FILE).write_text(json.dumps(record))
    return record


@pytest.fixture(scope="module")
def work(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("fuzz_batch")


_RECORDS = st.lists(st.one_of(mutations([RECORD]), values(), st.binary(max_size=40)), min_size=2, max_size=2)


@settings(max_examples=max(settings.default.max_examples // 4, 20) if settings.default.max_examples < 10_000
          else settings.default.max_examples)
@given(_RECORDS)
def test_resuming_over_damaged_records_runs_or_refuses(work: Path, records: list[Any]) -> None:
    """Resume over mutated, foreign or binary run records: whole records come back, or a ConfigError."""
    out = work / "out"
    shutil.rmtree(out, ignore_errors=True)
    plan = expand_plan(work / "m.yaml", seeds=range(2))
    whole: dict[str, bool] = {}
    for spec, data in zip(plan.runs, records, strict=True):
        run_dir = out / RUNS_DIR / spec.run_id
        run_dir.mkdir(parents=True)
        if isinstance(data, bytes):
            (run_dir / RECORD_FILE).write_bytes(data)
            whole[spec.run_id] = False
        else:
            if isinstance(data, dict) and data.get("run_id") == "":
                data = {**data, "run_id": spec.run_id}
            (run_dir / RECORD_FILE).write_text(json.dumps(data, allow_nan=True))
            whole[spec.run_id] = whole_record(json.loads(json.dumps(data, allow_nan=True)), spec.run_id)
    try:
        got = run_batch(plan, SerialEngine(), out, resume=True, fn=_rerun)
    except ConfigError:
        return
    assert [r.run_id for r in got] == [spec.run_id for spec in plan.runs]
    for record, spec in zip(got, plan.runs, strict=True):
        assert isinstance(record.status, str) and isinstance(record.seed, int)
        assert isinstance(record.robot_time_s, float | int) and math.isfinite(record.robot_time_s)
        if not whole[spec.run_id]:
            assert record.reason == "run again", "a record that is not whole is run again, not counted"
            assert (out / RUNS_DIR / f".{spec.run_id}{DAMAGED_SUFFIX}").is_dir(), "and kept aside"
        else:
            assert record.reason != "run again", "a whole record is kept"
    summary = summarize(got)
    format_table(summary)
    json.dumps(summary, allow_nan=False)
    write_results(got, out / "results.jsonl")
    write_junit(got, out / "junit.xml", "fuzz")
