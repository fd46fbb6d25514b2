"""One mission, several robots: the tree instantiated per robot, ticked together on one clock.

The session (:mod:`missiontree.session.fleet`) builds the mission's tree once per robot and hangs
the copies under a :class:`FleetRoot`, each copy inside a :class:`RobotScope` named after its robot
(so tick-log node paths read ``fleet/robot2/patrol``). What ties the robots together lives here:

- :class:`FleetView` (``context.fleet`` in every robot's context): the robot names, which robots
  are lost and why, and ``shared(key, make)``, one object per fleet that every robot's leaves see
  (a dispatcher). Listeners registered with :meth:`FleetView.on_loss` take over a lost robot's work.
- :class:`RobotEvents`: the event sink of one robot's leaves; every event carries ``robot``.
- :func:`namespace_tree`: a copy's blackboard keys moved under ``/<robot>/`` (``/robot1/patrol_waypoint``);
  keys written under ``/fleet/`` stay shared.

Outcome (:class:`FleetRoot`): a robot whose tree fails is lost (``robot_lost`` event, its robot
stopped) and the listeners are told; the fleet fails when every robot failed, or when a robot was
lost and no listener took over its work (a plain tree copied per robot has nobody to take it).
Otherwise the fleet succeeds when every robot's tree has ended.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import py_trees

from missiontree.events import EventSink

Status = py_trees.common.Status
Behaviour = py_trees.behaviour.Behaviour

#: The blackboard namespace every robot shares (``/fleet/...``); other keys go under ``/<robot>/``.
SHARED_NAMESPACE = "/fleet/"

__all__ = ["SHARED_NAMESPACE", "FleetRoot", "FleetView", "RobotEvents", "RobotScope", "namespace_tree"]


class FleetView:
    """What a fleet's leaves share: robot names, losses, and one object per key.

    Args:
        names: The robots' names, in fleet order.
        clock: The fleet's clock (seconds).
    """

    def __init__(self, names: list[str], clock: Callable[[], float]) -> None:
        self.names = list(names)
        self.clock = clock
        #: Lost robots: name -> {"t": time, "reason": why, "taken_over": whether a listener took its work}.
        self.lost: dict[str, dict[str, Any]] = {}
        self._shared: dict[str, Any] = {}
        self._listeners: list[Callable[[str, str], bool]] = []
        #: Where fleet-level events go (the runner's log; set by the session).
        self.events: EventSink | None = None

    def live(self) -> list[str]:
        """The robots not lost, in fleet order."""
        return [n for n in self.names if n not in self.lost]

    def shared(self, key: str, make: Callable[[], Any]) -> Any:
        """The fleet's one object under ``key``, made by ``make`` on the first call."""
        if key not in self._shared:
            self._shared[key] = make()
        return self._shared[key]

    def shared_items(self) -> list[tuple[str, Any]]:
        """Every shared object with its key (the session reports the dispatchers from them)."""
        return list(self._shared.items())

    def on_loss(self, listener: Callable[[str, str], bool]) -> None:
        """Call ``listener(name, reason)`` when a robot is lost; it returns True when it took the work."""
        if listener not in self._listeners:
            self._listeners.append(listener)

    def lose(self, name: str, reason: str) -> bool:
        """Mark ``name`` lost (once), emit ``robot_lost``, tell the listeners: did one take its work."""
        if name in self.lost:
            return bool(self.lost[name]["taken_over"])
        record: dict[str, Any] = {"t": self.clock(), "reason": reason, "taken_over": False}
        self.lost[name] = record
        if self.events is not None:
            self.events.emit("robot_lost", robot=name, reason=reason, live=self.live())
        for listener in self._listeners:
            if listener(name, reason):
                record["taken_over"] = True
        return bool(record["taken_over"])


class RobotEvents:
    """An event sink that adds ``robot=<name>`` to every event, in front of the run's sink."""

    def __init__(self, inner: EventSink, robot: str) -> None:
        self.inner = inner
        self.robot = robot
        #: Events emitted through this sink, by kind.
        self.counts: dict[str, int] = {}

    def emit(self, event: str, /, **fields: Any) -> None:
        """Forward ``event`` with the robot's name."""
        self.counts[event] = self.counts.get(event, 0) + 1
        fields.setdefault("robot", self.robot)
        self.inner.emit(event, **fields)


class RobotScope(py_trees.decorators.Decorator):
    """One robot's copy of the tree: passes its child's status through; named after the robot."""

    def __init__(self, robot: str, child: Behaviour) -> None:
        super().__init__(name=robot, child=child)
        self.robot = robot

    def update(self) -> Status:
        """The child's status."""
        return self.decorated.status


class FleetRoot(py_trees.composites.Composite):
    """Ticks every robot's scope each tick; a failed robot is lost, the fleet goes on (see module doc).

    Args:
        scopes: One :class:`RobotScope` per robot.
        view: The fleet's shared view (losses are recorded there).
        stop_robot: Called with a robot's name when its tree failed (the session stops that robot).
    """

    def __init__(self, scopes: list[RobotScope], view: FleetView,
                 stop_robot: Callable[[str], None] | None = None) -> None:
        super().__init__(name="fleet", children=list(scopes))
        self.view = view
        self.stop_robot = stop_robot
        #: Each robot's final status and reason once its tree ended: name -> {"status", "reason", "t"}.
        self.ended: dict[str, dict[str, Any]] = {}
        self.untaken: list[str] = []

    def tick(self) -> Any:
        """Tick each robot whose tree has not ended, then decide the fleet's status."""
        if self.status is not Status.RUNNING:
            self.initialise()
        for scope in self.children:
            if scope.name in self.ended:
                continue
            yield from scope.tick()
            if scope.status in (Status.SUCCESS, Status.FAILURE):
                self._ended(scope)
        self.status = self._decide()
        if self.status is not Status.RUNNING:
            self.stop(self.status)
        yield self

    def initialise(self) -> None:
        """A fresh start: no robot has ended."""
        self.ended = {}
        self.untaken = []

    def _ended(self, scope: Behaviour) -> None:
        reason = _reason_below(scope) if scope.status is Status.FAILURE else ""
        self.ended[scope.name] = {"status": scope.status.name, "reason": reason, "t": self.view.clock()}
        if scope.status is Status.FAILURE:
            if self.stop_robot is not None:
                self.stop_robot(scope.name)
            if not self.view.lose(scope.name, reason or "its tree failed"):
                self.untaken.append(scope.name)

    def _decide(self) -> Status:
        if len(self.ended) < len(self.children):
            if self.untaken or not self.view.live():
                return Status.FAILURE
            return Status.RUNNING
        if all(e["status"] == Status.FAILURE.name for e in self.ended.values()) or self.untaken:
            return Status.FAILURE
        return Status.SUCCESS

    def stop(self, new_status: Status = Status.INVALID) -> None:
        """Halt every robot's scope still running."""
        for child in self.children:
            if child.status is Status.RUNNING or new_status is Status.INVALID:
                child.stop(Status.INVALID)
        self.status = new_status

    def robot_report(self) -> dict[str, dict[str, Any]]:
        """Each robot's end: its status (RUNNING when it had not ended), reason, time and loss."""
        report: dict[str, dict[str, Any]] = {}
        for name in self.view.names:
            end = dict(self.ended.get(name, {"status": Status.RUNNING.name, "reason": "", "t": None}))
            if name in self.view.lost:
                end["lost"] = dict(self.view.lost[name])
            report[name] = end
        return report


def _reason_below(node: Behaviour) -> str:
    """Why ``node`` failed: down the chain of failed children, the last failed child each time.

    The last one is the child whose failure ended its parent (a Selector's last try, a Sequence's
    failed step), not an earlier one a parent absorbed (a guard that failed as it does every tick).
    """
    while node.children:
        failed = [child for child in node.children if child.status is Status.FAILURE]
        if not failed:
            break
        node = failed[-1]
    return str(node.feedback_message or "")


def namespace_tree(root: Behaviour, robot: str) -> list[str]:
    """Move every blackboard key of ``root``'s nodes under ``/<robot>/`` (``/fleet/`` keys stay shared).

    Each node's clients keep the keys they registered (a leaf still reads ``patrol_waypoint``); only
    where the value is stored changes. Returns the keys moved, as stored.
    """
    moved: list[str] = []
    access = py_trees.common.Access
    for node in root.iterate():
        for client in node.blackboards:
            kinds = [(key, access.READ) for key in client.read]
            kinds += [(key, access.WRITE) for key in client.write]
            kinds += [(key, access.EXCLUSIVE_WRITE) for key in client.exclusive]
            for key, kind in kinds:
                stored = client.remappings.get(key, key)
                if stored.startswith(SHARED_NAMESPACE) or stored.startswith(f"/{robot}/"):
                    continue
                client.unregister_key(key, clear=False)
                target = f"/{robot}{stored}" if stored.startswith("/") else f"/{robot}/{stored}"
                client.register_key(key, kind, remap_to=target)
                moved.append(target)
    return sorted(set(moved))
