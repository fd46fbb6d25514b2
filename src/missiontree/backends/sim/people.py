"""People walking scripted routes: where each one is at any time, and the prisms they occupy.

A person walks the route's points in order at a constant speed, starting at ``start_time``
(standing at the first point before that), standing ``pause`` seconds at each point. A looping
route closes back to its first point and repeats; otherwise the person stays at the last point
(or leaves the world when ``vanish_at_end``). Positions are a pure function of time, so ground
truth can answer "where was she at t" for any t, and runs are deterministic.

A person is drawn as legs (two thin cylinders that swing with the gait, what the lidar sees at
its 0.2 m plane), a torso and a head. People do not avoid the robot: they block its sensors and
its path, as the passers-by of seed 001 did.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from missiontree.backends.sim.raycast import CYLINDER, Primitives
from missiontree.backends.sim.schema import PersonSpec

LEG_RADIUS = 0.065
LEG_SPREAD = 0.11
LEG_HEIGHT = 0.85
TORSO_RADIUS = 0.19
TORSO_TOP = 1.45
HEAD_RADIUS = 0.1
HEAD_TOP = 1.72
STEP_LENGTH = 0.7
#: Radius of the disc a person blocks for navigation and collisions.
BODY_RADIUS = 0.25


@dataclass(frozen=True)
class PersonState:
    """Where a person is at one instant."""

    x: float
    y: float
    heading: float
    walking: bool
    present: bool
    travelled: float


class Person:
    """One scripted walker."""

    def __init__(self, spec: PersonSpec, inst: int) -> None:
        self.spec = spec
        self.id = spec.id
        self.inst = inst
        points = [tuple(p) for p in spec.route]
        if spec.loop and len(points) > 1:
            points.append(points[0])
        self._points = np.array(points, dtype=float)
        legs = np.diff(self._points, axis=0) if len(points) > 1 else np.zeros((0, 2))
        self._lengths = np.hypot(legs[:, 0], legs[:, 1]) if len(legs) else np.zeros(0)
        walk = self._lengths / spec.speed if spec.speed > 0 else np.full(len(self._lengths), np.inf)
        # each leg: pause at its start, then walk
        self._durations = walk + spec.pause
        self._period = float(self._durations.sum()) if len(self._durations) else 0.0

    def state_at(self, t: float) -> PersonState:
        """The person's position, heading and whether they walk or are present at time ``t``."""
        pts = self._points
        if len(pts) == 1 or self.spec.speed == 0 or t < self.spec.start_time:
            heading = self._leg_heading(0)
            return PersonState(pts[0, 0], pts[0, 1], heading, False, True, 0.0)
        elapsed = t - self.spec.start_time
        laps = 0
        if self.spec.loop and self._period > 0:
            laps = int(elapsed // self._period)
            elapsed -= laps * self._period
        elif elapsed >= self._period:
            last = len(self._lengths) - 1
            return PersonState(pts[-1, 0], pts[-1, 1], self._leg_heading(last), False,
                               not self.spec.vanish_at_end, float(self._lengths.sum()))
        travelled = laps * float(self._lengths.sum())
        for i, duration in enumerate(self._durations):
            if elapsed < duration or i == len(self._durations) - 1:
                walked = max(0.0, min(self._lengths[i], (elapsed - self.spec.pause) * self.spec.speed))
                frac = walked / self._lengths[i] if self._lengths[i] > 0 else 0.0
                x, y = pts[i] + frac * (pts[i + 1] - pts[i])
                walking = elapsed >= self.spec.pause and walked < self._lengths[i]
                return PersonState(float(x), float(y), self._leg_heading(i), walking, True,
                                   travelled + float(self._lengths[:i].sum()) + walked)
            elapsed -= duration
        raise AssertionError("unreachable: the last leg always returns")

    def _leg_heading(self, i: int) -> float:
        if len(self._points) < 2:
            return 0.0
        i = min(i, len(self._points) - 2)
        d = self._points[i + 1] - self._points[i]
        return math.atan2(d[1], d[0])

    def primitives(self, t: float) -> list[tuple[int, tuple[float, ...], float, float, tuple[int, int, int], int]]:
        """Prism rows (see :class:`Primitives`) for legs, torso and head at time ``t``."""
        s = self.state_at(t)
        if not s.present:
            return []
        c, si = math.cos(s.heading), math.sin(s.heading)
        swing = 0.18 * math.sin(2.0 * math.pi * s.travelled / STEP_LENGTH) if s.walking else 0.0
        spec = self.spec
        rows = []
        for side, sign in ((LEG_SPREAD, 1.0), (-LEG_SPREAD, -1.0)):
            lx = s.x - si * side + c * swing * sign
            ly = s.y + c * side + si * swing * sign
            rows.append((CYLINDER, (lx, ly, LEG_RADIUS), 0.0, LEG_HEIGHT, spec.trousers_rgb, self.inst))
        rows.append((CYLINDER, (s.x, s.y, TORSO_RADIUS), LEG_HEIGHT, TORSO_TOP, spec.shirt_rgb, self.inst))
        rows.append((CYLINDER, (s.x, s.y, HEAD_RADIUS), TORSO_TOP + 0.04, HEAD_TOP, spec.skin_rgb, self.inst))
        return rows


class Crowd:
    """All people of a world."""

    def __init__(self, people: list[Person]) -> None:
        self.people = people

    def __len__(self) -> int:
        return len(self.people)

    def primitives(self, t: float) -> Primitives:
        """Prisms of everyone present at time ``t``."""
        rows = []
        for person in self.people:
            rows.extend(person.primitives(t))
        return Primitives.build(rows)

    def positions(self, t: float) -> list[tuple[str, float, float]]:
        """(id, x, y) of everyone present at time ``t``."""
        out = []
        for person in self.people:
            s = person.state_at(t)
            if s.present:
                out.append((person.id, s.x, s.y))
        return out
