"""Who has been seen already: light person tracks, so each person costs one model call, not one a frame.

Surveillance in ``detect`` mode sees a person in every frame for as long as they are in view. Asking
the VLM about each of those frames would spend the call budget on people already confirmed and
leave none for the next newcomer. A :class:`PersonTracks` associates each detection with a track
by map position (nearest within a gate that grows with the time since the track was last seen, at
a walking speed) or, when no position was measured, by map-frame bearing; when both carry an
appearance (the mean colour of the box's centre, mostly clothing) it must match too, so two people
passing close to each other are not taken for one. A track remembers
whether its person was already asked about (``pending``), confirmed (``confirmed``) or declared
not a person (``safe``, asked again after a while). Tracks unseen for ``forget_after`` seconds are
dropped, so a person who comes back later is a new encounter.

A :class:`CallBudget` is a token bucket: on average at most ``rate`` calls a second, with short
bursts of ``burst`` so that two newcomers a moment apart are both asked at once.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

from missiontree.types import wrap_angle

TrackState = Literal["new", "pending", "confirmed", "safe"]


@dataclass
class Track:
    """One person followed across frames.

    Attributes:
        id: Increasing number.
        position: Last map position (None when never measured).
        map_bearing: Map-frame direction from the robot when last seen (rad).
        last_seen: Time of the last frame showing them.
        state: ``new``, ``pending`` (a call is out), ``confirmed`` (alarm raised) or ``safe``.
        state_since: When the state last changed.
        appearance: Mean RGB of the centre of the person's box (their clothing), None if unknown.
        hits: Frames the person was detected in.
    """

    id: int
    position: tuple[float, float] | None
    map_bearing: float
    last_seen: float
    state: TrackState = "new"
    state_since: float = 0.0
    appearance: tuple[float, float, float] | None = None
    hits: int = 1

    def set(self, state: TrackState, now: float) -> None:
        """Change state."""
        self.state = state
        self.state_since = now


class PersonTracks:
    """Nearest-neighbour association of person detections to tracks.

    Args:
        gate: Distance (m) within which a detection continues a track seen a moment ago.
        speed: Walking speed (m/s) by which the gate grows per second unseen.
        max_gate: Largest gate (m).
        bearing_gate: Map-bearing gate (rad) for detections without a position.
        forget_after: Seconds unseen after which a track is dropped.
        colour_gate: Largest RGB distance between appearances of one person.
    """

    def __init__(self, gate: float = 0.5, speed: float = 1.0, max_gate: float = 2.0,
                 bearing_gate: float = math.radians(8.0), forget_after: float = 10.0,
                 colour_gate: float = 45.0) -> None:
        self.gate = gate
        self.colour_gate = colour_gate
        self.speed = speed
        self.max_gate = max_gate
        self.bearing_gate = bearing_gate
        self.forget_after = forget_after
        self.tracks: list[Track] = []
        self._next_id = 1

    def expire(self, now: float) -> None:
        """Drop the tracks unseen for longer than ``forget_after``."""
        self.tracks = [t for t in self.tracks if now - t.last_seen <= self.forget_after]

    def match(self, now: float, position: tuple[float, float] | None, map_bearing: float,
              taken: set[int] | None = None, appearance: tuple[float, float, float] | None = None) -> Track:
        """The track this detection continues (updated), or a new one.

        Args:
            now: Time of the frame.
            position: Measured map position, None when unknown.
            map_bearing: Map-frame direction from the robot to the detection.
            taken: Ids of tracks already matched in this frame (one detection each).
            appearance: Mean RGB of the detection's centre, None when unknown.
        """
        taken = taken or set()
        best: Track | None = None
        best_cost = math.inf
        for track in self.tracks:
            if track.id in taken:
                continue
            if (appearance is not None and track.appearance is not None
                    and math.dist(appearance, track.appearance) > self.colour_gate):
                continue
            if position is not None and track.position is not None:
                gate = min(self.max_gate, self.gate + self.speed * max(0.0, now - track.last_seen))
                cost = math.dist(position, track.position) / gate
            else:
                cost = abs(wrap_angle(map_bearing - track.map_bearing)) / self.bearing_gate
            if cost <= 1.0 and cost < best_cost:
                best, best_cost = track, cost
        if best is None:
            best = Track(self._next_id, position, map_bearing, now, "new", now, appearance)
            self._next_id += 1
            self.tracks.append(best)
        else:
            best.position = position if position is not None else best.position
            best.map_bearing = map_bearing
            best.last_seen = now
            best.hits += 1
            best.appearance = appearance if appearance is not None else best.appearance
        return best


class CallBudget:
    """A token bucket: at most ``rate`` calls a second on average, bursts of ``burst``."""

    def __init__(self, rate: float, burst: int = 2) -> None:
        self.rate = rate
        self.burst = float(burst)
        self.tokens = float(burst)
        self.updated: float | None = None

    def take(self, now: float) -> bool:
        """Spend one call if the budget allows it now."""
        if self.updated is not None:
            self.tokens = min(self.burst, self.tokens + (now - self.updated) * self.rate)
        self.updated = now
        if self.tokens >= 1.0 - 1e-9:
            self.tokens -= 1.0
            return True
        return False
