"""Test helpers shipped in the package, not only in its test suite: use them in your own plugin's tests too.

- :class:`ClockRobot`: a test double of the Robot protocol with only a clock — enough for engine
  and blackboard-only trees. Its sensors are empty and navigation is refused; it records the
  ``stop()`` calls. Not a simulator: use ``missiontree.backends.sim`` for real behaviour tests.
- :class:`ScriptedLeaf`: a leaf that returns a given sequence of statuses, recording its lifecycle.
- :func:`tick_until`: tick a tree until its root reaches a status.
- :func:`capture_tick_log`: run a tree with the runner and get the tick log lines back.
- :func:`clean_state`: reset py_trees' blackboard and structlog's context (call it in a fixture).
- :func:`fresh_plugins`: a fresh plugin manager, entry-point plugins off unless asked.
- :mod:`missiontree.testing_models`: conformance suites for model providers (Detector,
  VisionLanguageModel, LanguageModel, Embedder); :mod:`missiontree.robot.conformance` for backends.
- :meth:`ClockRobot.add_sensor` / :meth:`ClockRobot.set_sensor`: plugin sensor readings for leaf tests.
"""

from __future__ import annotations

import io
import json
from collections.abc import Iterable
from typing import Any

import py_trees
import structlog
from pydantic import BaseModel, Field

from missiontree.engine.context import MissionContext
from missiontree.engine.leaf import Leaf, Status
from missiontree.errors import BackendError
from missiontree.robot.actions import ActionHandle
from missiontree.robot.sensors import SensorKind, SensorReading, SensorStore
from missiontree.types import LaserScan, OccupancyGrid, Pose2D, PoseStamped, RGBDFrame, Tolerance

_STATUS = {"S": Status.SUCCESS, "F": Status.FAILURE, "R": Status.RUNNING}


class ClockRobot:
    """A test double: a robot that is only a simulated clock (no sensors, no navigation).

    ``spin_until(t)`` jumps the clock to ``t``; the runner therefore ticks as fast as possible.
    Calls to ``stop()`` are counted so tests can check that a run stopped the robot.

    Args:
        start: The clock's initial time in seconds.
        simulated: Report simulated time (True) or pretend to be a real robot (False).
    """

    def __init__(self, start: float = 0.0, simulated: bool = True) -> None:
        self.name = "clock"
        self.simulated = simulated
        self.time = start
        self.stop_calls = 0
        self.closed = False
        self.spins: list[float] = []
        self.sensor_store = SensorStore()

    def now(self) -> float:
        """The clock's time."""
        return self.time

    def spin_until(self, t: float) -> None:
        """Move the clock to ``t`` (never backwards)."""
        self.spins.append(t)
        self.time = max(self.time, t)

    def pose(self) -> PoseStamped | None:
        """No localisation: None."""
        return None

    def scan(self) -> LaserScan | None:
        """No lidar: None."""
        return None

    def rgbd(self) -> RGBDFrame | None:
        """No camera: None."""
        return None

    def occupancy(self) -> OccupancyGrid | None:
        """No map: None."""
        return None

    def pose_at(self, stamp: float) -> Pose2D | None:
        """No history: None."""
        return None

    def sensor(self, name: str) -> SensorReading | None:
        """A reading set with :meth:`set_sensor`, None before; unknown names raise as on a robot."""
        return self.sensor_store.get(name)

    def sensor_names(self) -> list[str]:
        """The sensors given to :meth:`add_sensor`."""
        return self.sensor_store.names()

    def sensor_kind(self, name: str) -> SensorKind:
        """What plugin sensor ``name`` is (UnknownSensorError naming the robot's sensors otherwise)."""
        return self.sensor_store.kind(name)

    def add_sensor(self, kind: SensorKind) -> None:
        """Give the double a plugin sensor (no readings until :meth:`set_sensor`)."""
        self.sensor_store = SensorStore([*self.sensor_store.kinds.values(), kind])

    def set_sensor(self, name: str, value: Any, stamp: float | None = None) -> None:
        """Record a reading of sensor ``name`` stamped ``stamp`` (default: the clock now)."""
        self.sensor_store.put(name, self.time if stamp is None else stamp, value)

    def scan_at(self, stamp: float) -> LaserScan | None:
        """No history: None."""
        return None

    def navigate_to(self, goal: Pose2D, tolerance: Tolerance | None = None) -> ActionHandle:
        """Navigation is not part of this double."""
        raise BackendError("ClockRobot cannot navigate; use the simulator backend for motion tests")

    def drive(self, v: float, w: float) -> None:
        """Accept and ignore a velocity command."""

    def stop(self) -> None:
        """Count the call."""
        self.stop_calls += 1

    def close(self) -> None:
        """Mark closed."""
        self.stop()
        self.closed = True


class ScriptedLeaf(Leaf):
    """Returns the scripted statuses in turn (last one repeats); records its lifecycle.

    Script letters: ``S`` success, ``F`` failure, ``V`` failure that is a verdict (see
    :mod:`missiontree.engine.faults`), ``R`` running, ``X`` raise an error. The
    script restarts each time the leaf is initialised, unless ``restart`` is False (then it
    goes on across runs: ``FS`` fails on the first tick and succeeds on every later one).
    """

    class Params(BaseModel):
        script: str = Field("S", description="statuses to return, one letter a tick: S, F, V, R or X")
        reason: str = Field("scripted failure", description="failure reason given on F")
        restart: bool = Field(True, description="start the script again at each initialise")

    def __init__(self, name: str, params: BaseModel | None = None, **kwargs: Any) -> None:
        if params is None and kwargs:
            params = self.Params(**kwargs)
        super().__init__(name, params)
        self.calls: list[str] = []
        self._step = 0

    def initialise(self) -> None:
        """Restart the script."""
        self.calls.append("initialise")
        if self.params.restart:  # type: ignore[attr-defined]
            self._step = 0

    def update(self) -> Status:
        """Return the next scripted status."""
        self.calls.append("update")
        script = self.params.script  # type: ignore[attr-defined]
        letter = script[min(self._step, len(script) - 1)]
        self._step += 1
        if letter == "X":
            raise RuntimeError(f"{self.name}: scripted error")
        if letter in "FV":
            return self.fail(self.params.reason, verdict=letter == "V")  # type: ignore[attr-defined]
        if letter == "R":
            return self.running(f"step {self._step}")
        return self.succeed()

    def terminate(self, new_status: Status) -> None:
        """Record how it ended (``terminate:INVALID`` means it was halted)."""
        self.calls.append(f"terminate:{new_status.name}")


def tick_until(
    root: py_trees.behaviour.Behaviour,
    statuses: Iterable[Status] = (Status.SUCCESS, Status.FAILURE),
    max_ticks: int = 100,
) -> int:
    """Tick ``root`` until its status is one of ``statuses``; return the number of ticks.

    Raises:
        AssertionError: It did not get there within ``max_ticks``.
    """
    wanted = set(statuses)
    for count in range(1, max_ticks + 1):
        root.tick_once()
        if root.status in wanted:
            return count
    raise AssertionError(f"{root.name} still {root.status.name} after {max_ticks} ticks")


def capture_tick_log(root: py_trees.behaviour.Behaviour, context: MissionContext | None = None,
                     **options: Any) -> tuple[Any, list[dict[str, Any]]]:
    """Run ``root`` with the runner (on a :class:`ClockRobot` unless ``context`` says otherwise).

    ``options`` go to :class:`~missiontree.engine.runner.Runner`; ``max_duration`` defaults to 60 s.

    Returns:
        The :class:`~missiontree.engine.runner.RunResult` and the tick log, one dict per line.
    """
    from missiontree.engine.runner import Runner

    context = context or MissionContext(robot=ClockRobot())
    stream = io.StringIO()
    options.setdefault("handle_signals", False)
    options.setdefault("max_duration", 60.0)  # a test tree that never ends must not hang the suite
    result = Runner(root, context, log_stream=stream, **options).run()
    return result, [json.loads(line) for line in stream.getvalue().splitlines()]


def clean_state() -> None:
    """Reset process-global state: py_trees' blackboard, structlog's context and configuration, secrets."""
    from missiontree.redact import forget_secrets

    forget_secrets()
    py_trees.blackboard.Blackboard.clear()
    structlog.contextvars.clear_contextvars()
    structlog.reset_defaults()


def fresh_plugins(autoload: bool = False, strict: bool = False) -> Any:
    """A fresh :class:`~missiontree.plugins.manager.Plugins` (entry-point plugins off by default).

    ``strict=True`` raises on a broken plugin instead of leaving it out: a plugin's own tests use it
    to see their plugin's error.
    """
    from missiontree.plugins.manager import load_plugins

    return load_plugins(autoload=autoload, strict=strict)
