"""Tests of run_batch's bookkeeping with stand-in task functions (no missions): retries, resume, order."""

from __future__ import annotations

import json
import tracemalloc
from pathlib import Path
from typing import Any

import pytest

from missiontree.errors import ConfigError
from missiontree.evaluation.batch import INFRA, RUNS_DIR, complete_runs, make_engine, max_jobs, run_batch
from missiontree.evaluation.engines import SerialEngine
from missiontree.evaluation.plan import expand_plan
from missiontree.evaluation.worker import MAX_RECORD_BYTES, RECORD_FILE, RunTask

CALLS: list[tuple[int, int]] = []


def fake_run(task: RunTask) -> dict[str, Any]:
    """Seed 1 raises on every attempt, seed 2 on its first only; others write a complete run."""
    CALLS.append((task.spec.seed, task.attempt))
    if task.spec.seed == 1 or (task.spec.seed == 2 and task.attempt == 1):
        raise OSError("No space left on device")
    record = {"run_id": task.spec.run_id, "world": task.spec.world, "seed": task.spec.seed,
              "run_seed": task.spec.run_seed, "params": task.spec.params_dict, "status": "SUCCESS",
              "stopped_by": "status", "reason": "succeeded", "robot_time_s": 1.0, "wall_time_s": 0.01,
              "path_length_m": 0.0, "ticks": 10, "figures": {}, "attempt": task.attempt}
    final = Path(task.runs_dir) / task.spec.run_id
    final.mkdir()
    (final / RECORD_FILE).write_text(json.dumps(record))
    return record


@pytest.fixture(autouse=True)
def _calls() -> None:
    CALLS.clear()


def test_a_harness_error_is_retried_once_then_infra(tmp_path: Path) -> None:
    """A task failing around the mission twice is INFRA; once, it succeeds on its retry."""
    plan = expand_plan(tmp_path / "m.yaml", seeds=range(4))
    records = run_batch(plan, SerialEngine(), tmp_path / "out", fn=fake_run)
    assert [r.status for r in records] == ["SUCCESS", INFRA, "SUCCESS", "SUCCESS"]
    assert records[1].attempt == 2 and "No space left" in records[1].reason
    assert records[2].attempt == 2
    assert sorted(CALLS) == [(0, 1), (1, 1), (1, 2), (2, 1), (2, 2), (3, 1)]


def test_resume_skips_complete_runs_and_keeps_plan_order(tmp_path: Path) -> None:
    """A second batch with --resume runs only what is missing (the INFRA run), in plan order."""
    plan = expand_plan(tmp_path / "m.yaml", seeds=range(4))
    run_batch(plan, SerialEngine(), tmp_path / "out", fn=fake_run)
    CALLS.clear()
    seen: list[tuple[int, bool]] = []
    records = run_batch(plan, SerialEngine(), tmp_path / "out", resume=True, fn=fake_run,
                        on_record=lambda r, skipped: seen.append((r.seed, skipped)))
    assert [seed for seed, _ in CALLS] == [1, 1]
    assert sorted(seen) == [(0, True), (1, False), (2, True), (3, True)]
    assert [r.seed for r in records] == [0, 1, 2, 3]


def test_runs_in_out_need_resume_and_stale_partials_go(tmp_path: Path) -> None:
    """Without resume an out dir with runs is refused; a killed batch's .partial dirs are removed."""
    plan = expand_plan(tmp_path / "m.yaml", seeds=[0])
    run_batch(plan, SerialEngine(), tmp_path / "out", fn=fake_run)
    with pytest.raises(ConfigError, match="--resume"):
        run_batch(plan, SerialEngine(), tmp_path / "out", fn=fake_run)
    stale = tmp_path / "out" / RUNS_DIR / ".default_s0.123.1.partial"
    stale.mkdir()
    run_batch(plan, SerialEngine(), tmp_path / "out", resume=True, fn=fake_run)
    assert not stale.exists()


def test_a_cut_record_is_set_aside_and_its_run_done_again(tmp_path: Path) -> None:
    """On resume, a run whose record.json was cut short is run again; its directory is kept aside."""
    plan = expand_plan(tmp_path / "m.yaml", seeds=[0, 3])
    out = tmp_path / "out"
    run_batch(plan, SerialEngine(), out, fn=fake_run)
    cut = out / RUNS_DIR / plan.runs[1].run_id / RECORD_FILE
    cut.write_text(cut.read_text()[:40])
    CALLS.clear()
    records = run_batch(plan, SerialEngine(), out, resume=True, fn=fake_run)
    assert CALLS == [(3, 1)]
    assert [r.status for r in records] == ["SUCCESS", "SUCCESS"]
    assert (out / RUNS_DIR / f".{plan.runs[1].run_id}.damaged" / RECORD_FILE).is_file()


def test_an_oversized_record_is_not_read_whole_and_its_run_is_done_again(tmp_path: Path) -> None:
    """On resume a 64 MB record.json is refused by its size (not read into memory) and its run redone."""
    plan = expand_plan(tmp_path / "m.yaml", seeds=[0, 3])
    out = tmp_path / "out"
    run_batch(plan, SerialEngine(), out, fn=fake_run)
    big = out / RUNS_DIR / plan.runs[1].run_id / RECORD_FILE
    with big.open("r+b") as stream:
        stream.truncate(MAX_RECORD_BYTES * 16)          # sparse: no disk used
    tracemalloc.start()
    try:
        found = complete_runs(out)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert plan.runs[1].run_id not in found and plan.runs[0].run_id in found
    assert peak < MAX_RECORD_BYTES * 2
    CALLS.clear()
    records = run_batch(plan, SerialEngine(), out, resume=True, fn=fake_run)
    assert CALLS == [(3, 1)] and [r.status for r in records] == ["SUCCESS", "SUCCESS"]


def test_jobs_beyond_four_per_core_are_refused() -> None:
    """--jobs 10000 is a ConfigError naming the limit, not 10,000 processes."""
    with pytest.raises(ConfigError, match=r"--jobs: expected at most \d+ workers"):
        make_engine(None, 10_000)
    assert make_engine(None, max_jobs()).workers == max_jobs()
