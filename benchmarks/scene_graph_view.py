"""Which true objects the camera had in view: splits the scene graph's misses into unseen and lost.

Recall over every true object mixes two causes: objects the exploration never showed the camera
(the route's part) and objects shown but not put in the graph (the perception's part). This module
counts, from the simulator's visibility log (every camera frame, whether or not the detector looked
at it), in how many frames each object showed at least :data:`SHOWN_PIXELS` pixels while within
the leaf's ``max_range`` of the robot's true position. The benchmark's ``object_recall_in_view`` is
recall over the objects shown in at least one such frame.

Truth is read here for scoring only, as for every figure of the benchmark; no pipeline sees it.
"""

from __future__ import annotations

import bisect
import math
from collections import Counter
from typing import Any

#: Pixels an object must show in a frame to count as in view (as the diagnosis counts "shown").
SHOWN_PIXELS = 100


class PoseTrack:
    """The robot's true planar positions by stamp, recorded by the probe after every tick."""

    def __init__(self) -> None:
        self.stamps: list[float] = []
        self.xy: list[tuple[float, float]] = []

    def record(self, stamp: float, x: float, y: float) -> None:
        """Add the true position at ``stamp`` (stamps arrive in order; a repeat is ignored)."""
        if self.stamps and stamp <= self.stamps[-1]:
            return
        self.stamps.append(stamp)
        self.xy.append((x, y))

    def at(self, stamp: float) -> tuple[float, float] | None:
        """The recorded position nearest ``stamp`` (None before any)."""
        if not self.stamps:
            return None
        i = bisect.bisect_left(self.stamps, stamp)
        best = min((j for j in (i - 1, i) if 0 <= j < len(self.stamps)),
                   key=lambda j: abs(self.stamps[j] - stamp))
        return self.xy[best]


def frames_in_view(visibility: Any, track: PoseTrack, truths: list[Any],
                   max_range: float, min_pixels: int = SHOWN_PIXELS) -> Counter[str]:
    """Per object id, the camera frames that showed it (``min_pixels``) within ``max_range``.

    Args:
        visibility: The simulator's visibility log: a sequence of (stamp, {name: sighting}).
        track: The robot's true positions by stamp.
        truths: The true objects (``id`` and ``pose``).
        max_range: Farthest distance (m) at which a shown object counts as in view.
        min_pixels: Least pixels an object must show in the frame.
    """
    positions = {t.id: (t.pose.x, t.pose.y) for t in truths}
    counts: Counter[str] = Counter()
    for stamp, seen in visibility:
        here = track.at(stamp)
        if here is None:
            continue
        for name, sighting in seen.items():
            if sighting.pixels < min_pixels or name not in positions:
                continue
            x, y = positions[name]
            if math.hypot(x - here[0], y - here[1]) <= max_range:
                counts[name] += 1
    return counts


def recall_in_view(scored: dict[str, Any], counts: Counter[str], least: int = 1) -> tuple[int, int]:
    """(matched, total) over the true objects shown in at least ``least`` frames.

    Args:
        scored: A phase's score (``pairs`` of prediction and truth indices, ``truths``).
        counts: Frames in view per object id (:func:`frames_in_view`).
        least: Frames an object must have been in view to count.
    """
    truths = scored["truths"]
    matched = {j for _, j in scored["pairs"]}
    shown = [j for j, t in enumerate(truths) if counts.get(t.id, 0) >= least]
    return sum(1 for j in shown if j in matched), len(shown)
