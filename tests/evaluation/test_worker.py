"""Tests of one batch run in a worker: atomic and idempotent, outcomes as records, threads pinned."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from missiontree.evaluation.plan import RunSpec
from missiontree.evaluation.worker import THREAD_ENV, RunTask, _pinned_models, execute_run, pin_threads
from missiontree.testing import clean_state

MISSION = """\
version: 1
params:
  wait: 0.3
run:
  backend: sim
  tick_hz: 10
  max_duration: 5
root:
  Wait: {seconds: "${wait}"}
"""


@pytest.fixture(autouse=True)
def _clean() -> None:
    clean_state()


def _task(tmp_path: Path, params: tuple[tuple[str, str], ...] = (), **request: object) -> RunTask:
    mission = tmp_path / "m.yaml"
    mission.write_text(MISSION, encoding="utf-8")
    (tmp_path / "runs").mkdir(exist_ok=True)
    return RunTask(spec=RunSpec(world=None, seed=4, run_seed=9, params=params), mission=str(mission),
                   runs_dir=str(tmp_path / "runs"), request=request)


def test_a_run_is_renamed_into_place_complete_and_not_run_twice(tmp_path: Path) -> None:
    """The run directory appears under its final name with record.json; a second attempt returns it as is."""
    task = _task(tmp_path)
    record = execute_run(task)
    final = tmp_path / "runs" / task.spec.run_id
    assert record["status"] == "SUCCESS" and record["run_seed"] == 9 and record["seed"] == 4
    assert {"record.json", "summary.json", "ticks.jsonl"} <= {p.name for p in final.iterdir()}
    assert [p.name for p in (tmp_path / "runs").iterdir()] == [task.spec.run_id]  # no staging left
    stamp = (final / "record.json").stat().st_mtime_ns
    assert execute_run(task.retry()) == record  # an engine's repeat: the complete run is returned
    assert (final / "record.json").stat().st_mtime_ns == stamp


def test_the_limit_is_a_result_with_its_reason(tmp_path: Path) -> None:
    """A mission stopped by max_duration is recorded (status RUNNING, stopped_by limit), not lost."""
    record = execute_run(_task(tmp_path, params=(("wait", "30"),)))
    assert (record["status"], record["stopped_by"]) == ("RUNNING", "limit")
    assert "max_duration" in record["reason"]
    assert record["robot_time_s"] == pytest.approx(5.0, abs=0.2)


def test_a_run_that_raises_is_an_error_record(tmp_path: Path) -> None:
    """A run whose session cannot open (a missing models file) is an ERROR record with the message."""
    record = execute_run(_task(tmp_path, models=str(tmp_path / "missing.yaml")))
    assert record["status"] == "ERROR" and record["stopped_by"] == "error"
    assert "missing.yaml" in record["reason"]


def test_models_get_one_onnx_thread_unless_given() -> None:
    """Providers taking 'threads' get 1 when the config leaves it out; a given value and others are kept."""
    pinned = _pinned_models(Path("unused.yaml"), "offline", None)
    assert pinned["roles"]["detector"]["threads"] == 1
    assert "threads" not in pinned["roles"]["vlm"]
    given = {"roles": {"detector": {"provider": "sim_detector", "threads": 3}}}
    assert _pinned_models(Path("unused.yaml"), given, None) is given


def test_pin_threads_sets_the_environment(monkeypatch: pytest.MonkeyPatch) -> None:
    """OMP, MKL, OpenBLAS and numba thread counts are 1 in a worker."""
    for name in THREAD_ENV:
        monkeypatch.setenv(name, "8")
    pin_threads()
    assert all(os.environ[name] == "1" for name in THREAD_ENV if name != "NUMBA_NUM_THREADS")


def test_pinning_in_a_process_that_runs_numba_leaves_its_thread_variable_alone() -> None:
    """A serial batch pins numba through its API: a changed NUMBA_NUM_THREADS would break compiles."""
    import numba
    import numpy as np

    @numba.njit(parallel=True, cache=False)
    def total(values: np.ndarray) -> float:
        result = 0.0
        for i in numba.prange(values.size):
            result += values[i]
        return result

    assert total(np.ones(8)) == 8.0  # launches numba's thread pool, as the simulator does
    before = os.environ.get("NUMBA_NUM_THREADS")
    pin_threads()
    assert os.environ.get("NUMBA_NUM_THREADS") == before
    assert numba.get_num_threads() == 1

    @numba.njit(cache=False)
    def twice(x: float) -> float:
        return 2 * x

    assert twice(2.0) == 4.0  # compiles: numba's environment check passes
