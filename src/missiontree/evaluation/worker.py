"""One run of a batch, as an engine's worker executes it: :func:`execute_run`.

The run goes through the session (the one wiring path) into a directory named
``.<run id>.<pid>.<attempt>.partial`` beside its final place, which is renamed to ``<run id>``
only when the run is complete, with its ``record.json`` inside. So a killed batch leaves no half
runs under a final name, and an engine that runs a task twice (Dask retries a dead worker's task)
finds the run already there and returns its record: the task is atomic and idempotent.

The worker tunes its process for long runs (:func:`~missiontree.session.process.tune_process`) and
pins thread counts (:func:`pin_threads`): BLAS/OpenMP/numba through the
environment, onnxruntime through the models config (``threads: 1`` for every provider that takes
``threads`` and was not given one), so a run's numbers do not depend on the machine's cores.

A :class:`Probe` lets a caller (an evaluation benchmark) score a run inside the worker: built there
from a picklable factory, it sees the session after every tick and adds its figures at the end.
"""

from __future__ import annotations

import json
import math
import os
import shutil
import time
import traceback
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

from missiontree.file_limits import read_text_bounded

if TYPE_CHECKING:
    from missiontree.engine.runner import RunResult
    from missiontree.evaluation.plan import RunSpec
    from missiontree.session import Session

__all__ = ["PARTIAL_SUFFIX", "RECORD_FILE", "THREAD_ENV", "Probe", "RunTask", "execute_run",
           "pin_threads", "why_stopped"]

#: Environment that pins the thread pools of numerical libraries to one thread (set before import).
THREAD_ENV = {
    "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1",
    "NUMBA_NUM_THREADS": "1", "VECLIB_MAXIMUM_THREADS": "1", "NUMEXPR_NUM_THREADS": "1",
}
RECORD_FILE = "record.json"
#: Largest record.json read (bytes): a record is a few hundred bytes plus its figures; a bigger file
#: is not one of ours and is not read whole (issue 32: every file read has a limit).
MAX_RECORD_BYTES = 4 * 2**20
PARTIAL_SUFFIX = ".partial"
#: The summary keys every run has; the rest are the mission's (or a plugin's) own figures.
_RUNNER_KEYS = {"mission", "status", "stopped_by", "signal", "ticks", "duration", "tick_hz", "seed", "robot",
                "events", "pictures", "nodes", "failure_reasons", "failures", "final_pose",
                "true_final_pose", "final_pose_error", "final_state_error", "complete", "reason"}


class Probe(Protocol):
    """Scores one run inside the worker (built there by the task's ``probe`` factory)."""

    def on_tick(self, session: Session) -> None:
        """Called after every tick; must return at once (may read ``session.robot.truth``)."""

    def finish(self, session: Session, result: RunResult) -> Mapping[str, Any]:
        """The run's figures (JSON data), merged into the record's ``figures``."""


@dataclass(frozen=True)
class RunTask:
    """What a worker needs for one run (picklable; paths absolute).

    Attributes:
        spec: The run.
        mission: The mission file.
        runs_dir: Where run directories go.
        request: Shared :class:`~missiontree.session.MissionRequest` fields of the batch.
        attempt: 1, or 2 when retried after its process crashed.
        probe: A picklable factory of a :class:`Probe` (a class or module-level function), or None.
        write_log: Keep ``ticks.jsonl`` in the run directory (False: the log goes nowhere).
    """

    spec: RunSpec
    mission: str
    runs_dir: str
    request: Mapping[str, Any] = field(default_factory=dict)
    attempt: int = 1
    probe: Callable[[], Probe] | None = None
    write_log: bool = True

    def retry(self) -> RunTask:
        """The same task, second attempt."""
        return RunTask(self.spec, self.mission, self.runs_dir, self.request, self.attempt + 1, self.probe,
                       self.write_log)

    def partial_prefix(self) -> str:
        """Every attempt's staging directory name starts with this."""
        return f".{self.spec.run_id}."


def pin_threads() -> None:
    """Pin numerical libraries' threads to one (environment first; pools already loaded too).

    Once numba is imported its thread count is pinned with ``numba.set_num_threads`` and its
    environment variable is left alone: numba re-reads the environment at every compilation and
    refuses a ``NUMBA_NUM_THREADS`` that differs from the pool it launched (a serial batch runs in
    the caller's own process, which may have launched that pool already).
    """
    import sys

    numba = sys.modules.get("numba")
    os.environ.update({name: value for name, value in THREAD_ENV.items()
                       if numba is None or name != "NUMBA_NUM_THREADS"})
    if numba is not None:
        try:
            numba.set_num_threads(1)
        except Exception:  # noqa: BLE001, S110 - numba without threading layer: nothing to pin
            pass


def ignore_interrupts() -> None:
    """A pool worker's initialiser: pin threads; Ctrl-C is the parent's to handle, not each worker's."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    pin_threads()
    import missiontree.session  # noqa: F401 - imported once per worker, not timed in its first run


def execute_run(task: RunTask) -> dict[str, Any]:
    """Run one mission of a batch to its end and return its record (see module docstring).

    A mission that fails, errs or hits its limit is a result (the record says which); only the
    death of this process is an infrastructure failure, which the engine reports.
    """
    from missiontree.session.process import tune_process

    pin_threads()
    tune_process()
    runs_dir = Path(task.runs_dir)
    final = runs_dir / task.spec.run_id
    done = _read_record(final)
    if done is not None:  # already run by an earlier attempt of this task (an engine's retry)
        return done
    staging = runs_dir / f"{task.partial_prefix()}{os.getpid()}.{task.attempt}{PARTIAL_SUFFIX}"
    shutil.rmtree(staging, ignore_errors=True)
    staging.mkdir(parents=True)
    record = _run(task, staging)
    (staging / RECORD_FILE).write_text(json.dumps(record, indent=2, sort_keys=True) + "\n", encoding="utf-8")
    try:
        os.rename(staging, final)
    except OSError:  # another attempt finished first: keep its run, drop ours
        shutil.rmtree(staging, ignore_errors=True)
        done = _read_record(final)
        if done is None:
            raise
        return done
    return record


#: A run record's fields and the types a whole record has (``results.jsonl``'s line, see RunRecord).
_TEXT, _INT, _NUMBER = (str,), (int,), (int, float)
RECORD_FIELDS: dict[str, tuple[type, ...]] = {
    "run_id": _TEXT, "world": (str, type(None)), "seed": _INT, "run_seed": _INT, "params": (dict,),
    "status": _TEXT, "stopped_by": _TEXT, "reason": _TEXT, "robot_time_s": _NUMBER, "wall_time_s": _NUMBER,
    "path_length_m": _NUMBER, "ticks": _INT,
}
#: Fields a record may leave out (their defaults hold).
OPTIONAL_FIELDS: dict[str, tuple[type, ...]] = {"figures": (dict,), "attempt": _INT}


def whole_record(data: Any, run_id: str | None = None) -> bool:
    """Whether ``data`` is a whole run record (of run ``run_id`` when given): every field, of its type.

    A record cut by a killed process, edited by hand or written by another version is not a result:
    its run is done again rather than counted.
    """
    if not isinstance(data, dict):
        return False
    for key, types in {**RECORD_FIELDS, **OPTIONAL_FIELDS}.items():
        if key not in data:
            if key in RECORD_FIELDS:
                return False
            continue
        value = data[key]
        if isinstance(value, bool) or not isinstance(value, types):
            return False
        if isinstance(value, float) and not math.isfinite(value):
            return False
    if not all(isinstance(k, str) and isinstance(v, str) for k, v in data["params"].items()):
        return False
    return run_id is None or data["run_id"] == run_id


def load_record(path: Path) -> Any:
    """The JSON in a record file, read within :data:`MAX_RECORD_BYTES`; None when it cannot be read.

    Unreadable, too large, not UTF-8 or not JSON all read as no record (the run is done again).
    """
    try:
        return json.loads(read_text_bounded(path, MAX_RECORD_BYTES, "run record"))
    except (OSError, ValueError):   # FileTooLargeError is an OSError, UnicodeDecodeError a ValueError
        return None


def _read_record(run_dir: Path) -> dict[str, Any] | None:
    """The run directory's record when it is whole, else None."""
    data = load_record(run_dir / RECORD_FILE)
    return data if whole_record(data, run_dir.name) else None


class _PathMeter:
    """Sums the robot's path: the simulator's true pose when it has one, else the robot's estimate."""

    def __init__(self, probe: Probe | None) -> None:
        self.length = 0.0
        self.probe = probe
        self._last: tuple[float, float] | None = None

    def __call__(self, session: Session) -> None:
        robot = session.robot
        truth = getattr(robot, "truth", None)
        pose = truth.robot_pose() if truth is not None and hasattr(truth, "robot_pose") else None
        if pose is None:
            stamped = robot.pose()
            pose = stamped.pose if stamped is not None else None
        if pose is not None:
            if self._last is not None:
                self.length += math.hypot(pose.x - self._last[0], pose.y - self._last[1])
            self._last = (pose.x, pose.y)
        if self.probe is not None:
            self.probe.on_tick(session)


def _run(task: RunTask, staging: Path) -> dict[str, Any]:
    """The mission through the session; every outcome (an exception too) becomes a record."""
    import io

    import py_trees

    from missiontree.session import MissionRequest, Session

    spec = task.spec
    record: dict[str, Any] = {
        "run_id": spec.run_id, "world": spec.world, "seed": spec.seed, "run_seed": spec.run_seed,
        "params": spec.params_dict, "attempt": task.attempt,
    }
    py_trees.blackboard.Blackboard.clear()  # a worker runs many missions: none sees another's keys
    options = dict(task.request)
    options.setdefault("plugins", _plugins())
    options["models"] = _pinned_models(Path(task.mission), options.get("models"), options.get("plugins"))
    probe = task.probe() if task.probe is not None else None
    meter = _PathMeter(probe)
    started = time.perf_counter()
    try:
        request = MissionRequest(
            mission=Path(task.mission), world=spec.world, seed=spec.run_seed, out=staging,
            params=spec.params_dict or None, quiet=True, handle_signals=False, on_tick=meter,
            log_stream=None if task.write_log else io.StringIO(), **options)
        with Session.open(request) as session:
            result = session.run()
            figures = dict(probe.finish(session, result)) if probe is not None else {}
    except Exception as error:  # noqa: BLE001 - a run that raised is a result (ERROR), not a lost run
        record.update(status="ERROR", stopped_by="error", reason=f"{type(error).__name__}: {error}",
                      robot_time_s=0.0, wall_time_s=round(time.perf_counter() - started, 4),
                      path_length_m=round(meter.length, 4), ticks=0, figures={},
                      traceback=traceback.format_exc(limit=8))
        return record
    summary = result.summary
    own = {k: v for k, v in summary.items() if k not in _RUNNER_KEYS}
    record.update(
        status=result.status.name, stopped_by=result.stopped_by, reason=why_stopped(summary, result),
        robot_time_s=round(result.duration, 4), wall_time_s=round(time.perf_counter() - started, 4),
        path_length_m=round(meter.length, 4), ticks=result.ticks,
        figures={"events": summary.get("events", {}), **own, **figures})
    if result.plugin_error:  # the run completed, a plugin's mission_finished hook failed after it
        record.update(status="ERROR", stopped_by="error", reason=result.plugin_error)
    return record


def why_stopped(summary: Mapping[str, Any], result: RunResult) -> str:
    """Why the run ended, in one line: the deciding failure's reason, the limit, or success."""
    if result.stopped_by == "limit":
        return f"max_duration reached after {result.duration:.1f} s (root still {result.status.name})"
    if result.stopped_by == "signal":
        return f"stopped by {summary.get('signal') or 'a signal'}"
    failures = summary.get("failures") or {}
    decided = [(path, f) for path, f in failures.items() if f.get("decided")]
    for path, failure in sorted(decided, key=lambda item: -len(item[0])):  # the deepest node said why
        reasons = failure.get("reasons") or []
        if reasons:
            return f"{path}: {reasons[-1]}"
    if result.status.name == "SUCCESS":
        return "succeeded"
    return result.stopped_by


_PLUGIN_CACHE: dict[str | None, Any] = {}


def _plugins() -> Any:
    """The plugins, loaded once per worker process (as the environment says, like the parent)."""
    from missiontree.plugins.manager import DISABLE_ENV, load_plugins

    key = os.environ.get(DISABLE_ENV)
    if key not in _PLUGIN_CACHE:
        _PLUGIN_CACHE[key] = load_plugins()
    return _PLUGIN_CACHE[key]


def _pinned_models(mission: Path, models: Any, plugins: Any) -> Any:
    """The run's models config with ``threads: 1`` for providers that take ``threads`` (unless set).

    Returns ``models`` unchanged when nothing takes threads or the config cannot be read here (the
    session then reports the problem as it would in ``missiontree run``).
    """
    from missiontree.errors import MissionTreeError, ProblemsError
    from missiontree.session.models import load_models_config
    from missiontree.yamlio import load_yaml

    try:
        if models is None:
            document = load_yaml(mission, error=ProblemsError).data
            run = document.get("run") if isinstance(document, dict) else None
            models = run.get("models") if isinstance(run, dict) else None
        data = load_models_config(models).data
    except (MissionTreeError, OSError, AttributeError):
        return models
    if not isinstance(data, dict) or not isinstance(data.get("roles"), dict):
        return models
    plugins = plugins if plugins is not None else _plugins()
    changed = False
    roles = {}
    for role, section in data["roles"].items():
        section = dict(section) if isinstance(section, dict) else section
        factory = plugins.providers.get(section.get("provider")) if isinstance(section, dict) else None
        fields = getattr(getattr(factory, "options_model", None), "model_fields", {})
        if isinstance(section, dict) and "threads" in fields and "threads" not in section:
            section["threads"] = 1
            changed = True
        roles[role] = section
    return {**data, "roles": roles} if changed else models
