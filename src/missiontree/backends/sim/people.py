"""People walking scripted routes: where each one is at any time, and the prisms they occupy.

A person walks the route's points in order at a constant speed, starting at ``start_time``
(standing at the first point before that), standing ``pause`` seconds at each point. A looping
route closes back to its first point and repeats; otherwise the person stays at the last point
(or leaves the world when ``vanish_at_end``). Positions are a pure function of time, so ground
truth can answer "where was she at t" for any t, and runs are deterministic.

A person is drawn as legs (two thin cylinders that swing with the gait, what the lidar sees at
its 0.2 m plane), a torso and a head. People do not avoid the robot: they block its sensors and
its path, as the passers-by of the patrol-robot thesis did.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from missiontree.backends.sim.raycast import CYLINDER, Primitives, Row
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
        points = [(float(p[0]), float(p[1])) for p in spec.route]
        if spec.loop and len(points) > 1:
            points.append(points[0])
        self._points = points
        legs = list(zip(points[:-1], points[1:], strict=True))
        self._lengths = [math.hypot(b[0] - a[0], b[1] - a[1]) for a, b in legs]
        self._headings = [math.atan2(b[1] - a[1], b[0] - a[0]) for a, b in legs]
        self._total = sum(self._lengths)
        walk = [n / spec.speed if spec.speed > 0 else math.inf for n in self._lengths]
        self._durations = [t + spec.pause for t in walk]  # each leg: pause at its start, then walk
        self._period = sum(self._durations)

    def state_at(self, t: float) -> PersonState:
        """The person's position, heading and whether they walk or are present at time ``t``."""
        pts = self._points
        spec = self.spec
        if len(pts) == 1 or spec.speed == 0 or t < spec.start_time:
            return PersonState(pts[0][0], pts[0][1], self._leg_heading(0), False, True, 0.0)
        elapsed = t - spec.start_time
        travelled = 0.0
        if spec.loop and self._period > 0:
            laps = int(elapsed // self._period)
            elapsed -= laps * self._period
            travelled = laps * self._total
        elif elapsed >= self._period:
            last = len(self._lengths) - 1
            return PersonState(pts[-1][0], pts[-1][1], self._leg_heading(last), False,
                               not spec.vanish_at_end, self._total)
        last = len(self._durations) - 1
        for i, duration in enumerate(self._durations):
            if elapsed < duration or i == last:
                length = self._lengths[i]
                walked = max(0.0, min(length, (elapsed - spec.pause) * spec.speed))
                frac = walked / length if length > 0 else 0.0
                (x0, y0), (x1, y1) = pts[i], pts[i + 1]
                walking = elapsed >= spec.pause and walked < length
                return PersonState(x0 + frac * (x1 - x0), y0 + frac * (y1 - y0), self._headings[i], walking,
                                   True, travelled + walked)
            elapsed -= duration
            travelled += self._lengths[i]
        raise AssertionError("unreachable: the last leg always returns")

    def _leg_heading(self, i: int) -> float:
        if not self._headings:
            return 0.0
        return self._headings[min(i, len(self._headings) - 1)]

    def centres(self, state: PersonState) -> list[tuple[float, float]]:
        """Centres of the left leg, right leg, torso and head (the legs swing with the gait)."""
        c, si = math.cos(state.heading), math.sin(state.heading)
        swing = 0.18 * math.sin(2.0 * math.pi * state.travelled / STEP_LENGTH) if state.walking else 0.0
        left = (state.x - si * LEG_SPREAD + c * swing, state.y + c * LEG_SPREAD + si * swing)
        right = (state.x + si * LEG_SPREAD - c * swing, state.y - c * LEG_SPREAD - si * swing)
        return [left, right, (state.x, state.y), (state.x, state.y)]

    def rows(self) -> list[tuple[float, float, float, tuple[int, int, int]]]:
        """(radius, bottom, top, colour) of the left leg, right leg, torso and head."""
        spec = self.spec
        return [(LEG_RADIUS, 0.0, LEG_HEIGHT, spec.trousers_rgb),
                (LEG_RADIUS, 0.0, LEG_HEIGHT, spec.trousers_rgb),
                (TORSO_RADIUS, LEG_HEIGHT, TORSO_TOP, spec.shirt_rgb),
                (HEAD_RADIUS, TORSO_TOP + 0.04, HEAD_TOP, spec.skin_rgb)]

    def primitives(self, t: float, state: PersonState | None = None) -> list[Row]:
        """Prism rows (see :class:`Primitives`) for legs, torso and head at time ``t``."""
        s = state if state is not None else self.state_at(t)
        if not s.present:
            return []
        return [(CYLINDER, (x, y, r), z0, z1, rgb, self.inst)
                for (x, y), (r, z0, z1, rgb) in zip(self.centres(s), self.rows(), strict=True)]


class Crowd:
    """All people of a world; the last queried instant is cached (sensors and physics share it)."""

    def __init__(self, people: list[Person]) -> None:
        self.people = people
        self._prims_at: tuple[float, Primitives] | None = None
        self._states_at: tuple[float, list[PersonState]] | None = None
        # the parts that do not move: radius, heights, colours, ids (4 rows a person)
        rows = [row for person in people for row in person.rows()]
        self._geom = np.zeros((len(rows), 6))
        self._geom[:, 2] = [r[0] for r in rows]
        self._z = np.array([(r[1], r[2]) for r in rows], np.float64).reshape(-1, 2)
        self._rgb = np.array([r[3] for r in rows], np.float64).reshape(-1, 3)
        self._inst = np.repeat(np.array([p.inst for p in people], np.int64), 4)

    def __len__(self) -> int:
        return len(self.people)

    def states(self, t: float) -> list[PersonState]:
        """Everyone's state at time ``t`` (cached for the last instant asked)."""
        if self._states_at is None or self._states_at[0] != t:
            self._states_at = (t, [person.state_at(t) for person in self.people])
        return self._states_at[1]

    def primitives(self, t: float) -> Primitives:
        """Prisms of everyone present at time ``t``."""
        if self._prims_at is None or self._prims_at[0] != t:
            states = self.states(t)
            geom = self._geom.copy()
            present = np.ones(len(geom), bool)
            for i, (person, state) in enumerate(zip(self.people, states, strict=True)):
                if state.present:
                    geom[4 * i: 4 * i + 4, :2] = person.centres(state)
                else:
                    present[4 * i: 4 * i + 4] = False
            table = Primitives(np.full(len(geom), CYLINDER, np.int64), geom, self._z, self._rgb, self._inst)
            self._prims_at = (t, table if present.all() else table.select(present))
        return self._prims_at[1]

    def positions(self, t: float) -> list[tuple[str, float, float]]:
        """(id, x, y) of everyone present at time ``t``."""
        return [(p.id, s.x, s.y) for p, s in zip(self.people, self.states(t), strict=True) if s.present]
