"""Where a batch's runs execute: in this process, a local process pool, or a Dask cluster.

Every engine runs one mission per task and yields ``(task, outcome)`` as runs finish, where the
outcome is the run's record or a :class:`Crash` (the process running the mission died: a segfault,
``os._exit``, a killed worker; or the harness around the mission raised, e.g. a full disk — a
mission's own exceptions are records with status ERROR). The batch counts crashes apart and
retries each once, isolated (``isolated=True``: alone on a fresh worker, so a second crash is the
run's own and not a neighbour's).

- :class:`SerialEngine` — in this process, one after another (the reference of
  benchmarks/batch_scaling.py; a crash here ends the batch).
- :class:`PoolEngine` — ``concurrent.futures.ProcessPoolExecutor`` with spawned workers that pin
  their threads before importing anything numerical. When a worker dies the pool breaks for every
  task in it: the runs that had started (their staging directory exists) are reported as crashed,
  the others are simply submitted again to a new pool.
- :class:`~missiontree.evaluation.dask_engine.DaskEngine` — Dask distributed, a local cluster or a
  running scheduler, short runs several to a task (its own module: Dask is an optional extra).

:func:`~missiontree.evaluation.batch.make_engine` picks one from the command line's flags.
How the engines compare, and why the local Dask cluster is configured as it is: docs/performance.md.
"""

from __future__ import annotations

import multiprocessing
import os
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from missiontree.evaluation.worker import RECORD_FILE, RunTask, ignore_interrupts, load_record

__all__ = ["Crash", "Engine", "PoolEngine", "SerialEngine"]

Outcome = dict[str, Any]
TaskFn = Callable[[RunTask], Outcome]


@dataclass(frozen=True)
class Crash:
    """The process running a run died before the run finished.

    Attributes:
        reason: What the engine reported.
    """

    reason: str


class Engine:
    """Runs tasks, one mission each; see the module docstring."""

    name = "engine"
    workers = 1

    def run(self, fn: TaskFn, tasks: Iterable[RunTask], isolated: bool = False
            ) -> Iterator[tuple[RunTask, Outcome | Crash]]:
        """Run every task; yield each with its outcome as it finishes."""
        raise NotImplementedError

    def describe(self) -> dict[str, Any]:
        """The engine for reports."""
        return {"name": self.name, "workers": self.workers}

    def warm_up(self) -> None:
        """Start every worker and import the mission engine there (benchmarks time runs, not start-up)."""

    def close(self) -> None:
        """Release workers (idempotent)."""

    def __enter__(self) -> Engine:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class SerialEngine(Engine):
    """Every run in this process, one after another."""

    name = "serial"

    def run(self, fn: TaskFn, tasks: Iterable[RunTask], isolated: bool = False
            ) -> Iterator[tuple[RunTask, Outcome | Crash]]:
        """Run the tasks here, in order (``isolated`` changes nothing)."""
        for task in tasks:
            try:
                outcome: Outcome | Crash = fn(task)
            except Exception as error:  # noqa: BLE001 - the harness failed, not the mission
                clear_partials(task)
                outcome = Crash(f"{type(error).__name__}: {error}")
            yield task, outcome


class PoolEngine(Engine):
    """A local process pool (spawned workers, threads pinned), one mission per task."""

    name = "pool"

    def __init__(self, workers: int | None = None) -> None:
        self.workers = max(1, workers or os.cpu_count() or 1)
        self._context = multiprocessing.get_context("spawn")  # a clean interpreter: nothing loaded unpinned
        self._pool: ProcessPoolExecutor | None = None
        self._size = 0

    def _fresh_pool(self, size: int) -> ProcessPoolExecutor:
        if self._pool is not None and self._size == size:
            return self._pool
        self._drop_pool()
        self._pool = ProcessPoolExecutor(max_workers=size, mp_context=self._context,
                                         initializer=ignore_interrupts)
        self._size = size
        return self._pool

    def _drop_pool(self, kill: bool = False) -> None:
        pool, self._pool = self._pool, None
        if pool is None:
            return
        if kill:  # stop missions now (Ctrl-C): the pool's own shutdown would wait for them
            for process in list(getattr(pool, "_processes", {}).values()):  # stdlib internals, stable
                process.kill()
        pool.shutdown(wait=True, cancel_futures=True)

    def run(self, fn: TaskFn, tasks: Iterable[RunTask], isolated: bool = False
            ) -> Iterator[tuple[RunTask, Outcome | Crash]]:
        """Run the tasks on the pool (``isolated``: one worker, one task at a time)."""
        queue = list(tasks)
        # a running pool is kept (warm workers); a new one needs no more workers than tasks
        size = 1 if isolated else (self._size if self._pool is not None and self._size > 1
                                   else min(self.workers, max(1, len(queue))))
        ok = False
        try:
            while queue:
                pool = self._fresh_pool(size)
                futures: dict[Future[Outcome], RunTask] = {pool.submit(fn, t): t for t in queue}
                queue = []
                pending = set(futures)
                broken = False
                while pending and not broken:
                    done, pending = wait(pending, return_when=FIRST_COMPLETED)
                    for future in done:
                        error = future.exception()
                        if isinstance(error, BrokenProcessPool):
                            broken = True
                            pending.add(future)
                            continue
                        if error is not None:  # the harness failed, not the mission (disk full, ...)
                            clear_partials(futures[future])
                            yield futures[future], Crash(f"{type(error).__name__}: {error}")
                            continue
                        yield futures[future], future.result()
                if broken:
                    self._drop_pool()
                    for future in pending:
                        task = futures[future]
                        if future.done() and future.exception() is None:
                            yield task, future.result()
                        elif task_started(task):
                            clear_partials(task)
                            yield task, Crash("the worker process died while running it (BrokenProcessPool)")
                        else:
                            queue.append(task)
            ok = True
        finally:
            if not ok:
                self._drop_pool(kill=True)

    def warm_up(self) -> None:
        """Spawn the workers (their initialiser imports the session) and wait until each answered."""
        pool = self._fresh_pool(self.workers)
        for future in [pool.submit(warm_worker, None) for _ in range(self.workers)]:
            future.result()

    def close(self) -> None:
        """Shut the pool down."""
        self._drop_pool()


def warm_worker(_: object) -> int:
    """Import what a run needs (in a worker); return the worker's process id."""
    from missiontree.evaluation.worker import pin_threads

    pin_threads()
    import missiontree.session  # noqa: F401 - the import is the point

    return os.getpid()



def task_started(task: RunTask) -> bool:
    """Whether an attempt of this task created its staging directory (the worker had begun it)."""
    return any(Path(task.runs_dir).glob(f"{_glob_escape(task.partial_prefix())}*.{task.attempt}.partial"))


def clear_partials(task: RunTask) -> None:
    """Remove the staging directories an attempt of this task left (it did not finish)."""
    import shutil

    for path in Path(task.runs_dir).glob(f"{_glob_escape(task.partial_prefix())}*.partial"):
        shutil.rmtree(path, ignore_errors=True)


def _glob_escape(text: str) -> str:
    import glob

    return glob.escape(text)


def final_record(task: RunTask) -> Outcome | None:
    """The record a finished attempt of this task left in its run directory, or None."""
    data = load_record(Path(task.runs_dir) / task.spec.run_id / RECORD_FILE)
    return dict(data) if isinstance(data, dict) else None
