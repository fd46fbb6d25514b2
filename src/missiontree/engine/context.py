"""What a running mission gives its leaves: the robot, the models, the event sink, the run directory.

Leaves receive it in ``setup(context=...)`` (py_trees passes setup keyword arguments to every
node), never in their constructor: trees build, validate and render with no robot. The session
fills it whole before any leaf sees it: the model providers by role, the mission's bound model
caller (``calls``), the event sink; a ``BuildSceneGraph`` leaf adds the live ``scene``. The
services are typed by protocols under everything (:mod:`missiontree.services`,
:mod:`missiontree.events`): the engine names no map and no model.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from missiontree.events import EventSink, NullEvents
from missiontree.robot.interface import Robot
from missiontree.services import ModelCalls, Scene
from missiontree.types import Marker

__all__ = ["MAX_MARKERS", "EventSink", "MissionContext", "NullEvents"]

#: Most markers a run keeps for its picture; past it the oldest is dropped (a patrol that runs for
#: days marks one alarm per encounter: the list must not grow with the run).
MAX_MARKERS = 2000


@dataclass
class MissionContext:
    """Everything a leaf may use at run time.

    Attributes:
        robot: The robot (simulated or ROS 2).
        models: Model providers by role (``detector``, ``vlm``, ``llm``, ``embedder``, ...): the
            session's :class:`missiontree.reasoning.models.Models` (a mapping, so ``models[role]``
            reads a provider); use :meth:`model` for a message naming the configured roles.
        calls: The mission's model caller (:class:`missiontree.reasoning.calls.ModelCaller`), bound
            by the session before any leaf is set up; None for a context made by hand (then
            ``reasoning.calls.model_caller(context)`` makes one on first use).
        events: Sink for typed tick-log events.
        run_dir: The run's output directory (alarm frames, pictures), None when not writing.
        markers: Things to draw on the run's top-down picture, added through :meth:`mark`:
            bounded (:data:`MAX_MARKERS`, oldest dropped first), and a repeat of a marker already
            kept (same kind, label and spot, e.g. a patrol's goal on every lap) is not added again.
        markers_dropped: How many markers :meth:`mark` dropped to keep the bound.
        config: Free-form run configuration (from ``--config``).
        seed: The run's random seed.
        started_files: Run-directory files this run has begun (see :meth:`starts`).
        realtime: The run is paced to wall time (set by the runner): model calls then never wait
            for a worker on the tick thread, even in the simulator.
        scene: The live scene (a :class:`~missiontree.services.Scene` such as
            :class:`missiontree.semantics.live.LiveScene`: semantic map, rooms, latest scene graph)
            once a ``BuildSceneGraph`` leaf has set it up; None before.
        outcome: What the mission did, in its own words, through :meth:`report`: summary.json's
            ``outcome`` section (which object was served and why, what the exploration left, ...).
        fleet: In a fleet run (``run: robots: N``), what the robots share
            (:class:`missiontree.engine.fleet.FleetView`: names, losses, one dispatcher); None for
            a single robot.
    """

    robot: Robot
    models: dict[str, Any] = field(default_factory=dict)
    events: EventSink = field(default_factory=NullEvents)
    run_dir: Path | None = None
    markers: list[Marker] = field(default_factory=list)
    config: dict[str, Any] = field(default_factory=dict)
    seed: int = 0
    started_files: set[Path] = field(default_factory=set)
    realtime: bool = False
    scene: Scene | None = None
    markers_dropped: int = 0
    outcome: dict[str, Any] = field(default_factory=dict)
    calls: ModelCalls | None = None
    fleet: Any = None
    _marker_keys: set[tuple[str, str, float, float]] = field(default_factory=set, repr=False)

    def report(self, section: str, value: Any) -> None:
        """Put ``value`` (plain JSON data) under ``section`` of summary.json's ``outcome``.

        A leaf reports what its mission did there, e.g. ``report("intent", {"served": ...})``;
        a later report of the same section replaces the earlier one (the last word stands).
        """
        self.outcome[section] = value

    def starts(self, path: Path) -> bool:
        """Whether ``path`` in the run directory is new to this run (True once, on the first call).

        A run writes into a directory that an earlier run may have used: the first write of a
        file replaces what the earlier run left there, and later writes of this run add to it.
        """
        key = Path(path).resolve()
        if key in self.started_files:
            return False
        self.started_files.add(key)
        return True

    def mark(self, kind: str, x: float, y: float, label: str = "") -> None:
        """Add a marker for the run's picture at the current time (a repeat is not added again).

        The picture draws a repeat (same kind and label within a centimetre) exactly as the first, so
        a patrol's goals add one marker per waypoint, not one per lap. Past :data:`MAX_MARKERS` the
        oldest marker is dropped and counted in :attr:`markers_dropped`.
        """
        key = (kind, label, round(x, 2), round(y, 2))
        if key in self._marker_keys:
            return
        while len(self.markers) >= MAX_MARKERS:
            old = self.markers.pop(0)
            self._marker_keys.discard((old.kind, old.label, round(old.x, 2), round(old.y, 2)))
            self.markers_dropped += 1
        self.markers.append(Marker(kind, x, y, self.robot.now(), label))
        self._marker_keys.add(key)

    def model(self, role: str) -> Any:
        """The provider configured for ``role``; raises ConfigError naming the known roles."""
        from missiontree.errors import ConfigError

        try:
            return self.models[role]
        except KeyError:
            known = ", ".join(sorted(self.models)) or "none"
            raise ConfigError(
                f"no model configured for role {role!r} (configured: {known}); "
                f"add it to the models config (config/models/*.yaml)"
            ) from None
