"""Tests of batch runs on real engines: crashes, a killed and resumed batch, pool against Dask."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest

from missiontree.evaluation.batch import INFRA, RUNS_DIR, run_batch
from missiontree.evaluation.dask_engine import DaskEngine
from missiontree.evaluation.engines import PoolEngine, SerialEngine
from missiontree.evaluation.plan import expand_plan
from missiontree.evaluation.worker import RunTask, execute_run
from missiontree.testing import clean_state
from missiontree.testing_runs import observe_dask_chunks

WAIT_MISSION = """\
version: 1
params:
  wait: 0.3
run:
  backend: sim
  tick_hz: 10
  max_duration: 20
  realtime: {realtime}
root:
  Wait: {{seconds: "${{wait}}"}}
"""

NAV_MISSION = """\
version: 1
params:
  x: 6.5
run:
  backend: sim
  world: office
  tick_hz: 10
  max_duration: 40
root:
  NavigateTo: {x: "${x}", y: 3.6, timeout: 35}
"""


@pytest.fixture(autouse=True)
def _clean() -> None:
    clean_state()


def _mission(tmp_path: Path, text: str, name: str = "m.yaml") -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


# Task functions the engines run instead of execute_run: module level, so spawned workers import them.

def crash_seed_2_always_seed_1_once(task: RunTask) -> dict[str, Any]:
    """Seed 2's process dies every time; seed 1's only on its first attempt; the rest run normally."""
    if task.spec.seed == 2 or (task.spec.seed == 1 and task.attempt == 1):
        Path(task.runs_dir, f".{task.spec.run_id}.{os.getpid()}.{task.attempt}.partial").mkdir()
        os._exit(3)  # noqa: SLF001 - a process dying without cleanup is what is tested
    return execute_run(task)


def kill_own_process_on_seed_0(task: RunTask) -> dict[str, Any]:
    """Seed 0's worker kills itself with SIGKILL (a killed Dask worker)."""
    if task.spec.seed == 0:
        os.kill(os.getpid(), signal.SIGKILL)
    return execute_run(task)


@pytest.mark.slow
def test_a_run_that_crashes_its_process_is_an_infrastructure_failure(tmp_path: Path) -> None:
    """Pool: a run dying twice is INFRA (retried once), one dying once succeeds on retry, others untouched."""
    plan = expand_plan(_mission(tmp_path, WAIT_MISSION.format(realtime="false")), seeds=range(5))
    with PoolEngine(2) as engine:
        records = run_batch(plan, engine, tmp_path / "out", fn=crash_seed_2_always_seed_1_once)
    by_seed = {r.seed: r for r in records}
    assert [r.seed for r in records] == [0, 1, 2, 3, 4]
    assert by_seed[2].status == INFRA and by_seed[2].attempt == 2 and by_seed[2].run_dir is None
    assert "retried once" in by_seed[2].reason
    assert by_seed[1].status == "SUCCESS" and by_seed[1].attempt == 2
    assert all(by_seed[s].status == "SUCCESS" for s in (0, 3, 4))
    runs = tmp_path / "out" / RUNS_DIR
    assert sorted(p.name for p in runs.iterdir()) == sorted(r.run_id for r in records if r.status != INFRA)


@pytest.mark.slow
def test_a_killed_dask_worker_is_an_infrastructure_failure(tmp_path: Path) -> None:
    """Dask LocalCluster: a task whose worker is SIGKILLed twice comes back as INFRA; the others succeed."""
    import cloudpickle

    cloudpickle.register_pickle_by_value(sys.modules[__name__])  # Dask workers cannot import test modules
    plan = expand_plan(_mission(tmp_path, WAIT_MISSION.format(realtime="false")), seeds=range(3))
    with DaskEngine("local", 2) as engine:
        records = run_batch(plan, engine, tmp_path / "out", fn=kill_own_process_on_seed_0)
    assert [r.status for r in records] == [INFRA, "SUCCESS", "SUCCESS"]
    assert "KilledWorker" in records[0].reason


def _comparable(path: Path) -> list[dict[str, Any]]:
    lines = [json.loads(line) for line in path.read_text().splitlines()]
    for line in lines:
        line.pop("wall_time_s")
        line.get("figures", {}).pop("profile", None)  # CPU times measured in the run's own process
    return lines


@pytest.mark.slow
def test_pool_dask_and_serial_give_the_same_results(tmp_path: Path) -> None:
    """The same small navigation batch on the three engines: results.jsonl equal apart from measured times."""
    from missiontree.evaluation.report import write_results

    mission = _mission(tmp_path, NAV_MISSION)
    plan = expand_plan(mission, seeds=[0, 1], sweeps={"x": ["6.5", "3.5"]})
    outputs = {}
    engines = (("pool", PoolEngine(2)), ("dask", DaskEngine("local", 2)), ("serial", SerialEngine()),
               ("dask_chunks", DaskEngine("local", 1, chunk=3)))
    chunked = observe_dask_chunks(engines[3][1])
    for name, engine in engines:
        with engine:
            records = run_batch(plan, engine, tmp_path / name)
        write_results(records, tmp_path / name / "results.jsonl")
        outputs[name] = _comparable(tmp_path / name / "results.jsonl")
    assert len(outputs["pool"]) == 4
    assert all(r["status"] == "SUCCESS" and r["path_length_m"] > 0.5 for r in outputs["pool"])
    assert {r["robot_time_s"] for r in outputs["pool"]} != {outputs["pool"][0]["robot_time_s"]}  # x matters
    assert outputs["pool"] == outputs["dask"] == outputs["serial"] == outputs["dask_chunks"]
    assert chunked == [2, 1, 1]  # several runs in one Dask task change nothing


def kill_own_process_on_seed_1(task: RunTask) -> dict[str, Any]:
    """Seed 1's worker kills itself with SIGKILL, every attempt."""
    if task.spec.seed == 1:
        Path(task.runs_dir, f".{task.spec.run_id}.{os.getpid()}.{task.attempt}.partial").mkdir()
        os.kill(os.getpid(), signal.SIGKILL)
    return execute_run(task)


@pytest.mark.slow
def test_a_chunk_whose_worker_dies_keeps_its_finished_runs_and_runs_the_rest_one_by_one(
        tmp_path: Path) -> None:
    """Dask chunks of 4 runs: the run that killed its worker is the crash (INFRA after its retry).

    The chunk's run finished before it keeps its record; the ones after it run again alone, as first
    attempts.
    """
    import cloudpickle

    cloudpickle.register_pickle_by_value(sys.modules[__name__])
    plan = expand_plan(_mission(tmp_path, WAIT_MISSION.format(realtime="false")), seeds=range(7))
    with DaskEngine("local", 1, chunk=4) as engine:
        sizes = observe_dask_chunks(engine)
        records = run_batch(plan, engine, tmp_path / "out", fn=kill_own_process_on_seed_1)
    assert [r.status for r in records] == ["SUCCESS", INFRA, "SUCCESS", "SUCCESS", "SUCCESS", "SUCCESS",
                                           "SUCCESS"]
    assert "KilledWorker" in records[1].reason and records[1].attempt == 2
    assert [r.attempt for r in records[:4] if r.status == "SUCCESS"] == [1, 1, 1]  # seed 0 ran once
    assert sizes[:3] == [4, 2, 1] and sizes.count(1) >= 4  # 6 alone, 2 and 3 again alone, 1's retry
    runs = tmp_path / "out" / RUNS_DIR
    assert sorted(p.name for p in runs.iterdir()) == sorted(r.run_id for r in records if r.status != INFRA)


@pytest.mark.slow
def test_dask_auto_chunks_short_runs_after_two_runs_per_worker(tmp_path: Path,
                                                                monkeypatch: pytest.MonkeyPatch) -> None:
    """chunk="auto": two first runs per worker alone; short runs then go several to a task, the last alone.

    Long runs stay one a task. A later batch of the same mission starts from the run time the engine
    saw, without the single runs. ("Short" is moved for each batch, so the machine's load does not
    decide.)
    """
    from missiontree.evaluation import dask_engine

    plan = expand_plan(_mission(tmp_path, WAIT_MISSION.format(realtime="false")), seeds=range(12))
    with DaskEngine("local", 2) as engine:
        sizes = observe_dask_chunks(engine)
        monkeypatch.setattr(dask_engine, "SHORT_RUN_S", 60.0)
        monkeypatch.setattr(dask_engine, "CHUNK_S", 600.0)  # chunks as large as guided scheduling allows
        records = run_batch(plan, engine, tmp_path / "short")
        short = list(sizes)
        sizes.clear()
        monkeypatch.setattr(dask_engine, "SHORT_RUN_S", 0.0)
        long_records = run_batch(plan, engine, tmp_path / "long")
        long = list(sizes)
        sizes.clear()
        monkeypatch.setattr(dask_engine, "SHORT_RUN_S", 60.0)
        again = run_batch(plan, engine, tmp_path / "again")  # the engine has seen this mission's runs
        known = list(sizes)
        sizes.clear()
        (recent,) = engine.run_seconds.values()
        recent.append(120.0)  # one run slowed by the machine: the median of the latest decides
        run_batch(plan, engine, tmp_path / "outlier")
        after_outlier = sizes
    assert all(r.status == "SUCCESS" for r in records + long_records + again) and len(again) == 12
    assert short[:4] == [1, 1, 1, 1] and sum(short) == 12
    assert short == [1, 1, 1, 1, 3, 2, 1, 1, 1]  # 8 left: 8 over 3 rounded up, ..., the last 3 alone
    assert long == [1] * 12
    assert known == [4, 3, 2, 1, 1, 1]  # no single runs first: chunked from the run time seen
    assert after_outlier == known


@pytest.mark.slow
def test_a_killed_batch_resumes_without_repeating_or_losing_runs(tmp_path: Path) -> None:
    """SIGKILL the whole batch mid-way: no half run under a final name; --resume runs only the rest."""
    mission = _mission(tmp_path, WAIT_MISSION.format(realtime="true").replace("wait: 0.3", "wait: 1.5"))
    out = tmp_path / "out"
    command = [sys.executable, "-m", "missiontree.cli.main", "batch", str(mission), "--seeds", "0-7",
               "--jobs", "2", "--out", str(out), "--quiet"]
    process = subprocess.Popen(command, start_new_session=True, stdout=subprocess.DEVNULL,
                               stderr=subprocess.DEVNULL)
    runs = out / RUNS_DIR
    deadline = time.monotonic() + 240
    while time.monotonic() < deadline:
        done = [p for p in runs.glob("[!.]*")] if runs.is_dir() else []
        if len(done) >= 2:
            break
        assert process.poll() is None, "the batch ended before it could be killed"
        time.sleep(0.05)
    os.killpg(process.pid, signal.SIGKILL)
    process.wait(timeout=30)
    time.sleep(0.5)
    complete = {p.name: (p / "record.json").stat().st_mtime_ns
                for p in runs.iterdir() if not p.name.startswith(".")}
    assert 2 <= len(complete) < 8
    assert all((runs / name / "record.json").is_file() for name in complete)  # no half run under a final name
    assert not (out / "results.jsonl").exists()

    again = subprocess.run([*command[:-1], "--resume", "--quiet"], capture_output=True, text=True,
                           timeout=300)
    assert again.returncode == 0, again.stderr + again.stdout
    records = [json.loads(line) for line in (out / "results.jsonl").read_text().splitlines()]
    assert [r["seed"] for r in records] == list(range(8))  # every run once, in plan order
    assert all(r["status"] == "SUCCESS" for r in records)
    for name, mtime in complete.items():  # runs complete before the kill were not run again
        assert (runs / name / "record.json").stat().st_mtime_ns == mtime
    assert not list(runs.glob(".*"))  # the killed batch's partial runs are gone
    assert len(list(runs.iterdir())) == 8


class TruthProbe:
    """Counts ticks and keeps the simulator's true final x (a probe as evaluation benchmarks write them)."""

    def __init__(self) -> None:
        self.ticks = 0
        self.x = float("nan")

    def on_tick(self, session: Any) -> None:
        self.ticks += 1
        self.x = session.robot.truth.robot_pose().x

    def finish(self, session: Any, result: Any) -> dict[str, Any]:
        log = (session.run_dir / "ticks.jsonl").read_text().splitlines()
        return {"probe_ticks": self.ticks, "true_x": self.x, "log_lines": len(log)}


@pytest.mark.slow
def test_a_probe_scores_each_run_inside_its_worker(tmp_path: Path) -> None:
    """A probe built in the worker sees every tick and the finished run; its figures reach the record."""
    plan = expand_plan(_mission(tmp_path, NAV_MISSION), seeds=[0], sweeps={"x": ["3.5", "6.5"]})
    with PoolEngine(2) as engine:
        records = run_batch(plan, engine, tmp_path / "out", probe=TruthProbe)
    for record, goal in zip(records, (3.5, 6.5), strict=True):
        assert record.status == "SUCCESS"
        assert record.figures["probe_ticks"] == record.ticks
        assert record.figures["true_x"] == pytest.approx(goal, abs=0.3)
        assert record.figures["log_lines"] > record.ticks / 2
        summary = json.loads((tmp_path / "out" / record.run_dir / "summary.json").read_text())
        assert record.figures["true_x"] == pytest.approx(summary["true_final_pose"]["x"], abs=1e-6)


def _worker_settings(dask_worker: Any) -> dict[str, Any]:
    """What a Dask worker runs besides its task (run on the worker by Client.run)."""
    return {"malloc_trim": os.environ.get("MALLOC_TRIM_THRESHOLD_"),
            "omp_threads": os.environ.get("OMP_NUM_THREADS"),
            "callbacks": sorted(dask_worker.periodic_callbacks),
            "tick_ms": dask_worker.periodic_callbacks["tick"].callback_time,
            "memory_monitor_ms": dask_worker.periodic_callbacks["memory_monitor"].callback_time}


def _scheduler_settings(dask_scheduler: Any) -> dict[str, Any]:
    """What the local cluster's scheduler runs besides scheduling (run by Client.run_on_scheduler)."""
    return {"stealing": "stealing" in dask_scheduler.extensions,
            "saturation": dask_scheduler.WORKER_SATURATION,
            "amm_running": dask_scheduler.extensions["amm"].running}


@pytest.mark.slow
def test_a_local_dask_cluster_runs_missions_without_the_profiler_or_a_frozen_malloc(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """--dask local: no MALLOC_TRIM_THRESHOLD_ in the workers (nor leaked here), no 10 ms profiler."""
    import cloudpickle

    monkeypatch.delenv("MALLOC_TRIM_THRESHOLD_", raising=False)
    cloudpickle.register_pickle_by_value(sys.modules[__name__])
    with DaskEngine("local", 1) as engine:
        settings = list(engine.client.run(_worker_settings).values())
        scheduler = engine.client.run_on_scheduler(_scheduler_settings)
    assert scheduler == {"stealing": False, "saturation": 1.0, "amm_running": False}
    assert len(settings) == 1
    assert settings[0]["memory_monitor_ms"] >= 1000
    assert settings[0]["malloc_trim"] is None
    assert settings[0]["omp_threads"] == "1"
    assert "profile" not in settings[0]["callbacks"]
    assert "heartbeat" in settings[0]["callbacks"]  # the worker's own callbacks were read
    assert settings[0]["tick_ms"] >= 1000
    assert "MALLOC_TRIM_THRESHOLD_" not in os.environ
