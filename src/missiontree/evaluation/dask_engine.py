"""Batch runs on Dask distributed: a local cluster, or a running scheduler.

:class:`DaskEngine` runs missions through ``Client.map(pure=False)`` (``pure=False``: identical
tasks are not deduplicated), short runs several to a task. ``local`` starts a ``LocalCluster`` with
one thread per worker process and :data:`LOCAL_CLUSTER_CONFIG`; any other address connects to a
running scheduler (``dask scheduler`` and ``dask worker tcp://HOST:8786``). A task whose worker died
comes back as ``KilledWorker`` once the scheduler gives up on it (the local cluster gives up at the
first death, so the batch's own single retry is the only one). Workers write run directories
themselves: on a cluster of several machines the batch's ``--out`` must be on a filesystem they all
share, and missiontree (with the plugins the mission needs) must be installed in every worker's
environment.

Short runs go several to a task (``chunk``, default ``"auto"``), sent as tasks finish, two tasks a
worker out: each chunk holds about :data:`CHUNK_S` seconds of runs (at most :data:`MAX_CHUNK`), and no
more than the runs left over one more than the workers, so the chunks shrink to single runs at the end
(guided self-scheduling). Run times come from the runs done: the lower quartile of the latest
:data:`RECENT_RUNS` of the mission, kept per mission file (:attr:`DaskEngine.run_seconds`) so a later
batch of that mission starts with its chunks; with none known yet, or runs of :data:`SHORT_RUN_S` and
more, runs go one a task. Each run in a chunk is still one :func:`~.worker.execute_run` (its own run
directory, record and seed); when a chunk's worker dies, the runs it finished keep their records, the
run it had begun is the crash and the runs it had not begun are sent again, one a task. Retries
(``isolated``) always go one a task. Why these settings, and what they were measured to cost:
docs/performance.md.

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
import os
import statistics
from collections import deque
from collections.abc import Iterable, Iterator
from contextlib import suppress
from typing import Any

from missiontree.errors import BackendUnavailableError, ConfigError
from missiontree.evaluation.engines import (
    Crash,
    Engine,
    Outcome,
    TaskFn,
    clear_partials,
    final_record,
    task_started,
    warm_worker,
)
from missiontree.evaluation.worker import THREAD_ENV, RunTask

__all__ = ["LOCAL_CLUSTER_CONFIG", "DaskEngine", "guided_chunks"]

DASK_EXTRA = "dask"
#: ``dask.config`` values a ``--dask local`` cluster starts with (why: docs/performance.md).
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
            first, queue = guided_chunks(queue, self.workers, self.chunk), []
        running: dict[object, tuple[Any, list[RunTask]]] = {}  # (future, its runs) by key, until it is back

        def submit(chunks: list[list[RunTask]]) -> list[Any]:
            # one graph update for all of them (client.map), not one round trip a run
            futures = self.client.map(_run_chunk, [fn] * len(chunks), chunks, pure=False)
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
        self.client.run(warm_worker, None)

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
            clear_partials(task)
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
        done = final_record(task)
        if done is not None:
            yield task, done
        elif len(chunk) == 1 or task_started(task):
            clear_partials(task)
            yield task, Crash(reason)
        else:
            yield task, None


def _crash_reason(error: BaseException) -> str:
    from distributed import KilledWorker

    if isinstance(error, KilledWorker):
        return f"the Dask worker died while running it (KilledWorker: {error})"
    return f"{type(error).__name__}: {error}"


def _every_run_seconds(outcomes: list[Outcome | Crash] | None) -> list[float]:
    """Wall seconds of every run among ``outcomes`` that has them."""
    return [max(float(outcome["wall_time_s"]), 1e-3) for outcome in outcomes or []
            if isinstance(outcome, dict) and isinstance(outcome.get("wall_time_s"), int | float)]


def _guided_size(left: int, workers: int, most: int) -> int:
    """Guided self-scheduling: the runs ``left`` over one more than the workers, rounded up, 1 to ``most``."""
    return max(1, min(most, -(-left // (workers + 1))))


def guided_chunks(tasks: list[RunTask], workers: int, most: int) -> list[list[RunTask]]:
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


def _stop_heartbeat(dask_worker: Any) -> None:
    """Stop a worker's heartbeats before its cluster closes (run on the worker by ``client.run``).

    A heartbeat that is on its way when the scheduler closes fails, and the worker prints it as an
    error with a traceback (``Failed to communicate with scheduler during heartbeat``), about one
    close in ten, after a batch that went well.
    """
    dask_worker.periodic_callbacks["heartbeat"].stop()
