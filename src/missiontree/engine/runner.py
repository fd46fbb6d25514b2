"""The runner: ticks a mission's tree at a set rate on the robot's clock until it ends.

::

    runner = Runner(root, context, tick_hz=10, max_duration=600, run_dir=Path("runs/patrol"))
    result = runner.run()       # RunResult: status, stopped_by, ticks, duration, summary

Between ticks it calls ``robot.spin_until(next_tick_time)``: the simulator steps as fast as the
machine allows, the ROS 2 backend waits in wall time. It stops on a final root status, the
duration limit, or SIGINT/SIGTERM; on every exit path it halts the tree (``root.stop(INVALID)``,
so each running leaf's ``terminate()`` cancels its work) and then calls ``robot.stop()``.

Ticking walks only the nodes the tick reaches (the root's tick generator, as ``tick_once()``
does), never the whole tree as ``BehaviourTree.tick()`` does after every tick.
An exception escaping a behaviour that is not a :class:`~missiontree.engine.leaf.Leaf` (those
handle their own) becomes FAILURE of that node with an ``error`` event and a fault
(:mod:`missiontree.engine.faults`); the run goes on. A run that ends FAILURE because of a fault
says so in the summary (``fault``: the node and the error). A halt
whose cancel raises is reported the same way. py_trees' own composites and decorators, which only
manage their children, are trusted and ticked without a wrapper (:data:`TRUSTED_TYPES`).

The run directory's files (``ticks.jsonl``, ``summary.json``, the backend's pictures) are the
:class:`~missiontree.engine.recorder.RunRecorder`'s; the lines are the
:mod:`~missiontree.engine.tick_log`'s. Process settings for long runs (the heap, the garbage
collector) are the application's, not the runner's: :mod:`missiontree.session.process`.
"""

from __future__ import annotations

import contextlib
import math
import os
import signal
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from types import FrameType
from typing import Any, TextIO

import py_trees

from missiontree import startup
from missiontree.engine.context import MissionContext
from missiontree.engine.faults import ErrorFrames, fault_of
from missiontree.engine.fleet import RobotEvents
from missiontree.engine.guards import TRUSTED_TYPES, guard_exceptions
from missiontree.engine.node_words import node_paths
from missiontree.engine.profile import RunProfile
from missiontree.engine.recorder import RunRecorder
from missiontree.engine.summary import (
    STOPPED_BY_ERROR,
    STOPPED_BY_LIMIT,
    STOPPED_BY_SIGNAL,
    STOPPED_BY_STATUS,
    RunEnd,
    final_pose,
    profile_section,
    provisional_summary,
    run_summary,
)
from missiontree.engine.tick_log import TickLog, TickRecorder, plain
from missiontree.errors import ConfigError, MissionTreeError, PluginError
from missiontree.redact import scrub_data

Status = py_trees.common.Status
Behaviour = py_trees.behaviour.Behaviour

_FINAL = (Status.SUCCESS, Status.FAILURE)

__all__ = ["STOPPED_BY_ERROR", "STOPPED_BY_LIMIT", "STOPPED_BY_SIGNAL", "STOPPED_BY_STATUS", "TRUSTED_TYPES",
           "RunResult", "Runner", "guard_exceptions"]


@dataclass
class RunResult:
    """How a run ended.

    Attributes:
        status: The root's status when the run stopped (RUNNING when stopped by limit or signal).
        stopped_by: ``status``, ``limit``, ``signal`` or ``error``.
        ticks: Ticks done.
        duration: Backend time from the first tick to the end, in seconds.
        run_dir: Where the log, summary and pictures went (None when not writing).
        summary: The summary (as written to ``summary.json``).
        signal: The signal number that stopped the run, 0 otherwise.
        plugin_error: Why a plugin's ``mission_finished`` hook failed ("" when none did); the other
            plugins' hooks (the built-in recording included) ran, and the run exits 1.
    """

    status: Status
    stopped_by: str
    ticks: int
    duration: float
    run_dir: Path | None = None
    summary: dict[str, Any] = field(default_factory=dict)
    signal: int = 0
    plugin_error: str = ""

    @property
    def exit_code(self) -> int:
        """The CLI's exit code: 0 on SUCCESS, 1 on FAILURE, limit or a failed plugin hook, 128+signal."""
        if self.signal:
            return 128 + self.signal
        return 0 if self.status is Status.SUCCESS and not self.plugin_error else 1


class Runner:
    """Ticks one tree on one robot.

    Args:
        root: The tree's root behaviour (built, not yet set up).
        context: What the leaves get in ``setup(context=...)``; its ``events`` is replaced by the
            tick log and its ``run_dir`` by ``run_dir``.
        tick_hz: Ticks per second of backend time.
        max_duration: Stop after this many seconds of backend time (None: no limit).
        run_dir: Directory for ``ticks.jsonl``, ``summary.json`` and pictures; None writes nothing
            to disk unless ``log_stream`` is given.
        mission: The mission id written on every log line.
        hook: A plugin hook relay (``Plugins.hook``) for mission started/finished, or None.
        spec: The checked mission spec handed to ``missiontree_mission_started``.
        log_stream: Write the tick log here instead of ``run_dir/ticks.jsonl``.
        blackboard: Keys written to the blackboard before the first tick (logged with tick 1).
        realtime: Pace the ticks to wall time as well (a simulator then runs no faster than life;
            a backend on wall time is unaffected). Wall time never reaches the tick log.
        handle_signals: Install SIGINT/SIGTERM handlers while running (main thread only).
        on_tick: Called with the runner after every tick (progress lines, scoring that needs the
            robot between ticks); it must return at once.
        final_state: Called once as the run ends (after the robot stopped); its mapping is added to
            the summary (the session adds the simulator's true pose this way).
        profile: Measure where the run's time goes (:mod:`missiontree.engine.profile`): the
            summary's ``profile`` section. None: on unless the environment sets
            ``MISSIONTREE_PROFILE=0`` (to time a mission without it).
        scopes: A fleet's robots (:mod:`missiontree.engine.fleet`): ``(subtree, context, robot
            name)``; the subtree's nodes are set up with that context, whose events carry the robot.
    """

    def __init__(
        self, root: Behaviour, context: MissionContext, *, tick_hz: float = 10.0,
        max_duration: float | None = None, run_dir: Path | None = None, mission: str = "mission",
        hook: Any = None, spec: Any = None, log_stream: TextIO | None = None, handle_signals: bool = True,
        blackboard: dict[str, Any] | None = None, realtime: bool = False,
        on_tick: Callable[[Runner], None] | None = None,
        final_state: Callable[[], dict[str, Any]] | None = None, profile: bool | None = None,
        scopes: list[tuple[Behaviour, MissionContext, str]] | None = None,
    ) -> None:
        if not (tick_hz > 0 and math.isfinite(tick_hz)):
            raise ConfigError(f"tick rate must be a positive number of ticks per second, found {tick_hz!r}")
        if max_duration is not None and not max_duration > 0:
            raise ConfigError(f"max duration must be positive seconds, found {max_duration!r}")
        self.root = root
        self.context = context
        self.robot = context.robot
        self.period = 1.0 / tick_hz
        self.tick_hz = tick_hz
        self.max_duration = max_duration
        self.run_dir = Path(run_dir) if run_dir is not None else None
        self.mission = mission
        self.hook = hook
        self.spec = spec
        self.handle_signals = handle_signals
        self.blackboard = dict(blackboard or {})
        self.realtime = realtime
        context.realtime = realtime
        self.on_tick = on_tick
        self.final_state = final_state
        #: The run directory's files: the log's stream, the summary, the pictures.
        self.files = RunRecorder(self.run_dir, log_stream)
        self._signal = 0
        #: ``running`` (setup and ticks: a second signal interrupts at once) or ``stopping`` (halt,
        #: robot stop, summary: later signals are only noted, so the summary and log are whole).
        self._phase = "idle"
        self._interrupted = False
        #: Why the run ended when stopped_by is ``error`` (written as the summary's ``reason``).
        self._reason = ""
        self._fault: tuple[Behaviour, str] | None = None
        #: Traceback frames (``file:line in function``) of each node's last error, for the summary's fault.
        self.errors = ErrorFrames()
        self.log: TickLog | None = None
        self.recorder: TickRecorder | None = None
        self._set_up = False
        if profile is None:
            setting = os.environ.get("MISSIONTREE_PROFILE", "1").strip().lower()
            profile = setting not in {"0", "false", "no", "off"}
        self.profile_enabled = profile
        self.profiler: RunProfile | None = None
        self.scopes = list(scopes or [])

    # -- pieces --------------------------------------------------------------------------------

    def setup(self) -> None:
        """Open the log, guard non-Leaf nodes and set up every node with the mission context.

        Raises:
            ConfigError: A node failed to set up (names the node and the error).
        """
        if self._set_up:
            return
        self.files.open(provisional_summary(self.mission, self.tick_hz, self.context.seed, self.robot.name))
        if self.run_dir is not None:
            self.context.run_dir = self.run_dir
        self.log = TickLog(self.files.stream, self.mission, self.robot.now, bool(self.robot.simulated))
        self.context.events = self.errors.noting(self.log)
        self.log.bind()
        guard_exceptions(self.root, self._on_node_error)
        paths = node_paths(self.root)
        contexts = self._scope_contexts()
        for node in self.root.iterate():
            try:
                node.setup(context=contexts.get(id(node), self.context))
            except MissionTreeError:
                raise
            except Exception as error:
                raise ConfigError(f"node {paths.get(node, node.name)} failed to set up: "
                                  f"{type(error).__name__}: {error}") from error
        self.recorder = TickRecorder(self.root, self.log)
        self.recorder.watch_stops()
        if self.profile_enabled:
            self.profiler = RunProfile(self.root, self.recorder.path, self.context.models)
            self.profiler.attach()
        for key, value in self.blackboard.items():
            py_trees.blackboard.Blackboard.set(key if key.startswith("/") else f"/{key}", value)
        self._set_up = True

    def _scope_contexts(self) -> dict[int, MissionContext]:
        """Each fleet robot's nodes (by id) to its context, whose events now reach the tick log."""
        contexts: dict[int, MissionContext] = {}
        for subtree, context, robot in self.scopes:
            # through the run's sink as it is when each event comes: a mission-started hook may wrap
            # it after setup (the ROS 2 backend mirrors each robot's alarms to its namespace)
            context.events = RobotEvents(_RunEvents(self.context), robot)
            # each robot's files (alarms, frames) in its own folder of the run directory
            context.run_dir = None if self.context.run_dir is None else self.context.run_dir / robot
            context.realtime = self.realtime
            for node in subtree.iterate():
                contexts[id(node)] = context
        return contexts

    def tick(self) -> Status:
        """Tick the tree once, write its log line and return the root's status."""
        if not self._set_up:
            self.setup()
        assert self.recorder is not None and self.log is not None
        profiler = self.profiler
        started = time.thread_time() if profiler is not None else 0.0
        self.log.set_tick(self.recorder.ticks + 1)
        visited = list(self.root.tick())
        now = self.robot.now()
        self.recorder.record(now, visited)
        if profiler is not None:
            profiler.record_tick(now, visited)
            profiler.add_tick_cpu(time.thread_time() - started)
        return self.root.status

    def halt(self) -> None:
        """Halt the tree (running leaves' ``terminate()`` cancels their work) and log what stopped."""
        try:
            self.root.stop(Status.INVALID)
        except Exception as error:  # noqa: BLE001 - halting must go on to stop the robot
            self._on_node_error(self.root, error)
            for node in self.root.iterate():  # children first: reach every node still active
                if node.status != Status.INVALID:
                    try:
                        node.stop(Status.INVALID)
                    except Exception as again:  # noqa: BLE001 - keep halting the others
                        self._on_node_error(node, again)
                        node.status = Status.INVALID
        if self.recorder is not None:
            self.recorder.record(self.robot.now(), [], event="halted")

    def replace_tree(self, root: Behaviour) -> None:
        """Tick ``root`` from the next tick on (a reloaded tree, already set up; the old one halted).

        The new tree's non-Leaf nodes are guarded as the first tree's were, and the tick log names
        its nodes by their paths.
        """
        guard_exceptions(root, self._on_node_error)
        self.root = root
        if self.recorder is not None:
            self.recorder.root = root
            self.recorder.paths.update(node_paths(root))
            self.recorder.watch_stops()

    def _on_node_error(self, node: Behaviour, error: Exception) -> None:
        """A non-Leaf node's exception: an ``error`` event as a leaf's (reason, file:line, frames)."""
        site = self.errors.node_error(node, error)
        if self.log is None:
            return
        path = self.recorder.path(node) if self.recorder is not None else node.name
        self.log.emit("error", node=path, error=site.reason, where=site.where, function=site.function,
                      traceback=list(site.frames))

    def _on_signal(self, signum: int, frame: FrameType | None) -> None:
        """First signal: stop after this tick; a second one while running: stop now.

        After a second signal the tree is still halted and the robot stopped. While stopping (halt,
        robot stop, summary) later signals are only noted: they cannot cut the summary or the last
        log lines short.
        """
        if not self._signal:
            self._signal = signum
            return
        if self._phase == "running":
            self._interrupted = True
            if startup.guarding(self._previous.get(signal.SIGINT)):  # the command's run: recorded
                startup.raise_interrupt()
            raise KeyboardInterrupt

    # -- the loop ------------------------------------------------------------------------------

    def run(self) -> RunResult:
        """Tick until the tree ends, the limit passes or a signal arrives; always halt and stop.

        A second SIGINT/SIGTERM interrupts a tick at once; the run still halts the tree, stops the
        robot, writes the summary (``stopped_by: signal``) and returns normally.

        Raises:
            ConfigError: A node failed to set up, the run directory cannot be written, or the
                summary could not be written at the end (a full disk).
            PluginError: A mission started/finished hook failed.
        """
        self._install_signal_handlers()
        status = Status.INVALID
        stopped_by = STOPPED_BY_ERROR
        start = self.robot.now()
        try:
            self._phase = "running"
            self.setup()
            assert self.log is not None
            self.log.line("mission_started", tick_hz=self.tick_hz, max_duration=self.max_duration,
                          robot=self.robot.name, seed=self.context.seed, nodes=len(self.recorder.paths)
                          if self.recorder else 0)
            self._call_hook("missiontree_mission_started", context=self.context, mission=self.spec)
            start = self.robot.now()
            if self.profiler is not None:
                self.profiler.start()
            status, stopped_by = self._loop(start)
        except KeyboardInterrupt:  # a second signal (ours), or Ctrl-C without our handlers
            # interrupted inside a tick, the root has no status of that tick yet: it was running
            status = self.root.status if self.root.status in _FINAL else Status.RUNNING
            stopped_by = STOPPED_BY_SIGNAL
            if not self._signal:
                self._signal = signal.SIGINT
            if not self._interrupted:
                raise
        except BaseException as error:
            self._reason = f"{type(error).__name__}: {error}"
            raise
        finally:
            self._phase = "stopping"
            duration = self.robot.now() - start
            # before the halt resets every status: the faulted node behind a FAILURE
            self._fault = fault_of(self.root) if status == Status.FAILURE else None
            try:
                if self._set_up:
                    self.halt()
            finally:
                self.robot.stop()
            result = self._finish(status, stopped_by, duration)
            self._restore_signal_handlers()
        return self._after_run(result)

    def _after_run(self, result: RunResult) -> RunResult:
        """Call the mission-finished hooks; raise when the summary or the log could not be written."""
        try:
            self._call_hook("missiontree_mission_finished", context=self.context, summary=result.summary)
        except PluginError as error:  # the run is complete: keep its outcome, say what failed after it
            result.plugin_error = str(error)
            result.summary["plugin_error"] = str(error)
            if self.run_dir is not None and self.files.write_failure is None:
                with contextlib.suppress(OSError):
                    self.files.write_summary(result.summary)
        if self.files.write_failure is not None:
            what, failure = self.files.write_failure
            raise ConfigError(f"the run ended ({result.status.name}, stopped by {result.stopped_by}) but its "
                              f"{what} could not be written in {self.run_dir}: {failure.strerror or failure}")
        return result

    def _loop(self, start: float) -> tuple[Status, str]:
        index = 0
        wall_start = time.monotonic()
        while True:
            if self._signal:
                return self.root.status, STOPPED_BY_SIGNAL
            if self.max_duration is not None and self.robot.now() - start >= self.max_duration - 1e-9:
                return self.root.status, STOPPED_BY_LIMIT
            status = self.tick()
            if self.on_tick is not None:
                self.on_tick(self)
            if self._log_lost():
                return self.root.status, STOPPED_BY_ERROR
            if status in _FINAL:
                return status, STOPPED_BY_STATUS
            index += 1
            next_time = start + index * self.period
            now = self.robot.now()
            if now > next_time + self.period:  # a slow tick on a real clock: skip the missed slots
                index = math.floor((now - start) / self.period) + 1
                next_time = start + index * self.period
            if self.max_duration is not None:
                next_time = min(next_time, start + self.max_duration)
            self._spin_until(next_time)
            if self.realtime:
                time.sleep(max(0.0, wall_start + (next_time - start) - time.monotonic()))

    def _spin_until(self, next_time: float) -> None:
        """Let the robot run until ``next_time`` (its stepping's CPU goes to the profile)."""
        if self.profiler is None:
            self.robot.spin_until(next_time)
            return
        started = time.thread_time()
        try:
            self.robot.spin_until(next_time)
        finally:
            self.profiler.add_sim_cpu(time.thread_time() - started)

    def _log_lost(self) -> bool:
        """True (with the reason kept) when the tick log can no longer be written.

        That is a failed write (a full disk) or a run directory deleted under the run (its open log
        file has no name left).
        """
        assert self.log is not None
        error = self.log.write_error
        if error is not None:
            self._reason = (f"the tick log could not be written: {error.strerror or error}; the lines "
                            f"before the failure are kept")
            return True
        if self.files.directory_deleted():
            self._reason = (f"the run directory {self.run_dir} was deleted during the run; it was made "
                            f"again with the tick log read back from the open file (other files are lost)")
            return True
        return False

    def _finish(self, status: Status, stopped_by: str, duration: float) -> RunResult:
        """Draw pictures, write the summary and close the log (never raises: failures are kept)."""
        if self.files.dir_lost and self.log is not None:
            self.files.recover_log(self.log.redirect)
        if self.log is not None:
            self.log.flush_pending()
        profile = profile_section(self.profiler, self.robot.now(), self.period, duration)
        pictures = self.files.draw(self.robot, self.context.markers, self._on_draw_error)
        summary = run_summary(self.mission, self._end(status, stopped_by, duration), tick_hz=self.tick_hz,
                              seed=self.context.seed, robot=self.robot.name, log=self.log,
                              recorder=self.recorder, pictures=pictures, outcome=self.context.outcome)
        if profile:
            summary["profile"] = profile
        summary.update(final_pose(self.robot, self.final_state))
        summary = scrub_data(plain(summary))  # kept, printed and recorded by batches: no secret in it
        if self.recorder is not None:
            self.recorder.close()
        if self.log is not None:
            self.log.line("mission_finished", status=status.name, stopped_by=stopped_by,
                          ticks=summary["ticks"], duration=duration, reason=summary.get("reason"),
                          fault=summary.get("fault"))
            self.log.unbind()
            self.log.flush()
        self.files.finish(summary, log_failed=self.log is not None and self.log.write_error is not None)
        return RunResult(status=status, stopped_by=stopped_by, ticks=summary["ticks"], duration=duration,
                         run_dir=self.run_dir, summary=summary, signal=self._signal)

    def _on_draw_error(self, error: Exception) -> None:
        if self.log is not None:
            self.log.emit("error", node="", error=f"drawing failed: {type(error).__name__}: {error}",
                          where="draw")

    def _end(self, status: Status, stopped_by: str, duration: float) -> RunEnd:
        """How the run ended, with the fault behind a FAILURE (its node's path, error and frames)."""
        fault = None
        if self._fault is not None:
            node, cause = self._fault
            path = self.recorder.path(node) if self.recorder else node.name
            fault = (path, cause, self.errors.of(node))
        return RunEnd(status.name, stopped_by, self._signal, duration, self._reason, fault)

    def _call_hook(self, name: str, **kwargs: Any) -> None:
        if self.hook is None:
            return
        try:
            getattr(self.hook, name)(**kwargs)
        except PluginError:
            raise
        except Exception as error:
            raise PluginError(f"a plugin's {name} hook failed: {type(error).__name__}: {error}; fix the "
                              f"plugin or run with --no-plugins") from error

    # -- signals -------------------------------------------------------------------------------

    def _install_signal_handlers(self) -> dict[int, Any]:
        self._previous: dict[int, Any] = {}
        if not self.handle_signals or threading.current_thread() is not threading.main_thread():
            return self._previous
        for signum in (signal.SIGINT, signal.SIGTERM):
            self._previous[signum] = signal.signal(signum, self._on_signal)
        if startup.guarding(self._previous[signal.SIGINT]) and startup.interrupted():
            # a Ctrl-C the session's set-up swallowed (an import or extension cleared it): stop now
            self._signal = signal.SIGINT
        return self._previous

    def _restore_signal_handlers(self) -> None:
        for signum, handler in getattr(self, "_previous", {}).items():
            signal.signal(signum, handler)
        self._previous = {}


class _RunEvents:
    """An event sink forwarding to ``context.events`` as it is when an event comes, not at setup."""

    def __init__(self, context: MissionContext) -> None:
        self.context = context

    def emit(self, event: str, /, **fields: Any) -> None:
        """Forward to the run context's current sink."""
        self.context.events.emit(event, **fields)
