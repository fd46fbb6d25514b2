"""The safety envelope: where goals may go and how fast the robot may move, checked in code.

A model that proposes a goal ("the kitchen is at (12, 3)") or a blackboard value that becomes one
is untrusted: the goal may lie outside the building, on the stairs, or in a room the operator
closed. The envelope is declared once, in the run configuration (``--config``, section
``safety``), in the map frame::

    safety:
      geofence: [[-1, -1], [12, -1], [12, 8], [-1, 8]]   # goals must lie inside (a polygon)
      keep_out:                                          # goals must lie outside each of these
        - {name: stairs, polygon: [[4, 6], [6, 6], [6, 8], [4, 8]]}
      max_linear: 0.25                                   # m/s, caps every velocity command
      max_angular: 1.0                                   # rad/s

:class:`EnvelopedRobot` wraps any backend's robot (simulator, ROS 2, a recording) so that every
goal is checked *before* it is sent: a goal outside the geofence or inside a keep-out zone comes
back at once as a REJECTED action whose reason names the zone (the leaf fails with it; the tick
log gets a ``safety_refused`` event), and every velocity command is capped, a non-finite one
refused. Nothing a leaf, a model or a plugin does can go around it: leaves see only the wrapped
robot. This is the code-enforced check ROSA's blacklist stands for, applied to goals and speeds.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from missiontree.errors import BackendError, ConfigError
from missiontree.robot.actions import RefusedAction
from missiontree.types import Pose2D, Tolerance

__all__ = ["REFUSED", "Envelope", "EnvelopedRobot", "Zone", "enveloped", "parse_envelope", "unwrap",
           "wrap_robot"]
#: The keys of a ``safety`` section.
KEYS = ("geofence", "keep_out", "max_linear", "max_angular")

#: Failure kind of a goal the envelope refused (not a fault of the robot: the goal was not allowed).
REFUSED = "refused"
#: Most vertices a polygon may have (a declared zone is a few corners, never a traced map).
MAX_VERTICES = 1000
#: Most keep-out zones.
MAX_ZONES = 200

Point = tuple[float, float]


@dataclass(frozen=True)
class Zone:
    """A named polygon in the map frame (vertices in order, closed implicitly)."""

    name: str
    polygon: tuple[Point, ...]

    def contains(self, x: float, y: float) -> bool:
        """Whether (x, y) lies inside the polygon or on its edge (even-odd rule)."""
        inside = False
        points = self.polygon
        for i, (x1, y1) in enumerate(points):
            x2, y2 = points[i - 1]
            if _on_segment(x, y, x1, y1, x2, y2):
                return True
            if (y1 > y) != (y2 > y) and x < (x2 - x1) * (y - y1) / (y2 - y1) + x1:
                inside = not inside
        return inside


def _on_segment(x: float, y: float, x1: float, y1: float, x2: float, y2: float) -> bool:
    cross = (x2 - x1) * (y - y1) - (y2 - y1) * (x - x1)
    if abs(cross) > 1e-9 * max(1.0, math.hypot(x2 - x1, y2 - y1)):
        return False
    return min(x1, x2) - 1e-9 <= x <= max(x1, x2) + 1e-9 and min(y1, y2) - 1e-9 <= y <= max(y1, y2) + 1e-9


@dataclass(frozen=True)
class Envelope:
    """Where goals may go and how fast the robot may move.

    Attributes:
        geofence: Goals must lie inside it (None: anywhere).
        keep_out: Goals must lie outside each zone.
        max_linear: Cap on |v| of velocity commands (m/s), None for none.
        max_angular: Cap on |w| (rad/s), None for none.
    """

    geofence: Zone | None = None
    keep_out: tuple[Zone, ...] = ()
    max_linear: float | None = None
    max_angular: float | None = None

    def refusal(self, goal: Pose2D) -> str:
        """Why ``goal`` may not be sent ("" when it may)."""
        x, y = goal.x, goal.y
        if not all(math.isfinite(v) for v in (x, y, goal.yaw)):
            return f"goal ({x}, {y}, {goal.yaw}) is not a finite pose"
        if self.geofence is not None and not self.geofence.contains(x, y):
            return f"goal ({x:.2f}, {y:.2f}) lies outside the geofence"
        for zone in self.keep_out:
            if zone.contains(x, y):
                return f"goal ({x:.2f}, {y:.2f}) lies inside the keep-out zone {zone.name!r}"
        return ""

    def cap(self, v: float, w: float) -> tuple[float, float]:
        """The velocity command within the caps (its sign kept)."""
        if self.max_linear is not None:
            v = max(-self.max_linear, min(self.max_linear, v))
        if self.max_angular is not None:
            w = max(-self.max_angular, min(self.max_angular, w))
        return v, w


def _number(value: Any, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise ConfigError(f"{where}: expected a finite number, found {type(value).__name__}")
    return float(value)


def _polygon(value: Any, where: str) -> tuple[Point, ...]:
    if not isinstance(value, list) or not 3 <= len(value) <= MAX_VERTICES:
        raise ConfigError(f"{where}: expected a list of 3 to {MAX_VERTICES} [x, y] points (map frame, m)")
    points = []
    for i, point in enumerate(value):
        if not isinstance(point, list | tuple) or len(point) != 2:
            raise ConfigError(f"{where}[{i}]: expected an [x, y] point")
        points.append((_number(point[0], f"{where}[{i}][0]"), _number(point[1], f"{where}[{i}][1]")))
    return tuple(points)


def _cap(value: Any, where: str) -> float | None:
    if value is None:
        return None
    number = _number(value, where)
    if number <= 0:
        raise ConfigError(f"{where}: expected a speed above 0, found {number}")
    return number


def parse_envelope(data: Any, where: str = "safety") -> Envelope | None:
    """The envelope a ``safety`` section declares (None when there is none).

    Raises:
        ConfigError: The section is malformed (names the key and what was expected).
    """
    if data is None:
        return None
    if not isinstance(data, Mapping):
        raise ConfigError(f"{where}: expected a mapping with geofence, keep_out, max_linear, max_angular")
    unknown = sorted(str(k) for k in data if k not in KEYS)
    if unknown:
        raise ConfigError(f"{where}: unknown keys {unknown} (known: {', '.join(KEYS)})")
    fence = data.get("geofence")
    geofence = None if fence is None else Zone("geofence", _polygon(fence, f"{where}.geofence"))
    zones_raw = data.get("keep_out") or []
    if not isinstance(zones_raw, list) or len(zones_raw) > MAX_ZONES:
        raise ConfigError(f"{where}.keep_out: expected a list of at most {MAX_ZONES} {{name, polygon}} zones")
    zones = []
    for i, raw in enumerate(zones_raw):
        here = f"{where}.keep_out[{i}]"
        if not isinstance(raw, Mapping) or "polygon" not in raw:
            raise ConfigError(f"{here}: expected {{name: ..., polygon: [[x, y], ...]}}")
        name = str(raw.get("name") or f"zone {i + 1}")[:80]
        zones.append(Zone(name, _polygon(raw["polygon"], f"{here}.polygon")))
    return Envelope(geofence, tuple(zones), _cap(data.get("max_linear"), f"{where}.max_linear"),
                    _cap(data.get("max_angular"), f"{where}.max_angular"))


class EnvelopedRobot:
    """A robot whose goals and velocity commands pass the envelope first (everything else as is).

    Args:
        inner: The backend's robot.
        envelope: The envelope to enforce.
        emit: Where ``safety_refused`` and ``safety_capped`` events go (the tick log), if anywhere.
    """

    def __init__(self, inner: Any, envelope: Envelope,
                 emit: Callable[..., None] | None = None) -> None:
        self.inner = inner
        self.name = getattr(inner, "name", "robot")
        self.simulated = bool(getattr(inner, "simulated", False))
        self.envelope = envelope
        self.emit = emit
        self.refused: list[str] = []
        self._capped = False

    def __getattr__(self, name: str) -> Any:
        return getattr(self.inner, name)

    def navigate_to(self, goal: Pose2D, tolerance: Tolerance | None = None) -> Any:
        """Send ``goal`` if the envelope allows it; else a REJECTED handle naming why (nothing is sent)."""
        why = self.envelope.refusal(goal)
        if not why:
            return self.inner.navigate_to(goal, tolerance)
        self.refused.append(why)
        if self.emit is not None:
            self.emit("safety_refused", reason=why, x=goal.x if math.isfinite(goal.x) else None,
                      y=goal.y if math.isfinite(goal.y) else None)
        return RefusedAction(f"refused by the safety envelope: {why}", kind=REFUSED)

    def drive(self, v: float, w: float) -> None:
        """Command (v, w) within the caps; a non-finite command is refused (BackendError)."""
        if not (math.isfinite(v) and math.isfinite(w)):
            self.inner.stop()
            raise BackendError(f"refused by the safety envelope: velocity ({v}, {w}) is not finite; stopped")
        capped = self.envelope.cap(v, w)
        if capped != (v, w) and not self._capped and self.emit is not None:
            self.emit("safety_capped", v=v, w=w, to_v=capped[0], to_w=capped[1])
        self._capped = capped != (v, w)
        self.inner.drive(*capped)


#: The Robot protocol's methods, delegated by name (a Protocol check in Python 3.12 looks at the
#: class, not at ``__getattr__``).
_ROBOT_METHODS = ("now", "spin_until", "pose", "scan", "rgbd", "occupancy", "pose_at", "scan_at", "sensor",
                  "sensor_names", "sensor_kind", "stop", "close")
#: Optional capabilities a backend may have (drawing the run, a command channel), delegated when it does.
_OPTIONAL_METHODS = ("draw", "commands", "commands_closed")


def _delegate(name: str) -> Callable[..., Any]:
    def method(self: EnvelopedRobot, *args: Any, **kwargs: Any) -> Any:
        return getattr(self.inner, name)(*args, **kwargs)

    method.__name__ = name
    method.__doc__ = f"The backend robot's ``{name}``."
    return method


for _name in _ROBOT_METHODS:
    setattr(EnvelopedRobot, _name, _delegate(_name))


def enveloped(robot: Any, envelope: Envelope) -> EnvelopedRobot:
    """``robot`` inside ``envelope``, keeping the optional capabilities the backend has."""
    extra = {name: _delegate(name) for name in _OPTIONAL_METHODS if callable(getattr(robot, name, None))}
    cls = type(f"Enveloped{type(robot).__name__}", (EnvelopedRobot,), extra) if extra else EnvelopedRobot
    wrapped: EnvelopedRobot = cls(robot, envelope)
    return wrapped


def wrap_robot(robot: Any, config: Mapping[str, Any] | None, where: str = "run configuration") -> Any:
    """``robot`` inside the envelope the run configuration's ``safety`` section declares (as is without one).

    Raises:
        ConfigError: A malformed ``safety`` section.
    """
    envelope = parse_envelope((config or {}).get("safety"), f"{where}: safety")
    return robot if envelope is None else enveloped(robot, envelope)


def unwrap(robot: Any) -> Any:
    """The backend's own robot inside any envelope."""
    while isinstance(robot, EnvelopedRobot):
        robot = robot.inner
    return robot
