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
- :class:`DaskEngine` — Dask distributed through ``Client.map(pure=False)`` (``pure=False``: identical
  tasks are not deduplicated), short runs several to a task (below). ``local`` starts a ``LocalCluster``
  with one thread per worker process; any other address connects to a running scheduler (``dask
  scheduler`` and ``dask worker tcp://HOST:8786``). A task whose worker died comes back as
  ``KilledWorker`` once the scheduler gives up on it (the local cluster gives up at the first death, so
  the batch's own single retry is the only one; a remote scheduler applies its own
  ``distributed.scheduler.allowed-failures`` first). Workers write run directories themselves: on a
  cluster of several machines the batch's ``--out`` must be on a filesystem they all share, and
  missiontree (with the plugins the mission needs) must be installed in every worker's environment.

A mission in a Dask worker used to cost 28 % more than in a pool worker (82.5 ms serial, 85.8 ms
pool, 106 ms Dask on an idle machine). Dask's defaults for long-lived data workers made the
difference; the local cluster changes them (:data:`LOCAL_CLUSTER_CONFIG`, applied through
``dask.config`` while it starts):

- The nanny starts each worker with ``MALLOC_TRIM_THRESHOLD_=65536``
  (``distributed.nanny.pre-spawn-environ``). Setting any of glibc's malloc thresholds also freezes
  its mmap threshold at 128 KiB, so every larger array (scan rasters, grids, camera frames) is
  mapped and unmapped at each allocation and its pages fault in again (measured in one process
  with and without the variable, before the runner pinned the threshold: 7.8 k against 1.7 k page
  faults a mission, 9 % more CPU in the mission's own thread). Since the runner pins that
  threshold itself in every engine (:mod:`missiontree.engine.native_memory`, for steady memory on
  long runs), the variable no longer changes a mission's cost; the local cluster still drops it
  (``None``), so a Dask worker's allocator is the pool's, and the nanny no longer leaks it into
  this process's environment (where every process spawned later would inherit it).
- The worker's statistical profiler samples the running task's stack every 10 ms
  (``distributed.worker.profile.enabled``), the event-loop health check wakes every 20 ms
  (``distributed.admin.tick.interval``) and the system monitor reads the process's and host's
  counters every 0.5 s (``distributed.admin.system-monitor.interval``); each wake takes the GIL
  from the mission. Measured on a loaded machine, with four single-worker engines running missions
  side by side, they cost 20-35 ms of CPU a mission beyond the mission's own thread; with the
  profiler off, the check every second and the monitor every 5 s, about 10 ms. They feed the
  dashboard, which a local batch does not start.
- Idle, a local cluster of two workers still took 25 ms of CPU a second (14 in this process, 11 in
  the workers; /proc over 20 s). The memory monitors of each worker and of its nanny (both
  ``distributed.worker.memory.monitor-interval``) ran every 100 ms, now every second (the nanny
  still restarts a worker past 95 % of its memory limit); work stealing and the active memory
  manager ran in the scheduler, now off (tasks wait in the scheduler's queue until a worker has
  room, so there is nothing to steal; results are gathered and released at once, so there are no
  replicas to drop). Idle it now takes 11.5 ms a second, about 5 of them the workers' heartbeats
  (every 0.5 s, which the scheduler sets by the number of workers; no setting changes it).
- ``distributed.scheduler.worker-saturation`` 1.0 (Dask's default 1.1 gives a one-thread worker a
  second task ahead): a worker is sent its next task when it finishes one, so the last tasks go to
  whichever worker is free first. Measured beside the default in alternating rounds (25 runs of
  0.1 s, load average 7-9): the batch's end (its last run done to the results gathered) 5.6 against
  93.5 ms, the tail (first worker done to last) 173 against 229 ms; the task boundaries cost
  slightly more (123 against 83 ms a round summed over both workers: the next task is not waiting).

Checked and left as it is: thread pools are pinned alike in pool and Dask workers (the
``OMP``/``OPENBLAS``/``NUMBA`` thread variables 1, ``numba.get_num_threads()`` 1, the same two
non-Python threads in both; a Dask worker adds only its own Python threads: event loop, executor,
parent monitor, the nanny's stop queue); a mission's own thread spends the same CPU in a Dask
worker as in a pool worker (``time.thread_time``, within the noise of 3 %); the 9 garbage
collections of a mission make Dask's collection callbacks negligible. A LocalCluster's nannies
are not processes: they are objects in this process's event loop, and the workers are this
process's children; ``worker_class=distributed.Worker`` would put the workers themselves in this
process (checked: one process id, so one GIL for every mission), and a cluster whose workers run
without nannies in their own processes (``SubprocessCluster``, experimental) does not replace a
worker a crashing mission killed. Moving the scheduler to its own process spends the same CPU on
the same cores.

The rest of Dask's cost is per task, in this process (the scheduler of a local cluster and the client
run here, on the cores the workers need): each task is a graph update, a scheduling decision, a result
sent back. For short runs (the 0.1 s missions of benchmarks/batch_scaling.py) that is a few per cent of
every run, so the engine sends them several to a task (``chunk``, default ``"auto"``), and sends them as
tasks finish, keeping two tasks a worker out (one running, one waiting in the scheduler's queue, so no
worker waits for the client): each chunk holds about :data:`CHUNK_S` seconds of runs (at most
:data:`MAX_CHUNK`), and no more than the runs left over one more than the workers, so the chunks shrink
to single runs at the end and no worker waits long for another (guided self-scheduling). Run times come
from the runs done: the lower quartile of the latest :data:`RECENT_RUNS` of the mission (a worker's
first run, slow with its imports, weighs little); with none known yet, or runs of :data:`SHORT_RUN_S`
and more, runs go one a task. The engine keeps those run times for each mission file
(:attr:`DaskEngine.run_seconds`, as Dask's scheduler keeps a duration for each kind of task), so a later
batch of that mission on the same engine (an evaluation's next world, a benchmark's next round) starts
with its chunks. Each task costs CPU in the scheduler, the client and its worker while the other
workers' missions run on the same cores: measured in one batch of 200 runs of 0.1 s on two workers,
chunks of 3 runs (67 tasks) made each mission 10 % slower than in the pool (117 against 105-108 ms),
chunks of 8 (27 tasks) about 3 % (106 against 103 ms, a separate run). The results of every task done
since the last look come back in one gather (``as_completed(...).batches()``; not ``with_results=True``,
whose concurrent gathers trip an assertion in tornado's stream writes under load and leave the batch
waiting forever). Each run in a chunk is still one :func:`~.worker.execute_run` (its own run directory,
record and seed: results are those of the pool); a run whose harness raises is its own crash; when a
chunk's worker dies, the runs it finished keep their records, the run it had begun is the crash (retried
once by the batch, alone) and the runs it had not begun are sent again, one a task. Retries
(``isolated``) always go one a task. The pool stays one run a task. A Dask task alone costs about 1.5 ms
of CPU in this process and 2 ms in its worker (100 tasks of a 50 ms sleep, load average 3-5; the
worker's share is its state machine and messages, seen with cProfile); beside two busy workers it costs
their missions several times that (above), which chunks share out. With the settings above (the previous
ones beside them in alternating rounds, 8 × 25 runs, load average 4-5, where the machine had no second
core to give: every engine near 1.0) the Dask engine read 1.01 (rounds median 1.01) against 0.99 (0.98)
and the pool 0.97 (0.96); CPU a run, workers and this process together, 131.3 against 132.2 ms, the pool
127.7, serial 121.1.

On a remote cluster the workers read their own configuration; to get the same speed set, in a
Dask config file on every worker machine (e.g. ``~/.config/dask/missiontree.yaml``) before starting
``dask worker``::

    distributed:
      nanny:
        pre-spawn-environ:
          MALLOC_TRIM_THRESHOLD_: null
      worker:
        profile:
          enabled: false
        memory:
          monitor-interval: 1s
      admin:
        tick:
          interval: 1s
        system-monitor:
          interval: 5s

and, for the scheduler (``dask scheduler``; these change how the cluster schedules every client's
work, so the engine never sets them on a cluster it did not start)::

    distributed:
      scheduler:
        worker-saturation: 1.0
        work-stealing: false

(or start the workers with ``--no-nanny``, giving up the nanny's restart of a dead worker).

Dask is an optional extra: importing this module never imports it; :class:`DaskEngine` raises a
:class:`~missiontree.errors.BackendUnavailableError` naming the extra when it is missing.
"""

from __future__ import annotations

import asyncio
import logging
import multiprocessing
import os
import statistics
from collections import deque
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from contextlib import suppress
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from missiontree.errors import BackendUnavailableError, ConfigError
from missiontree.evaluation.worker import RECORD_FILE, THREAD_ENV, RunTask, ignore_interrupts

__all__ = ["LOCAL_CLUSTER_CONFIG", "Crash", "DaskEngine", "Engine", "PoolEngine", "SerialEngine",
           "make_engine"]

Outcome = dict[str, Any]
TaskFn = Callable[[RunTask], Outcome]
DASK_EXTRA = "dask"
#: ``dask.config`` values a ``--dask local`` cluster starts with (see the module docstring).
LOCAL_CLUSTER_CONFIG: dict[str, Any] = {
    # a task whose worker died comes back at once; the batch retries it once
    "distributed.scheduler.allowed-failures": 0,
    # glibc's default (dynamic) mmap threshold: large arrays reuse the heap instead of faulting in
    "distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None,
    # no 10 ms stack sampling of the mission, no 20 ms event-loop wake-ups (no dashboard to feed)
    "distributed.worker.profile.enabled": False,
    "distributed.admin.tick.interval": "1s",
    "distributed.admin.system-monitor.interval": "5s",
    # the memory monitors (each worker's, and its nanny's here) every second, not every 100 ms
    "distributed.worker.memory.monitor-interval": "1s",
    # a worker is sent its next task when it finishes one (Dask's default 1.1 sends a second ahead): the
    # last runs go to whichever worker is free first, so a batch does not wait on a worker's backlog
    "distributed.scheduler.worker-saturation": 1.0,
    # tasks wait in the scheduler's queue until a worker has room (queuing): nothing to steal
    "distributed.scheduler.work-stealing": False,
    # results are gathered and released at once: no replicas for the active memory manager to drop
    "distributed.scheduler.active-memory-manager.start": False,
}
#: ``chunk="auto"``: runs shorter than this (wall seconds, lower quartile of the latest) go several a task.
SHORT_RUN_S = 0.5
#: ``chunk="auto"``: a chunk holds about this many seconds of runs (and at most MAX_CHUNK runs).
CHUNK_S = 1.0
MAX_CHUNK = 32
#: ``chunk="auto"``: how many of a mission's latest run times the engine keeps for its next batch.
RECENT_RUNS = 16


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
                _clear_partials(task)
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
                            _clear_partials(futures[future])
                            yield futures[future], Crash(f"{type(error).__name__}: {error}")
                            continue
                        yield futures[future], future.result()
                if broken:
                    self._drop_pool()
                    for future in pending:
                        task = futures[future]
                        if future.done() and future.exception() is None:
                            yield task, future.result()
                        elif _started(task):
                            _clear_partials(task)
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
        for future in [pool.submit(_warm, None) for _ in range(self.workers)]:
            future.result()

    def close(self) -> None:
        """Shut the pool down."""
        self._drop_pool()


class DaskEngine(Engine):
    """Dask distributed: a ``LocalCluster`` (``address="local"``) or a running scheduler.

    Args:
        address: ``local`` or the scheduler's address.
        workers: Worker processes of a local cluster (default: the cores).
        chunk: Runs per Dask task: ``"auto"`` (default) sends runs as tasks finish, in chunks sized
            from the run times seen (:attr:`run_seconds`; one run a task while none is known or runs
            are long; see the module docstring); a number fixes the chunk size, all sent at once
            (1: one run per task, always).
    """

    name = "dask"

    def __init__(self, address: str, workers: int | None = None, chunk: int | str = "auto") -> None:
        try:
            import dask
            from distributed import Client, LocalCluster
        except ImportError as error:
            raise BackendUnavailableError(
                f"--dask needs the '{DASK_EXTRA}' extra (Dask distributed), which is not installed "
                f"({error}); install it with: pip install 'missiontree[{DASK_EXTRA}]'") from None
        if chunk != "auto" and (isinstance(chunk, bool) or not isinstance(chunk, int) or chunk < 1):
            raise ConfigError(f"Dask chunk: expected 'auto' or a whole number >= 1, found {chunk!r}")
        self.address = address
        self.chunk = chunk
        #: Runs in each Dask task submitted so far, in order (for reports and tests).
        self.chunk_sizes: list[int] = []
        #: ``chunk="auto"``: wall seconds of the latest runs (:data:`RECENT_RUNS`) seen of each mission
        #: file, as Dask's scheduler keeps a duration for each kind of task; chunks are sized from their
        #: lower quartile (a worker's first run, or one slowed by the machine's load, weighs little).
        self.run_seconds: dict[str, deque[float]] = {}
        self.cluster: Any = None
        try:
            if address == "local":
                self.workers = max(1, workers or os.cpu_count() or 1)
                with dask.config.set(LOCAL_CLUSTER_CONFIG):
                    self.cluster = LocalCluster(n_workers=self.workers, threads_per_worker=1, processes=True,
                                                dashboard_address=None, env=dict(THREAD_ENV),
                                                # the scheduler's HTTP routes (health, metrics) start even
                                                # without a dashboard: on a free local port, not 8787
                                                # (taken by any other cluster: a warning at every start)
                                                scheduler_kwargs={"dashboard_address": "127.0.0.1:0"},
                                                silence_logs=logging.ERROR)
                self.client = Client(self.cluster)
            else:
                self.client = Client(address, timeout="20s")
                self.workers = max(1, sum(self.client.nthreads().values()))
        except OSError as error:
            self.close()
            raise ConfigError(f"--dask {address}: cannot reach the Dask scheduler ({error}); start one "
                              "with `dask scheduler` and workers with `dask worker tcp://HOST:8786`, "
                              "or use --dask local") from None

    def describe(self) -> dict[str, Any]:
        """The engine for reports, with the scheduler's address."""
        return {"name": self.name, "workers": self.workers, "address": self.address, "chunk": self.chunk}

    def run(self, fn: TaskFn, tasks: Iterable[RunTask], isolated: bool = False
            ) -> Iterator[tuple[RunTask, Outcome | Crash]]:
        """Run the tasks on the cluster, several runs a Dask task when they are short (``chunk``).

        ``isolated`` (the retry of crashed runs): one run a task, whatever ``chunk`` says.
        """
        from distributed import as_completed

        queue = list(tasks)
        recent = self.run_seconds.setdefault(queue[0].mission if queue else "", deque(maxlen=RECENT_RUNS))
        first: list[list[RunTask]] = []  # auto: none; chunks go as tasks finish (refill, below)
        if isolated or self.chunk == 1 or len(queue) <= self.workers:
            first, queue = [[task] for task in queue], []
        elif isinstance(self.chunk, int):
            first, queue = _guided_chunks(queue, self.workers, self.chunk), []
        running: dict[object, tuple[Any, list[RunTask]]] = {}  # (future, its runs) by key, until it is back

        def submit(chunks: list[list[RunTask]]) -> list[Any]:
            # one graph update for all of them (client.map), not one round trip a run
            futures = self.client.map(_run_chunk, [fn] * len(chunks), chunks, pure=False)
            self.chunk_sizes.extend(len(chunk) for chunk in chunks)
            for future, chunk in zip(futures, chunks, strict=True):
                running[future.key] = (future, chunk)
            return futures

        def refill() -> list[list[RunTask]]:
            # two tasks a worker out (one running, one waiting in the scheduler's queue for it)
            nonlocal queue
            chunks: list[list[RunTask]] = []
            while queue and len(running) + len(chunks) < 2 * self.workers:
                size = self._chunk_size(len(queue), recent)
                chunks.append(queue[:size])
                queue = queue[size:]
            return chunks

        pending = as_completed(submit(first + refill()))
        try:
            for batch in pending.batches():  # every task done since the last look: one gather for them
                for future, result, error in self._gathered(batch):
                    chunk = running.pop(future.key)[1]
                    if error is not None:
                        again: list[RunTask] = []
                        for task, outcome in _crashed_chunk(chunk, error):
                            if outcome is None:
                                again.append(task)
                            else:
                                yield task, outcome
                        if again:  # runs of a crashed chunk that had not begun: again, one by one
                            pending.update(submit([[task] for task in again]))
                    else:
                        recent.extend(_every_run_seconds(result))
                        yield from zip(chunk, result, strict=True)
                if queue:
                    pending.update(submit(refill()))
        finally:
            left = [future for future, _ in running.values() if not future.done()]
            if left:
                self.client.cancel(left)

    def _chunk_size(self, left: int, recent: deque[float]) -> int:
        """``chunk="auto"``: runs in the next task, from the run times seen and the runs ``left``.

        One while no run time is known or runs are long (the lower quartile of the latest at least
        :data:`SHORT_RUN_S`: a worker's first run, slow with its imports, weighs little); else about
        :data:`CHUNK_S` seconds of runs (at most :data:`MAX_CHUNK`), and no more than the runs left over
        one more than the workers (guided self-scheduling: the last tasks are small).
        """
        if not recent:
            return 1
        seconds = statistics.quantiles(recent, n=4, method="inclusive")[0] if len(recent) > 1 else recent[0]
        if seconds >= SHORT_RUN_S:
            return 1
        most = max(1, min(MAX_CHUNK, int(CHUNK_S / max(seconds, 1e-3))))
        return _guided_size(left, self.workers, most)

    def _gathered(self, batch: list[Any]) -> Iterator[tuple[Any, Any, BaseException | None]]:
        """(future, its result or None, its error or None) for done futures; one gather for the results."""
        finished = [future for future in batch if future.status == "finished"]
        results: dict[Any, Any] = {}
        if finished:
            try:
                results = dict(zip([f.key for f in finished], self.client.gather(finished), strict=True))
            except Exception:  # noqa: BLE001, S110 - a result lost meanwhile: each future on its own below
                pass
        for future in batch:
            result, error = results.get(future.key), None
            if future.key not in results:
                try:
                    result = future.result()
                except (Exception, asyncio.CancelledError) as failed:  # noqa: BLE001 - KilledWorker, ...
                    error = failed
            yield future, result, error

    def warm_up(self) -> None:
        """Import the mission engine on every worker of the cluster."""
        self.client.wait_for_workers(1)
        self.client.run(_warm, None)

    def close(self) -> None:
        """Close the client, and the local cluster when this engine started it.

        A local cluster closes as quietly as it ran: its log level is set again for the close, since
        a second local cluster closed before it (a benchmark's reference engine) has put Dask's
        handlers back to INFO, which printed a dozen lines of its shutdown.
        """
        client = getattr(self, "client", None)
        if self.cluster is None:
            if client is not None:
                client.close()
            return
        from distributed.utils import silence_logging_cmgr

        with silence_logging_cmgr(logging.ERROR):
            if client is not None:
                with suppress(Exception):  # a worker gone already: nothing of it to quiet
                    client.run(_stop_heartbeat, timeout="5s")  # no heartbeat in flight while they close
                client.close()
            self.cluster.close()
            self.cluster = None


def _run_chunk(fn: TaskFn, tasks: list[RunTask]) -> list[Outcome | Crash]:
    """A Dask task: the runs one after another in this worker; a run's harness error is its own Crash."""
    outcomes: list[Outcome | Crash] = []
    for task in tasks:
        try:
            outcomes.append(fn(task))
        except Exception as error:  # noqa: BLE001 - the harness failed, not the mission (disk full, ...)
            _clear_partials(task)
            outcomes.append(Crash(f"{type(error).__name__}: {error}"))
    return outcomes


def _crashed_chunk(chunk: list[RunTask], error: BaseException
                   ) -> Iterator[tuple[RunTask, Outcome | Crash | None]]:
    """What became of each run of a chunk whose Dask task failed (its worker died, mostly).

    A run that completed before the death keeps its record (its run directory is final); the run
    that had begun is the crash (a :class:`Crash`, retried once by the batch), and so is a task of
    one run (as before chunks: Dask cannot tell a run queued in the dead worker from one that died
    before writing anything); a run of a chunk that had not begun yet is ``None``: the engine
    submits it again, alone.
    """
    reason = _crash_reason(error)
    for task in chunk:
        done = _final_record(task)
        if done is not None:
            yield task, done
        elif len(chunk) == 1 or _started(task):
            _clear_partials(task)
            yield task, Crash(reason)
        else:
            yield task, None


def _crash_reason(error: BaseException) -> str:
    from distributed import KilledWorker

    if isinstance(error, KilledWorker):
        return f"the Dask worker died while running it (KilledWorker: {error})"
    return f"{type(error).__name__}: {error}"


def _final_record(task: RunTask) -> Outcome | None:
    import json

    try:
        path = Path(task.runs_dir) / task.spec.run_id / RECORD_FILE
        return dict(json.loads(path.read_text(encoding="utf-8")))
    except (OSError, ValueError):
        return None


def _every_run_seconds(outcomes: list[Outcome | Crash] | None) -> list[float]:
    """Wall seconds of every run among ``outcomes`` that has them."""
    return [max(float(outcome["wall_time_s"]), 1e-3) for outcome in outcomes or []
            if isinstance(outcome, dict) and isinstance(outcome.get("wall_time_s"), int | float)]


def _guided_size(left: int, workers: int, most: int) -> int:
    """Guided self-scheduling: the runs ``left`` over one more than the workers, rounded up, 1 to ``most``."""
    return max(1, min(most, -(-left // (workers + 1))))


def _guided_chunks(tasks: list[RunTask], workers: int, most: int) -> list[list[RunTask]]:
    """Consecutive chunks of at most ``most`` runs, shrinking to single runs at the end.

    Guided self-scheduling: each chunk holds the runs left over one more than the workers, rounded
    up, so the last tasks are small and no worker waits long for another to finish a big one; at most
    ``workers + 1`` runs go alone at the end. (Over twice the workers, rounded down, 23 runs on two
    workers took 12 tasks, the last 7 alone; now 7, the last 2 alone. Each task costs a few ms of
    CPU in the scheduler and its worker, and a worker waits for its next one.)
    """
    chunks: list[list[RunTask]] = []
    index = 0
    while index < len(tasks):
        size = _guided_size(len(tasks) - index, workers, most)
        chunks.append(tasks[index:index + size])
        index += size
    return chunks


def make_engine(dask: str | None, jobs: int | None) -> Engine:
    """The engine the flags ask for: ``--dask ADDRESS|local`` (or DASK_SCHEDULER_ADDRESS), else a pool."""
    address = dask or os.environ.get("DASK_SCHEDULER_ADDRESS") or None
    if address:
        return DaskEngine(address, jobs)
    return PoolEngine(jobs)


def _stop_heartbeat(dask_worker: Any) -> None:
    """Stop a worker's heartbeats before its cluster closes (run on the worker by ``client.run``).

    A heartbeat that is on its way when the scheduler closes fails, and the worker prints it as an
    error with a traceback (``Failed to communicate with scheduler during heartbeat``), about one
    close in ten, after a batch that went well.
    """
    dask_worker.periodic_callbacks["heartbeat"].stop()


def _warm(_: object) -> int:
    """Import what a run needs (in a worker); return the worker's process id."""
    from missiontree.evaluation.worker import pin_threads

    pin_threads()
    import missiontree.session  # noqa: F401 - the import is the point

    return os.getpid()


def _started(task: RunTask) -> bool:
    """Whether an attempt of this task created its staging directory (the worker had begun it)."""
    return any(Path(task.runs_dir).glob(f"{_glob_escape(task.partial_prefix())}*.{task.attempt}.partial"))


def _clear_partials(task: RunTask) -> None:
    import shutil

    for path in Path(task.runs_dir).glob(f"{_glob_escape(task.partial_prefix())}*.partial"):
        shutil.rmtree(path, ignore_errors=True)


def _glob_escape(text: str) -> str:
    import glob

    return glob.escape(text)
