"""Tests of the runner: rate on the backend clock, stop conditions, halting, errors, run directory."""

from __future__ import annotations

import json
import os
import signal
import sys
from pathlib import Path

import py_trees
import pytest

from missiontree import startup
from missiontree.engine.context import MissionContext
from missiontree.engine.leaf import Leaf, Status
from missiontree.engine.recorder import RunRecorder
from missiontree.engine.runner import Runner
from missiontree.errors import ConfigError, PluginError
from missiontree.plugins.hookspecs import hookimpl
from missiontree.testing import ClockRobot, ScriptedLeaf, capture_tick_log, clean_state, fresh_plugins
from missiontree.types import Marker


@pytest.fixture(autouse=True)
def _clean() -> None:
    clean_state()


def _runner(root: py_trees.behaviour.Behaviour, robot: ClockRobot | None = None, **options: object) -> Runner:
    context = MissionContext(robot=robot or ClockRobot())
    options.setdefault("handle_signals", False)
    return Runner(root, context, **options)  # type: ignore[arg-type]


def test_ticks_at_the_set_rate_on_the_backend_clock() -> None:
    """Between ticks the runner asks the robot to run until the next tick time (5 Hz: 0.2 s apart)."""
    robot = ClockRobot(start=3.0)
    result = _runner(ScriptedLeaf("a", script="RRRS"), robot, tick_hz=5).run()
    assert result.ticks == 4
    assert robot.spins == pytest.approx([3.2, 3.4, 3.6])
    assert result.duration == pytest.approx(0.6)


def test_stops_on_success_with_exit_code_zero() -> None:
    """A root that succeeds ends the run with status SUCCESS and exit code 0."""
    result = _runner(ScriptedLeaf("a", script="RS")).run()
    assert (result.status, result.stopped_by, result.exit_code) == (Status.SUCCESS, "status", 0)


def test_stops_on_failure_with_exit_code_one() -> None:
    """A root that fails ends the run with exit code 1."""
    result = _runner(ScriptedLeaf("a", script="F")).run()
    assert (result.status, result.exit_code) == (Status.FAILURE, 1)


def test_duration_limit_stops_halts_the_tree_and_stops_the_robot() -> None:
    """At the limit the running leaf is halted (terminate INVALID) and robot.stop() is called once."""
    robot = ClockRobot()
    leaf = ScriptedLeaf("forever", script="R")
    result = _runner(leaf, robot, tick_hz=10, max_duration=1.0).run()
    assert (result.stopped_by, result.status, result.exit_code) == ("limit", Status.RUNNING, 1)
    assert result.ticks == 10  # t = 0.0 ... 0.9
    assert robot.now() == pytest.approx(1.0)
    assert leaf.calls[-1] == "terminate:INVALID"
    assert robot.stop_calls == 1


class _RaiseSignal(Leaf):
    """Sends a signal to this process on its third tick."""

    signum = signal.SIGINT

    def initialise(self) -> None:
        self.n = 0

    def update(self) -> Status:
        self.n += 1
        if self.n == 3:
            os.kill(os.getpid(), self.signum)
        return Status.RUNNING

    def terminate(self, new_status: Status) -> None:
        self.halted_with = new_status


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_signal_stops_after_the_tick_and_halts(signum: int) -> None:
    """SIGINT or SIGTERM stops the run after the current tick, halts the tree and restores handlers."""
    before = signal.getsignal(signum)
    leaf = _RaiseSignal("sig")
    leaf.signum = signum
    robot = ClockRobot()
    result = Runner(leaf, MissionContext(robot=robot), handle_signals=True).run()
    assert result.stopped_by == "signal"
    assert result.exit_code == 128 + signum
    assert result.ticks == 3
    assert leaf.halted_with == Status.INVALID
    assert robot.stop_calls == 1
    assert signal.getsignal(signum) is before


def test_a_ctrl_c_swallowed_during_set_up_stops_the_run_at_once(monkeypatch: pytest.MonkeyPatch) -> None:
    """A Ctrl-C the start-up guard recorded before the run took over stops it as a signal, exit 130."""
    before = signal.getsignal(signal.SIGINT)
    startup.guard()
    monkeypatch.setattr(startup, "_pending", True)  # an import swallowed its KeyboardInterrupt
    monkeypatch.setattr("sys.unraisablehook", sys.__unraisablehook__)
    try:
        robot = ClockRobot()
        result = Runner(ScriptedLeaf("on", script="R" * 50), MissionContext(robot=robot),
                        handle_signals=True, max_duration=5.0).run()
    finally:
        signal.signal(signal.SIGINT, before)
    assert (result.stopped_by, result.exit_code, result.ticks) == ("signal", 130, 0)
    assert robot.stop_calls == 1


def test_a_recorded_ctrl_c_outside_the_guard_does_not_stop_a_run(monkeypatch: pytest.MonkeyPatch) -> None:
    """Only the command's own guard hands a recorded Ctrl-C over: a run under another handler goes on."""
    monkeypatch.setattr(startup, "_pending", True)
    result = Runner(ScriptedLeaf("on", script="RS"), MissionContext(robot=ClockRobot()),
                    handle_signals=True).run()
    assert (result.stopped_by, result.exit_code) == ("status", 0)


class _SignalInFinaliser(Leaf):
    """Ctrl-C on its second tick and, in the same tick, a second one inside an object's ``__del__``."""

    def initialise(self) -> None:
        self.n = 0

    def update(self) -> Status:
        self.n += 1
        if self.n == 2:
            os.kill(os.getpid(), signal.SIGINT)

            class Finalised:
                def __del__(self) -> None:
                    os.kill(os.getpid(), signal.SIGINT)  # its handler runs inside this finaliser
            Finalised()
        return Status.RUNNING


def test_a_second_ctrl_c_inside_a_finaliser_is_kept_quiet(monkeypatch: pytest.MonkeyPatch,
                                                          capsys: pytest.CaptureFixture[str]) -> None:
    """The run's "stop now" swallowed by a ``__del__`` prints no traceback, and the run still stops."""
    before = signal.getsignal(signal.SIGINT)
    monkeypatch.setattr(startup, "_pending", False)
    monkeypatch.setattr("sys.unraisablehook", sys.unraisablehook)
    startup.guard()
    try:
        result = Runner(_SignalInFinaliser("leaf"), MissionContext(robot=ClockRobot()), handle_signals=True,
                        max_duration=5.0).run()
    finally:
        signal.signal(signal.SIGINT, before)
    assert (result.stopped_by, result.exit_code) == ("signal", 130)
    assert "Traceback" not in capsys.readouterr().err


class _TwoSignals(Leaf):
    """Two Ctrl-Cs in one tick: the second is the run's "stop now"."""

    def update(self) -> Status:
        os.kill(os.getpid(), signal.SIGINT)
        os.kill(os.getpid(), signal.SIGINT)
        return Status.RUNNING


def test_a_run_outside_the_command_leaves_the_start_up_record_alone() -> None:
    """A run under another SIGINT handler (a test, a library caller) stops now without recording a Ctrl-C.

    The record is the command's: a later ``main()`` in the same process would read it as its own.
    """
    assert not startup.interrupted()
    result = Runner(_TwoSignals("two"), MissionContext(robot=ClockRobot()), handle_signals=True).run()
    assert (result.stopped_by, result.exit_code) == ("signal", 130)
    assert not startup.interrupted()


def test_leaf_exception_becomes_failure_and_the_run_goes_on() -> None:
    """A raising leaf fails with an error event; the selector then tries its next child and succeeds."""
    root = py_trees.composites.Selector("root", memory=False, children=[
        ScriptedLeaf("broken", script="X"), ScriptedLeaf("fallback", script="S"),
    ])
    result, lines = capture_tick_log(root)
    assert result.status == Status.SUCCESS
    errors = [line for line in lines if line["event"] == "error"]
    assert errors and errors[0]["node"] == "broken" and "scripted error" in errors[0]["error"]


class _BrokenBehaviour(py_trees.behaviour.Behaviour):
    """A plain py_trees behaviour (not a Leaf) whose update raises."""

    def update(self) -> Status:
        raise ZeroDivisionError("division by zero in a plain behaviour")


def test_plain_behaviour_exception_becomes_failure_of_that_node() -> None:
    """An exception escaping a non-Leaf behaviour fails that node, logs an error and the run continues."""
    broken = _BrokenBehaviour("plain")
    fallback = ScriptedLeaf("ok", script="S")
    root = py_trees.composites.Selector("root", memory=False, children=[broken, fallback])
    result, lines = capture_tick_log(root)
    assert result.status == Status.SUCCESS
    errors = [line for line in lines if line["event"] == "error"]
    assert errors[0]["node"] == "root/plain"
    assert errors[0]["error"].startswith("ZeroDivisionError")
    first_tick = next(line for line in lines if line["event"] == "tick")
    failed = {c["node"]: c for c in first_tick["changed"] if c["status"] == "FAILURE"}
    assert "ZeroDivisionError" in failed["root/plain"]["reason"]


def test_a_plain_behaviours_fault_names_where_it_was_raised() -> None:
    """The reason of a non-Leaf node's error ends with the raising code's file:line and function."""
    broken = _BrokenBehaviour("plain")
    result, lines = capture_tick_log(py_trees.composites.Selector("root", memory=False, children=[broken]))
    assert result.status == Status.FAILURE
    first_tick = next(line for line in lines if line["event"] == "tick")
    reason = {c["node"]: c for c in first_tick["changed"]}["root/plain"]["reason"]
    line = _BrokenBehaviour.update.__code__.co_firstlineno + 1  # the raise
    assert reason.endswith(f"test_runner.py:{line} in update)"), reason
    error = next(line for line in lines if line["event"] == "error")
    assert error["error"] == reason and error["where"].endswith(f"test_runner.py:{line}")


class _BrokenDecorator(py_trees.decorators.Decorator):
    """A decorator whose update raises once its child is running."""

    def update(self) -> Status:
        raise KeyError("decorator bug")


def test_decorator_exception_halts_its_running_child() -> None:
    """When a decorator raises, its running child is halted (terminate INVALID) before it fails."""
    child = ScriptedLeaf("child", script="R")
    root = _BrokenDecorator(name="broken", child=child)
    result, _ = capture_tick_log(root)
    assert result.status == Status.FAILURE
    assert "terminate:INVALID" in child.calls


class _FailsSetup(Leaf):
    """A leaf whose setup fails (a missing device, say)."""

    def on_setup(self) -> None:
        raise OSError("camera not found")

    def update(self) -> Status:
        return Status.SUCCESS


def test_setup_failure_is_a_config_error_and_still_stops_the_robot() -> None:
    """A node failing setup raises ConfigError naming the node; the robot is stopped anyway."""
    robot = ClockRobot()
    root = py_trees.composites.Sequence("root", memory=True, children=[_FailsSetup("cam")])
    with pytest.raises(ConfigError, match="root/cam failed to set up: OSError: camera not found"):
        _runner(root, robot).run()
    assert robot.stop_calls == 1


class _DrawingRobot(ClockRobot):
    """A clock robot that draws a picture listing the markers."""

    def draw(self, out_dir: Path, markers: list[Marker]) -> list[Path]:
        path = out_dir / "map.txt"
        path.write_text("\n".join(m.kind for m in markers))
        return [path]


class _Marks(Leaf):
    """Adds a goal marker and succeeds."""

    def update(self) -> Status:
        self.context.mark("goal", 1.0, 2.0, "g1")
        return Status.SUCCESS


def test_run_directory_holds_log_summary_and_pictures(tmp_path: Path) -> None:
    """The run directory gets ticks.jsonl, summary.json and the pictures a Drawable robot draws."""
    root = py_trees.composites.Sequence("root", memory=True, children=[
        _Marks("mark"), ScriptedLeaf("nav", script="RF", reason="no path"),
    ])
    result = _runner(root, _DrawingRobot(), run_dir=tmp_path / "run", mission="demo").run()
    run_dir = tmp_path / "run"
    assert (run_dir / "map.txt").read_text() == "goal"
    summary = json.loads((run_dir / "summary.json").read_text())
    assert summary["status"] == "FAILURE" and summary["ticks"] == result.ticks == 2
    assert summary["nodes"]["root/nav"] == {"SUCCESS": 0, "FAILURE": 1}
    assert summary["failure_reasons"] == {"root/nav": ["no path"]}
    assert summary["pictures"] == ["map.txt"]
    lines = (run_dir / "ticks.jsonl").read_text().splitlines()
    assert json.loads(lines[0])["event"] == "mission_started"
    assert json.loads(lines[-1])["event"] == "mission_finished"



class _Serves(Leaf):
    """Reports what it served, twice (the last word stands), and succeeds."""

    def update(self) -> Status:
        self.context.report("intent", {"served": "cup_1", "confirmed": False})
        self.context.report("intent", {"served": "cup_2", "confirmed": True})
        return Status.SUCCESS


def test_what_leaves_report_is_the_summarys_outcome(tmp_path: Path) -> None:
    """A leaf's ``context.report`` lands in summary.json's ``outcome``; a run without one has none."""
    _runner(_Serves("serve"), run_dir=tmp_path / "run").run()
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["outcome"] == {"intent": {"served": "cup_2", "confirmed": True}}
    plain_run = _runner(ScriptedLeaf("a", script="S"), run_dir=tmp_path / "plain").run()
    assert "outcome" not in plain_run.summary

def test_blackboard_defaults_are_written_before_the_first_tick() -> None:
    """Blackboard defaults exist when the first tick runs and appear in its log line."""
    result, lines = capture_tick_log(ScriptedLeaf("a", script="S"), blackboard={"speed": 0.25})
    first_tick = next(line for line in lines if line["event"] == "tick")
    assert first_tick["bb"] == {"speed": 0.25}
    assert py_trees.blackboard.Blackboard.get("/speed") == 0.25


class _Recorder:
    """A plugin that records the mission hooks it receives."""

    def __init__(self) -> None:
        self.calls: list[str] = []

    @hookimpl
    def missiontree_mission_started(self, context: MissionContext, mission: object) -> None:
        self.calls.append(f"started:{mission}")

    @hookimpl
    def missiontree_mission_finished(self, context: MissionContext, summary: dict) -> None:
        self.calls.append(f"finished:{summary['status']}:{context.robot.stop_calls}")


def test_mission_hooks_are_called_around_the_run() -> None:
    """mission_started comes before the first tick; mission_finished after the robot was stopped."""
    plugins = fresh_plugins()
    recorder = _Recorder()
    plugins.pm.register(recorder)
    _runner(ScriptedLeaf("a", script="S"), hook=plugins.hook, spec="the-spec").run()
    assert recorder.calls == ["started:the-spec", "finished:SUCCESS:1"]


def test_failing_hook_is_a_plugin_error_after_cleanup() -> None:
    """A plugin hook that raises becomes a PluginError, and the robot is still stopped."""

    class Broken:
        @hookimpl
        def missiontree_mission_started(self, context: MissionContext, mission: object) -> None:
            raise RuntimeError("observer crashed")

    plugins = fresh_plugins()
    plugins.pm.register(Broken())
    robot = ClockRobot()
    with pytest.raises(PluginError, match="observer crashed"):
        _runner(ScriptedLeaf("a", script="S"), robot, hook=plugins.hook).run()
    assert robot.stop_calls == 1


@pytest.mark.parametrize("options", [{"tick_hz": 0}, {"tick_hz": float("nan")}, {"max_duration": -1.0}])
def test_bad_rate_or_limit_is_a_config_error(options: dict) -> None:
    """A non-positive tick rate or duration limit is refused with a ConfigError."""
    with pytest.raises(ConfigError):
        _runner(ScriptedLeaf("a"), **options)


def test_same_run_twice_gives_identical_log_bytes(tmp_path: Path) -> None:
    """On a simulated clock two identical runs write byte-identical tick logs with no wall time."""
    texts = []
    for name in ("one", "two"):
        clean_state()
        root = py_trees.composites.Sequence("root", memory=True, children=[
            ScriptedLeaf("a", script="RRS"), ScriptedLeaf("b", script="RX"),
        ])
        _runner(root, run_dir=tmp_path / name, mission="same").run()
        texts.append((tmp_path / name / "ticks.jsonl").read_bytes())
    assert texts[0] == texts[1]
    assert b"wall" not in texts[0]


def test_real_clock_robot_logs_wall_time() -> None:
    """On a robot whose clock is not simulated each line carries the wall-clock time."""
    context = MissionContext(robot=ClockRobot(simulated=False))
    _, lines = capture_tick_log(ScriptedLeaf("a", script="S"), context)
    assert all("wall" in line for line in lines)


class _BadCleanup(Leaf):
    """Runs forever; its terminate() raises (a cleanup bug)."""

    def update(self) -> Status:
        return Status.RUNNING

    def terminate(self, new_status: Status) -> None:
        if new_status == Status.INVALID:
            raise RuntimeError("cancel failed")


def test_leaf_whose_cleanup_raises_when_preempted_does_not_kill_the_run() -> None:
    """A running leaf halted by its parent whose terminate() raises is logged; the run goes on."""
    guard = ScriptedLeaf("guard", script="FS", restart=False)  # tick 2: succeeds, preempting "work"
    root = py_trees.composites.Selector("root", memory=False, children=[guard, _BadCleanup("work")])
    result, lines = capture_tick_log(root)
    assert result.status == Status.SUCCESS
    errors = [line for line in lines if line["event"] == "error"]
    assert errors and "cancel failed" in errors[0]["error"]


def test_halt_reaches_every_leaf_even_when_one_cleanup_raises() -> None:
    """At the limit, a leaf whose cancel raises does not stop the other running leaves from being halted."""
    bad, good = _BadCleanup("bad"), ScriptedLeaf("good", script="R")
    policy = py_trees.common.ParallelPolicy.SuccessOnAll(synchronise=False)
    root = py_trees.composites.Parallel("root", policy=policy, children=[bad, good])
    robot = ClockRobot()
    result = _runner(root, robot, max_duration=0.3).run()
    assert result.stopped_by == "limit"
    assert good.calls[-1] == "terminate:INVALID"
    assert robot.stop_calls == 1


class _Custom(py_trees.composites.Sequence):
    """A subclass of a py_trees composite: may override anything, so it is guarded."""


def test_only_py_trees_own_types_go_unguarded() -> None:
    """py_trees' own Sequence is ticked without a wrapper; a subclass and a plain behaviour get one."""
    from missiontree.engine.runner import guard_exceptions

    plain_seq = py_trees.composites.Sequence("s", memory=True)
    custom, broken = _Custom("c", memory=True), _BrokenBehaviour("b")
    root = py_trees.composites.Sequence("root", memory=True, children=[plain_seq, custom, broken])
    guard_exceptions(root, lambda node, error: None)
    assert "tick" not in vars(plain_seq) and "tick" not in vars(root)
    assert "tick" in vars(custom) and "tick" in vars(broken)


class _SignalsTwice(Leaf):
    """Sends SIGINT twice in one tick (an impatient user)."""

    def update(self) -> Status:
        os.kill(os.getpid(), signal.SIGINT)
        os.kill(os.getpid(), signal.SIGINT)
        return Status.RUNNING

    def terminate(self, new_status: Status) -> None:
        self.halted_with = new_status


def test_second_signal_interrupts_at_once_but_still_halts_and_stops() -> None:
    """A second SIGINT in a tick interrupts it; the tree is halted, the robot stopped, the run ends by signal.

    It used to leave the summary saying ``stopped_by: error, status: INVALID``.
    """
    before = signal.getsignal(signal.SIGINT)  # SIG_IGN when the suite runs as a background job
    leaf = _SignalsTwice("impatient")
    robot = ClockRobot()
    result = Runner(leaf, MissionContext(robot=robot), handle_signals=True).run()
    assert (result.stopped_by, result.status, result.exit_code) == ("signal", Status.RUNNING, 130)
    assert result.summary["signal"] == "SIGINT" and result.summary["complete"] is True
    assert leaf.halted_with == Status.INVALID
    assert robot.stop_calls == 1
    assert signal.getsignal(signal.SIGINT) == before  # whatever it was, it is back


def test_realtime_paces_ticks_to_wall_time() -> None:
    """With realtime on, five ticks at 20 Hz take at least 0.2 s of wall time."""
    import time

    start = time.monotonic()
    _runner(ScriptedLeaf("a", script="RRRRS"), tick_hz=20, realtime=True).run()
    assert time.monotonic() - start >= 0.19


class _SlowModelLeaf(Leaf):
    """Asks a model that takes ``seconds`` of wall time (simulated latency 0.1 s) and waits for it."""

    seconds = 1.0

    def initialise(self) -> None:
        import time

        from missiontree.reasoning.calls import model_caller

        self.call = model_caller(self.context).submit("vlm", time.sleep, self.seconds, node=self.name)

    def update(self) -> Status:
        status = self.call.status()
        if not status.done:
            return self.running("waiting for the model")
        return Status.SUCCESS if status.value == "succeeded" else self.fail(self.call.error())

    def terminate(self, new_status: Status) -> None:
        if getattr(self, "call", None) is not None:
            self.call.cancel()


def _slow_model_context(robot: ClockRobot) -> MissionContext:
    from missiontree.reasoning.calls import SETTINGS_KEY, CallSettings, LatencyModel

    settings = CallSettings(latency={"vlm": LatencyModel(0.1, 0.1)}, timeouts={"vlm": 10.0})
    return MissionContext(robot=robot, models={SETTINGS_KEY: settings})


def test_realtime_run_is_not_stalled_by_a_slow_model_call() -> None:
    """Paced to wall time, a 1 s model call leaves the 20 Hz ticks on time; the answer arrives later."""
    import time

    robot = ClockRobot()
    stamps: list[float] = []
    runner = Runner(_SlowModelLeaf("ask"), _slow_model_context(robot), tick_hz=20, realtime=True,
                    handle_signals=False, on_tick=lambda r: stamps.append(time.monotonic()))
    result = runner.run()
    assert result.status == Status.SUCCESS
    gaps = [b - a for a, b in zip(stamps, stamps[1:], strict=False)]
    assert max(gaps) < 0.4, f"a tick waited {max(gaps):.2f} s for the model"
    assert result.duration >= 0.9  # the answer showed when the worker finished, not at 0.1 s


def test_fast_run_still_waits_for_the_model_deterministically() -> None:
    """As fast as possible, the answer shows at exactly submit + simulated latency (robot clock)."""
    robot = ClockRobot()
    leaf = _SlowModelLeaf("ask")
    leaf.seconds = 0.2
    result = Runner(leaf, _slow_model_context(robot), tick_hz=20, handle_signals=False).run()
    assert result.status == Status.SUCCESS
    assert result.ticks == 3  # submitted at t=0, due at t=0.1: seen on the tick at t=0.1


class _QuietClock(ClockRobot):
    """A clock robot that keeps no list of its spins (so only the engine's memory is measured)."""

    def spin_until(self, t: float) -> None:
        self.time = max(self.time, t)


class _Blink(Leaf):
    """RUNNING on its first tick, SUCCESS on the next; writes the blackboard as it goes."""

    def initialise(self) -> None:
        self.ticked = False

    def update(self) -> Status:
        py_trees.blackboard.Blackboard.set("/step", self.name)
        if self.ticked:
            return Status.SUCCESS
        self.ticked = True
        return Status.RUNNING


def test_runner_and_tick_log_memory_stays_flat_on_a_long_run() -> None:
    """3,000 ticks of a looping plan (changes and blackboard writes every tick) keep memory flat."""
    import gc
    import tracemalloc

    plan = py_trees.composites.Sequence("plan", memory=True, children=[_Blink(f"s{i}") for i in range(20)])
    root = py_trees.decorators.Repeat("loop", plan, num_success=-1)
    robot = _QuietClock()
    with open(os.devnull, "w", encoding="utf-8") as sink:
        runner = Runner(root, MissionContext(robot=robot), log_stream=sink, handle_signals=False)
        runner.setup()
        tracemalloc.start()
        try:
            sizes = []
            for index in range(3000):
                runner.tick()
                robot.spin_until((index + 1) * 0.1)
                if index + 1 in (500, 3000):
                    gc.collect()
                    sizes.append(tracemalloc.get_traced_memory()[0])
        finally:
            tracemalloc.stop()
    assert sizes[1] - sizes[0] < 32 * 1024, f"grew {sizes[1] - sizes[0]} bytes over 2,500 ticks"


def test_a_summary_that_cannot_be_written_is_a_clear_error_after_the_robot_stopped(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A full disk at the end: ConfigError (exit 2) saying the summary was not written; robot stopped."""
    import errno

    robot = ClockRobot()
    runner = _runner(ScriptedLeaf("a", script="RRS"), robot, run_dir=tmp_path)
    original = RunRecorder.write_summary

    def full_at_the_end(self: RunRecorder, summary: dict) -> None:
        if summary.get("complete"):
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        original(self, summary)

    monkeypatch.setattr(RunRecorder, "write_summary", full_at_the_end)
    with pytest.raises(ConfigError, match="summary could not be written .*No space left on device"):
        runner.run()
    assert robot.stop_calls == 1
    assert json.loads((tmp_path / "summary.json").read_text())["complete"] is False  # the start's, valid
    assert json.loads((tmp_path / "ticks.jsonl").read_text().splitlines()[-1])["event"] == "mission_finished"


def test_run_directory_that_is_a_file_is_a_config_error(tmp_path: Path) -> None:
    """The runner alone (no session) given a file as its directory: ConfigError, robot stopped."""
    afile = tmp_path / "afile"
    afile.write_text("x")
    robot = ClockRobot()
    with pytest.raises(ConfigError, match="cannot write the run directory"):
        _runner(ScriptedLeaf("a", script="S"), robot, run_dir=afile).run()
    assert robot.stop_calls == 1 and afile.read_text() == "x"


def test_a_non_leaf_error_event_has_its_file_line_and_frames() -> None:
    """A plain behaviour's error event names file:line and lists the frames, as a leaf's does."""
    root = py_trees.composites.Selector("root", memory=False, children=[_BrokenBehaviour("plain")])
    _, lines = capture_tick_log(root)
    error = next(line for line in lines if line["event"] == "error")
    assert error["where"].startswith("tests/engine/test_runner.py:")
    assert error["function"] == "update"
    assert "(at tests/engine/test_runner.py:" in error["error"]
    assert error["traceback"] and error["traceback"][-1].endswith(" in update")


def test_the_summary_fault_lists_the_traceback_frames_without_source(tmp_path: Path) -> None:
    """A run that fails on a non-Leaf error: summary.json's fault has file:line frames, no source text."""
    result = _runner(_BrokenBehaviour("plain"), run_dir=tmp_path / "run").run()
    assert result.status == Status.FAILURE
    fault = json.loads((tmp_path / "run" / "summary.json").read_text())["fault"]
    assert fault["node"] == "plain"
    frames = fault["traceback"]
    assert frames and frames[-1].startswith("tests/engine/test_runner.py:")
    assert frames[-1].endswith(" in update")
    assert not any("raise ZeroDivisionError" in frame for frame in frames)


def test_the_summary_fault_of_a_leaf_lists_its_frames(tmp_path: Path) -> None:
    """A leaf's fault in summary.json carries the frames of its error event."""
    result = _runner(_RaisingLeaf("bad"), run_dir=tmp_path / "run").run()
    assert result.status == Status.FAILURE
    fault = json.loads((tmp_path / "run" / "summary.json").read_text())["fault"]
    assert fault["node"] == "bad"
    assert any(frame.endswith(" in update") for frame in fault["traceback"])


class _RaisingLeaf(Leaf):
    """A leaf whose update raises."""

    def update(self) -> Status:
        raise RuntimeError("leaf bug")
