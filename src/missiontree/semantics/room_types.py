"""A room's type from the objects seen in it and its shape: a naive Bayes classifier over priors.

Each room type has a prior (how common such rooms are in homes and offices) and, per object class,
the chance that a room of that type holds one (:data:`PRESENCE`: common knowledge of where things
are, written per label, not per world). A room's posterior multiplies, per known class,

- the chance of the class being there when it was seen in the room, and
- when it was not seen, ``1 - seen * P(class | type)`` (noisy absence: a large object that is
  there is seen in about :data:`SEEN_LARGE` of rooms the robot walked through, a small one in
  :data:`SEEN_SMALL`), only for classes the detector knows (an unknowable class says nothing);

and the shape of the room: a long narrow room (:func:`elongation`) is most likely a corridor. The
answer is the most probable type with its posterior; a room with no object and no telling shape
stays ``unknown``.
"""

from __future__ import annotations

import math
from collections.abc import Collection, Iterable
from dataclasses import dataclass

import numpy as np

#: How common each room type is, a priori (sums to 1).
PRIOR: dict[str, float] = {
    "kitchen": 0.12, "living_room": 0.12, "office": 0.20, "bedroom": 0.15, "bathroom": 0.12,
    "hall": 0.08, "storage": 0.10, "corridor": 0.11,
}
TYPES = tuple(PRIOR)

#: P(a room of the type holds at least one object of the class), per class, in TYPES order:
#: kitchen, living_room, office, bedroom, bathroom, hall, storage, corridor.
PRESENCE: dict[str, tuple[float, ...]] = {
    "refrigerator": (0.95, 0.03, 0.08, 0.02, 0.01, 0.02, 0.10, 0.01),
    "oven": (0.90, 0.01, 0.01, 0.01, 0.01, 0.01, 0.02, 0.01),
    "microwave": (0.80, 0.03, 0.10, 0.02, 0.01, 0.01, 0.05, 0.01),
    "sink": (0.90, 0.01, 0.03, 0.02, 0.95, 0.01, 0.05, 0.01),
    "toilet": (0.01, 0.01, 0.01, 0.01, 0.90, 0.01, 0.01, 0.01),
    "bed": (0.01, 0.03, 0.02, 0.95, 0.01, 0.01, 0.03, 0.01),
    "sofa": (0.05, 0.95, 0.15, 0.10, 0.01, 0.15, 0.05, 0.03),
    "tv": (0.15, 0.90, 0.15, 0.35, 0.02, 0.05, 0.05, 0.01),
    "table": (0.85, 0.70, 0.45, 0.15, 0.02, 0.20, 0.15, 0.05),
    "dining table": (0.70, 0.30, 0.05, 0.02, 0.01, 0.05, 0.03, 0.01),
    "desk": (0.03, 0.10, 0.95, 0.35, 0.01, 0.05, 0.05, 0.02),
    "chair": (0.60, 0.45, 0.90, 0.40, 0.03, 0.25, 0.15, 0.10),
    "bench": (0.05, 0.05, 0.02, 0.03, 0.05, 0.50, 0.03, 0.30),
    "bookshelf": (0.03, 0.45, 0.65, 0.25, 0.01, 0.15, 0.50, 0.05),
    "laptop": (0.10, 0.35, 0.70, 0.30, 0.01, 0.05, 0.03, 0.02),
    "cup": (0.75, 0.35, 0.40, 0.15, 0.10, 0.05, 0.05, 0.02),
    "bottle": (0.70, 0.25, 0.30, 0.15, 0.50, 0.05, 0.15, 0.03),
    "backpack": (0.05, 0.20, 0.35, 0.40, 0.02, 0.35, 0.15, 0.10),
    "umbrella": (0.03, 0.08, 0.08, 0.10, 0.02, 0.50, 0.20, 0.15),
    "potted plant": (0.20, 0.55, 0.35, 0.20, 0.10, 0.45, 0.05, 0.30),
    "trash can": (0.55, 0.15, 0.50, 0.15, 0.65, 0.15, 0.25, 0.20),
}
#: Classes this large or larger are seen in most rooms that hold them (absence says more).
LARGE = frozenset({"refrigerator", "oven", "bed", "sofa", "tv", "table", "dining table", "desk", "bookshelf",
                   "bench", "toilet", "sink", "chair"})
#: Share of rooms holding a large / small object of a class in which the robot saw it.
SEEN_LARGE = 0.6
SEEN_SMALL = 0.3
#: A room at least this elongated (length over width) and at most :data:`NARROW` m wide is corridor-shaped.
LONG = 3.0
NARROW = 2.2
#: P(corridor shape | type), in TYPES order (halls are sometimes long; other rooms rarely).
CORRIDOR_SHAPE = (0.03, 0.03, 0.05, 0.02, 0.05, 0.30, 0.10, 0.90)


@dataclass(frozen=True)
class RoomTypeAnswer:
    """The classifier's answer: the type, its posterior and what decided it."""

    room_type: str
    confidence: float
    evidence: list[str]


def elongation(polygon: np.ndarray) -> tuple[float, float]:
    """(length, width) of the polygon's principal extent, metres (0, 0 for fewer than 3 points)."""
    pts = np.asarray(polygon, dtype=float).reshape(-1, 2)
    if len(pts) < 3:
        return 0.0, 0.0
    centred = pts - pts.mean(axis=0)
    _, vectors = np.linalg.eigh(np.cov(centred.T))
    spans = [float(np.ptp(centred @ vectors[:, k])) for k in range(2)]
    return max(spans), min(spans)


def corridor_shaped(polygon: np.ndarray) -> bool:
    """Whether a room outline is long and narrow, as a corridor is."""
    length, width = elongation(polygon)
    return width > 0 and width <= NARROW and length >= LONG * width


def classify_room(
    labels: Iterable[str], polygon: np.ndarray | None = None, known: Collection[str] | None = None
) -> RoomTypeAnswer:
    """The most probable room type for the objects seen in a room and its outline.

    Args:
        labels: Labels of the objects seen in the room (one per instance; repeats count once).
        polygon: The room's outline (map coordinates), for its shape; None: shape unknown.
        known: Classes the detector can name (their absence is evidence); None: absence is not used.
    """
    seen = {label.strip().lower() for label in labels} & set(PRESENCE)
    corridor = polygon is not None and corridor_shaped(polygon)
    if not seen and not corridor:
        return RoomTypeAnswer("unknown", 0.0, [])
    logp = np.log(np.array([PRIOR[t] for t in TYPES]))
    for label in seen:
        logp += np.log(np.array(PRESENCE[label]))
    for label in set(known or ()) & set(PRESENCE) - seen:
        rate = SEEN_LARGE if label in LARGE else SEEN_SMALL
        logp += np.log(1.0 - rate * np.array(PRESENCE[label]))
    if polygon is not None:
        shape = np.array(CORRIDOR_SHAPE)
        logp += np.log(shape if corridor else 1.0 - shape)
    post = np.exp(logp - logp.max())
    post /= post.sum()
    best = int(np.argmax(post))
    room_type = TYPES[best]
    why = sorted(label for label in seen if PRESENCE[label][best] >= 0.3)
    if corridor:
        why.append("long and narrow")
    return RoomTypeAnswer(room_type, round(float(post[best]), 4), why or sorted(seen))


def _check_tables() -> None:
    """Every presence row has one probability per type, each in (0, 1)."""
    for label, row in PRESENCE.items():
        if len(row) != len(TYPES) or not all(0.0 < p < 1.0 for p in row):
            raise ValueError(f"room_types.PRESENCE[{label!r}] must give {len(TYPES)} probabilities in (0, 1)")
    if not math.isclose(sum(PRIOR.values()), 1.0, abs_tol=1e-6):
        raise ValueError("room_types.PRIOR must sum to 1")


_check_tables()
