"""Run a batch plan on an engine: :func:`run_batch` → one :class:`RunRecord` per run, in plan order.

The Python API of batch evaluation (``missiontree batch`` and the evaluation benchmarks call it)::

    from missiontree.evaluation import expand_plan, run_batch, PoolEngine
    plan = expand_plan(Path("trees/patrol.yaml"), seeds=range(10), worlds=["office"])
    with PoolEngine(2) as engine:
        records = run_batch(plan, engine, out=Path("runs/batch/patrol"))

Layout of ``out``::

    out/batch.json             the plan
    out/runs/<run id>/         one complete run: record.json, summary.json, ticks.jsonl, pictures
    out/runs/.<run id>.*.partial   a run in progress (never left behind by a finished batch)
    out/results.jsonl          one record a line, plan order (written by the caller, see report)
    out/batch.lock             the pid of the batch using the directory (while it runs)

One batch at a time uses a directory (:func:`lock_batch`): a second batch into the same ``out``
is refused with a :class:`~missiontree.errors.ConfigError` naming the first one's pid, so two
batches never both report while one's results replace the other's. A lock left by a batch that
died is taken over.

A run whose directory is complete is never run again with ``resume=True``; stale ``.partial``
directories of a killed batch are removed first, and a planned run's directory whose record is not
whole (cut, edited, another version's) is set aside as ``.<run id>.damaged`` and run again. A
crashed run (:class:`~.engines.Crash`) is retried once, isolated; crashing again, it is recorded as
an infrastructure failure (``status: INFRA``), counted apart from the mission's own results and not
written as a run (a later ``resume`` tries it again).
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
from collections.abc import Callable, Iterable, Iterator
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from missiontree.errors import ConfigError
from missiontree.evaluation.engines import Crash, Engine, PoolEngine
from missiontree.evaluation.plan import BatchPlan
from missiontree.evaluation.worker import (
    PARTIAL_SUFFIX,
    RECORD_FILE,
    Probe,
    RunTask,
    execute_run,
    load_record,
    whole_record,
)
from missiontree.file_limits import read_text_bounded
from missiontree.session.rundir import pid_alive

__all__ = ["BATCH_LOCK", "INFRA", "RUNS_DIR", "RunRecord", "complete_runs", "lock_batch", "run_batch"]

RUNS_DIR = "runs"
#: The lock file of a batch directory, holding the pid of the batch using it.
BATCH_LOCK = "batch.lock"
#: The status of a run lost to infrastructure (its process died twice).
INFRA = "INFRA"
#: Where a planned run's directory without a whole record is set aside (``.<run id>.damaged``) before
#: the run is done again: a record cut by a killed process or edited by hand is not a result.
DAMAGED_SUFFIX = ".damaged"


@dataclass
class RunRecord:
    """One line of ``results.jsonl``.

    Attributes:
        run_id: The run directory's name.
        world: The world (None: the mission's own).
        seed: The batch seed; ``run_seed`` the mission's seed.
        params: The mission's parameter values for this run (as given, text).
        status: SUCCESS, FAILURE, RUNNING (stopped by the limit), ERROR (the run raised) or INFRA.
        stopped_by: ``status``, ``limit``, ``signal``, ``error`` or ``crash``.
        reason: Why it stopped, one line.
        robot_time_s: Robot-clock seconds the mission ran.
        wall_time_s: Wall seconds in the worker (varies between machines and engines).
        path_length_m: Length of the robot's path.
        ticks: Ticks done.
        figures: The mission's own figures: its event counts, summary extras, a probe's figures.
        attempt: 2 when the run was retried after a crash.
        run_dir: The run directory, relative to the batch's ``out`` (None for INFRA).
    """

    run_id: str
    world: str | None
    seed: int
    run_seed: int
    params: dict[str, str]
    status: str
    stopped_by: str
    reason: str
    robot_time_s: float
    wall_time_s: float
    path_length_m: float
    ticks: int
    figures: dict[str, Any] = field(default_factory=dict)
    attempt: int = 1
    run_dir: str | None = None

    @property
    def passed(self) -> bool:
        """The mission succeeded."""
        return self.status == "SUCCESS"

    @property
    def infra(self) -> bool:
        """Lost to infrastructure (not a result of the mission)."""
        return self.status == INFRA

    def to_json(self) -> dict[str, Any]:
        """The record as JSON data."""
        return asdict(self)

    @classmethod
    def from_outcome(cls, data: dict[str, Any], run_dir: str | None) -> RunRecord:
        """A record from a worker's outcome (extra keys such as a traceback are dropped)."""
        names = set(cls.__dataclass_fields__)
        return cls(**{k: v for k, v in data.items() if k in names and k != "run_dir"}, run_dir=run_dir)


def complete_runs(out: Path) -> dict[str, dict[str, Any]]:
    """Run id → record of every complete run under ``out/runs`` (a whole record: see ``whole_record``)."""
    runs: dict[str, dict[str, Any]] = {}
    runs_dir = out / RUNS_DIR
    if not runs_dir.is_dir():
        return runs
    for path in runs_dir.iterdir():
        if path.name.startswith("."):
            continue
        data = load_record(path / RECORD_FILE)   # bounded; unreadable or not JSON: None
        if whole_record(data, path.name):
            runs[path.name] = data
    return runs


def _set_aside_damaged(runs_dir: Path, damaged: list[str]) -> None:
    """Move each run directory without a whole record to ``.<run id>.damaged`` (kept, run again)."""
    for run_id in damaged:
        aside = runs_dir / f".{run_id}{DAMAGED_SUFFIX}"
        shutil.rmtree(aside, ignore_errors=True)
        os.rename(runs_dir / run_id, aside)


def _lock_holder(lock: Path) -> int | None:
    try:
        return int(read_text_bounded(lock, 64, "batch lock file").strip() or "x")
    except (OSError, ValueError):   # too large (a pid is a few digits), unreadable, not a number
        return None


@contextlib.contextmanager
def lock_batch(out: Path) -> Iterator[None]:
    """Hold ``out/batch.lock`` while the block runs (this process may hold it already: then nothing).

    Raises:
        ConfigError: Another live process holds the lock, or the lock cannot be written.
    """
    out = Path(out)
    lock = out / BATCH_LOCK
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise ConfigError(f"cannot create the batch directory {out}: {error.strerror or error}") from error
    for _attempt in range(3):
        try:
            fd = os.open(lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
        except FileExistsError:
            holder = _lock_holder(lock)
            if holder == os.getpid():  # the CLI locked, then run_batch asks again
                yield
                return
            if holder is not None and pid_alive(holder):
                raise ConfigError(
                    f"batch directory {out} is in use by another batch (pid {holder}, lock file {lock}); "
                    "wait for it to end or choose another --out") from None
            with contextlib.suppress(FileNotFoundError):  # stale: its batch died without releasing
                lock.unlink()
            continue
        except OSError as error:
            raise ConfigError(
                f"cannot write in the batch directory {out}: {error.strerror or error}") from error
        with os.fdopen(fd, "w", encoding="utf-8") as stream:
            stream.write(f"{os.getpid()}\n")
        if _lock_holder(lock) != os.getpid():  # another batch took over the same stale lock first
            continue
        try:
            yield
        finally:
            if _lock_holder(lock) == os.getpid():
                with contextlib.suppress(OSError):
                    lock.unlink()
        return
    raise ConfigError(f"batch directory {out}: could not take its lock file {lock}; try again")


def run_batch(
    plan: BatchPlan,
    engine: Engine,
    out: Path,
    resume: bool = False,
    probe: Callable[[], Probe] | None = None,
    write_log: bool = True,
    on_record: Callable[[RunRecord, bool], None] | None = None,
    fn: Callable[[RunTask], dict[str, Any]] = execute_run,
) -> list[RunRecord]:
    """Run every run of ``plan`` not already complete in ``out``; return all records in plan order.

    Args:
        plan: The runs.
        engine: Where they run.
        out: The batch directory (created).
        resume: Keep complete runs found in ``out`` (else ``out`` must hold none).
        probe: A picklable factory of a probe that scores each run in its worker.
        write_log: Keep each run's ``ticks.jsonl``.
        on_record: Called with each record as it arrives and whether it was skipped (complete already).
        fn: The task function (tests swap in one that crashes).

    Raises:
        ConfigError: ``out`` holds runs and ``resume`` is false, or another batch is using ``out``.
    """
    with lock_batch(Path(out)):
        return _run_batch(plan, engine, Path(out), resume, probe, write_log, on_record, fn)


def _run_batch(
    plan: BatchPlan,
    engine: Engine,
    out: Path,
    resume: bool,
    probe: Callable[[], Probe] | None,
    write_log: bool,
    on_record: Callable[[RunRecord, bool], None] | None,
    fn: Callable[[RunTask], dict[str, Any]],
) -> list[RunRecord]:
    runs_dir = out / RUNS_DIR
    runs_dir.mkdir(parents=True, exist_ok=True)
    for stale in runs_dir.glob(f".*{PARTIAL_SUFFIX}"):  # half runs of a killed batch
        shutil.rmtree(stale, ignore_errors=True)
    found = complete_runs(out)
    wanted = {spec.run_id for spec in plan.runs}
    damaged = sorted(run_id for run_id in wanted - set(found) if (runs_dir / run_id).is_dir())
    if (found or damaged) and not resume:  # nothing in --out is replaced without being asked
        also = f" and {len(damaged)} without a whole record" if damaged else ""
        raise ConfigError(f"{out} already holds {len(found)} complete run(s){also}; pass --resume to keep "
                          "them and run the rest (a run without a whole record is set aside and run "
                          "again), or choose another --out")
    _set_aside_damaged(runs_dir, damaged)
    (out / "batch.json").write_text(json.dumps(plan.describe(), indent=2, sort_keys=True) + "\n",
                                    encoding="utf-8")
    records: dict[str, RunRecord] = {}
    for run_id, data in found.items():
        if run_id in wanted:
            records[run_id] = RunRecord.from_outcome(data, f"{RUNS_DIR}/{run_id}")
            if on_record is not None:
                on_record(records[run_id], True)
    request = {**plan.request}
    tasks = [RunTask(spec=spec, mission=str(Path(plan.mission).resolve()), runs_dir=str(runs_dir.resolve()),
                     request=request, probe=probe, write_log=write_log)
             for spec in plan.runs if spec.run_id not in records]
    retries: list[RunTask] = []

    def take(outcomes: Iterable[tuple[RunTask, dict[str, Any] | Crash]]) -> None:
        for task, outcome in outcomes:
            if isinstance(outcome, Crash):
                if task.attempt == 1:
                    retries.append(task.retry())
                    continue
                record = RunRecord(
                    run_id=task.spec.run_id, world=task.spec.world, seed=task.spec.seed,
                    run_seed=task.spec.run_seed, params=task.spec.params_dict, status=INFRA,
                    stopped_by="crash", reason=f"{outcome.reason} (twice: retried once)", robot_time_s=0.0,
                    wall_time_s=0.0, path_length_m=0.0, ticks=0, attempt=task.attempt)
            else:
                record = RunRecord.from_outcome(outcome, f"{RUNS_DIR}/{task.spec.run_id}")
            records[record.run_id] = record
            if on_record is not None:
                on_record(record, False)

    take(engine.run(fn, tasks))
    if retries:
        take(engine.run(fn, retries, isolated=True))
    return [records[spec.run_id] for spec in plan.runs]


def max_jobs() -> int:
    """Most workers a batch starts: four per core (more only queue for the cores, each a process)."""
    return 4 * (os.cpu_count() or 1)


def make_engine(dask: str | None, jobs: int | None) -> Engine:
    """The engine the flags ask for: ``--dask ADDRESS|local`` (or DASK_SCHEDULER_ADDRESS), else a pool.

    Raises:
        ConfigError: ``jobs`` is more than :func:`max_jobs` (``--jobs 10000`` would start one process
            per run).
    """
    if jobs is not None and jobs > max_jobs():
        raise ConfigError(f"--jobs: expected at most {max_jobs()} workers (four per core, "
                          f"{os.cpu_count() or 1} cores here), found {jobs}")
    address = dask or os.environ.get("DASK_SCHEDULER_ADDRESS") or None
    if address:
        from missiontree.evaluation.dask_engine import DaskEngine  # Dask is optional: only when asked for

        return DaskEngine(address, jobs)
    return PoolEngine(jobs)
