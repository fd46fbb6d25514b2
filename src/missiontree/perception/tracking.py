"""The NAIS paper's detection filters, each a named parameter with the paper's value as default.

The paper's object-detection node (YOLOv8x on every RGB-D pair) keeps a detection only if:

1. its confidence is at least ``min_confidence`` (0.7);
2. its class is not one of ``dynamic_classes`` (people, vehicles, animals);
3. its depth point, the median around the box centre, lies within ``max_range`` (4.5 m, the
   RealSense's effective range) of the camera;
4. (temporal voting) the same candidate has appeared in at least ``min_frames`` frames (10);
5. (spatial de-duplication) it is not within ``dedup_radius`` (0.5 m) of one of the last
   ``dedup_buffer`` (100) confirmed positions;
6. (room change) except when the room context changed: an object confirmed in another room and
   now seen closer replaces the old record.

Each filter is here alone — :func:`confident`, :func:`is_dynamic`, :func:`within_range`,
:class:`TemporalVoting`, :class:`DedupBuffer`, :func:`replaces` — and :class:`NaisTracker` chains
them as the paper does, with no update once an object is confirmed (the paper's graph "does not
update if an object moves or is removed"). It is the reference the scene-graph benchmark compares
with; missiontree's own fusion (:mod:`missiontree.semantics.fusion`) reuses the filters 1–4.

How candidates are matched across frames the paper leaves open: here a candidate is a label and a
running-mean position; a projection joins the nearest candidate of its label within
``candidate_radius`` (0.5 m, the paper's de-duplication radius), and a candidate not seen for
``candidate_timeout`` seconds is forgotten.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field

from missiontree.perception.projection import Projection

#: Classes the paper calls dynamic ("people, vehicles, or animals"), in COCO's names.
DYNAMIC_CLASSES: frozenset[str] = frozenset(
    {
        "person",
        "bicycle",
        "car",
        "motorcycle",
        "airplane",
        "bus",
        "train",
        "truck",
        "boat",
        "bird",
        "cat",
        "dog",
        "horse",
        "sheep",
        "cow",
        "elephant",
        "bear",
        "zebra",
        "giraffe",
    }
)


@dataclass(frozen=True)
class NaisFilterParams:
    """The filters' parameters, defaults as published in the NAIS paper.

    Attributes:
        min_confidence: Least detector confidence (0.7).
        dynamic_classes: Labels dropped at once (people, vehicles, animals).
        max_range: Farthest accepted distance from the camera, metres (4.5).
        min_frames: Frames a candidate must appear in before it is accepted (10).
        dedup_radius: A new object this close to a confirmed one is a duplicate, metres (0.5).
        dedup_buffer: How many confirmed positions the de-duplication remembers (100).
        dedup_any_label: Whether a confirmed object of any label blocks (the paper's buffer holds
            positions only); False: only the same label.
        room_change_replacement: Whether an object confirmed in another room and now seen closer
            replaces the old record (True).
        candidate_radius: A projection joins a candidate of its label this close, metres.
        candidate_timeout: Seconds after which an unseen candidate is forgotten.
    """

    min_confidence: float = 0.7
    dynamic_classes: frozenset[str] = DYNAMIC_CLASSES
    max_range: float = 4.5
    min_frames: int = 10
    dedup_radius: float = 0.5
    dedup_buffer: int = 100
    dedup_any_label: bool = True
    room_change_replacement: bool = True
    candidate_radius: float = 0.5
    candidate_timeout: float = 30.0


# -- the filters, one at a time --------------------------------------------------------------------


def confident(score: float, min_confidence: float = 0.7) -> bool:
    """Filter 1: the detection's confidence is at least ``min_confidence``."""
    return score >= min_confidence


def is_dynamic(label: str, dynamic_classes: Iterable[str] = DYNAMIC_CLASSES) -> bool:
    """Filter 2: the class moves by itself (person, vehicle, animal) and is dropped."""
    return label.strip().lower() in {c.lower() for c in dynamic_classes}


def within_range(projection: Projection, max_range: float = 4.5) -> bool:
    """Filter 3: the depth point is at most ``max_range`` metres from the camera."""
    return math.isfinite(projection.range) and projection.range <= max_range


@dataclass
class Candidate:
    """A detection seen in some frames, not yet accepted."""

    label: str
    x: float
    y: float
    z: float
    frames: int
    last_stamp: float
    best_range: float
    projections: list[Projection] = field(default_factory=list)

    def add(self, p: Projection) -> None:
        """Join a projection: running-mean position, one more frame."""
        n = self.frames
        self.x = (self.x * n + p.position[0]) / (n + 1)
        self.y = (self.y * n + p.position[1]) / (n + 1)
        self.z = (self.z * n + p.position[2]) / (n + 1)
        self.frames = n + 1
        self.last_stamp = p.stamp
        self.best_range = min(self.best_range, p.range)
        self.projections.append(p)
        if len(self.projections) > 30:
            del self.projections[0]


class TemporalVoting:
    """Filter 4: a candidate is accepted once it has appeared in ``min_frames`` frames."""

    def __init__(
        self,
        min_frames: int = 10,
        radius: float = 0.5,
        timeout: float = 30.0,
        *,
        size_aware: bool = False,
        required: Callable[[Candidate], int] | None = None,
        ready: Callable[[Candidate], bool] | None = None,
        reach: Callable[[Projection], float | None] | None = None,
    ) -> None:
        """Voting as the paper does by default.

        Args:
            min_frames: Frames a candidate needs (the paper's 10).
            radius: A projection joins a candidate of its label this close, metres.
            timeout: Seconds after which an unseen candidate is forgotten.
            size_aware: Join within half the projection's measured width when that is larger than
                ``radius`` (a sofa's views scatter more than a cup's; off for the paper).
            required: Frames a given candidate needs instead of ``min_frames`` (a class- or
                size-aware rule); None: ``min_frames``.
            ready: A further test a candidate with enough frames must pass to be accepted; one that
                fails keeps collecting frames.
            reach: How close a given projection must fall to a candidate to join it, overriding
                ``radius`` and ``size_aware`` (two small objects of a class half a metre apart); None
                from it, or no ``reach``: the rule above.
        """
        if min_frames < 1:
            raise ValueError(f"min_frames must be at least 1, found {min_frames}")
        self.min_frames = min_frames
        self.radius = radius
        self.timeout = timeout
        self.size_aware = size_aware
        self.required = required
        self.ready = ready
        self.reach = reach
        self.candidates: list[Candidate] = []

    def vote(self, projection: Projection) -> Candidate | None:
        """Count one frame for the projection's candidate; return it once it reaches ``min_frames``.

        An accepted candidate is forgotten here (the caller owns it from then on).
        """
        self.expire(projection.stamp)
        best, best_d = None, self.radius
        if self.size_aware:
            best_d = max(self.radius, 0.5 * projection.size[0])
        own = self.reach(projection) if self.reach is not None else None
        if own is not None:
            best_d = own
        for cand in self.candidates:
            if cand.label != projection.label or cand.last_stamp == projection.stamp:
                continue  # one vote a frame per candidate
            d = math.hypot(cand.x - projection.position[0], cand.y - projection.position[1])
            if d <= best_d:
                best, best_d = cand, d
        if best is None:
            x, y, z = projection.position
            best = Candidate(projection.label, x, y, z, 0, projection.stamp, projection.range)
            self.candidates.append(best)
        best.add(projection)
        need = self.required(best) if self.required is not None else self.min_frames
        if best.frames >= need and (self.ready is None or self.ready(best)):
            self.candidates.remove(best)
            return best
        return None

    def expire(self, now: float) -> None:
        """Forget candidates not seen for ``timeout`` seconds."""
        self.candidates = [c for c in self.candidates if now - c.last_stamp <= self.timeout]


@dataclass(frozen=True)
class Confirmed:
    """A confirmed object in the de-duplication buffer."""

    label: str
    x: float
    y: float
    room: str | None
    range: float
    key: str


class DedupBuffer:
    """Filter 5: the last ``size`` confirmed positions; a new one within ``radius`` is a duplicate."""

    def __init__(self, radius: float = 0.5, size: int = 100, any_label: bool = True) -> None:
        self.radius = radius
        self.any_label = any_label
        self.entries: deque[Confirmed] = deque(maxlen=size)

    def duplicate_of(self, label: str, x: float, y: float) -> Confirmed | None:
        """The nearest buffered entry within ``radius`` (of the same label unless ``any_label``)."""
        best, best_d = None, self.radius
        for entry in self.entries:
            if not self.any_label and entry.label != label:
                continue
            d = math.hypot(entry.x - x, entry.y - y)
            if d <= best_d:
                best, best_d = entry, d
        return best

    def push(self, entry: Confirmed) -> None:
        """Remember a confirmed position (the oldest falls out beyond ``size``)."""
        self.entries.append(entry)

    def discard(self, key: str) -> None:
        """Forget the entry of the record ``key``."""
        self.entries = deque((e for e in self.entries if e.key != key), maxlen=self.entries.maxlen)


def replaces(old: Confirmed, label: str, new_range: float, room: str | None) -> bool:
    """Filter 6: a duplicate of ``old`` replaces it when the room changed and it is seen closer."""
    return old.label == label and room is not None and old.room != room and new_range < old.range


# -- the paper's chain -----------------------------------------------------------------------------


@dataclass(frozen=True)
class TrackerEvent:
    """What :class:`NaisTracker` did with a candidate: ``confirmed``, ``replaced`` or ``duplicate``."""

    kind: str
    key: str
    label: str
    position: tuple[float, float, float]
    room: str | None
    replaced: str | None = None


class NaisTracker:
    """The NAIS paper's detection node: filters 1-6 in order; confirmed objects are never updated.

    Attributes:
        objects: Confirmed records by key: (label, position, room).
    """

    def __init__(self, params: NaisFilterParams | None = None) -> None:
        self.params = params or NaisFilterParams()
        p = self.params
        self.voting = TemporalVoting(p.min_frames, p.candidate_radius, p.candidate_timeout)
        self.buffer = DedupBuffer(p.dedup_radius, p.dedup_buffer, p.dedup_any_label)
        self.objects: dict[str, Confirmed] = {}
        self.positions: dict[str, tuple[float, float, float]] = {}
        self.dropped = {"confidence": 0, "dynamic": 0, "range": 0, "duplicate": 0}
        self._count = 0

    def accept(self, projection: Projection) -> bool:
        """Filters 1-3 (a single frame's filters); counts what each drops."""
        p = self.params
        if not confident(projection.score, p.min_confidence):
            self.dropped["confidence"] += 1
            return False
        if is_dynamic(projection.label, p.dynamic_classes):
            self.dropped["dynamic"] += 1
            return False
        if not within_range(projection, p.max_range):
            self.dropped["range"] += 1
            return False
        return True

    def process(self, projections: Iterable[Projection], room: str | None = None) -> list[TrackerEvent]:
        """Run one frame's projections through the chain; return what was confirmed or replaced.

        Args:
            projections: The frame's detections in the map frame.
            room: The current room context (the paper's room updates), None when unknown.
        """
        events: list[TrackerEvent] = []
        for projection in projections:
            if not self.accept(projection):
                continue
            cand = self.voting.vote(projection)
            if cand is None:
                continue
            events.extend(self._confirm(cand, room))
        return events

    def _confirm(self, cand: Candidate, room: str | None) -> list[TrackerEvent]:
        p = self.params
        duplicate = self.buffer.duplicate_of(cand.label, cand.x, cand.y)
        position = (cand.x, cand.y, cand.z)
        if duplicate is not None:
            if p.room_change_replacement and replaces(duplicate, cand.label, cand.best_range, room):
                self.buffer.discard(duplicate.key)
                self.objects.pop(duplicate.key, None)
                self.positions.pop(duplicate.key, None)
                key = self._add(cand, room)
                return [TrackerEvent("replaced", key, cand.label, position, room, replaced=duplicate.key)]
            self.dropped["duplicate"] += 1
            return [TrackerEvent("duplicate", duplicate.key, cand.label, position, room)]
        key = self._add(cand, room)
        return [TrackerEvent("confirmed", key, cand.label, position, room)]

    def _add(self, cand: Candidate, room: str | None) -> str:
        self._count += 1
        key = f"{'_'.join(cand.label.split())}_{self._count}"
        entry = Confirmed(cand.label, cand.x, cand.y, room, cand.best_range, key)
        self.buffer.push(entry)
        self.objects[key] = entry
        self.positions[key] = (cand.x, cand.y, cand.z)
        return key
