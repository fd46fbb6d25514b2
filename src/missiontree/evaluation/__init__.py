"""Batch evaluation: a mission over many seeds, worlds and parameter values, here or on Dask.

- :mod:`~missiontree.evaluation.plan` — seeds/worlds/--set/--sweep → :class:`BatchPlan` of :class:`RunSpec`.
- :mod:`~missiontree.evaluation.worker` — one run in a worker (through the session), atomic and idempotent.
- :mod:`~missiontree.evaluation.engines` — serial and local process pool engines.
- :mod:`~missiontree.evaluation.dask_engine` — Dask distributed (optional extra).
- :mod:`~missiontree.evaluation.batch` — :func:`run_batch` (resume, crash retry) → :class:`RunRecord` list.
- :mod:`~missiontree.evaluation.report` — results.jsonl, summary.json (Wilson intervals), table, junit.xml.
- :mod:`~missiontree.evaluation.progress` — the progress bar.

``missiontree batch`` (missiontree.cli.batch) and the evaluation benchmarks use this package. Dask is
imported only when a Dask engine is made.
"""

from missiontree.evaluation.batch import RunRecord, make_engine, run_batch
from missiontree.evaluation.dask_engine import DaskEngine
from missiontree.evaluation.engines import Crash, Engine, PoolEngine, SerialEngine
from missiontree.evaluation.plan import BatchPlan, RunSpec, expand_plan
from missiontree.evaluation.worker import Probe, RunTask

__all__ = ["BatchPlan", "Crash", "DaskEngine", "Engine", "PoolEngine", "Probe", "RunRecord", "RunSpec",
           "RunTask", "SerialEngine", "expand_plan", "make_engine", "run_batch"]
