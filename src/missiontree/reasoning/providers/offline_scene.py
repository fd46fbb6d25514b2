"""Offline stand-ins for the scene graph's vision-language questions: room types and descriptions.

The NAIS paper asks LLaVA two things: which type of room a frame shows, and the colour, relative
size and shape of each object (from a crop 20 % larger than its box), as JSON. Without a model
these answers come from what the robot itself measured, never from the simulator's truth:

- :func:`room_type_from_objects` — the room type the objects *seen in the room* point to, by the
  weights of :data:`ROOM_EVIDENCE` (a refrigerator or a sink and a stove say kitchen, a bed says
  bedroom, a sofa and a tv say living room, a desk or bookshelf says office, ...). Objects that
  occur anywhere (chairs, bottles) weigh little; a room with no telling object stays ``unknown``.
- :func:`measured_description` — an :class:`~missiontree.reasoning.schemas.ObjectDescription` from
  the instance's measured colour (pixels, :mod:`missiontree.perception.colour`) and size (depth):
  relative size from its largest dimension, shape from its proportions.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping

from missiontree.reasoning.schemas import ObjectDescription, RoomClassification

#: Label → {room type: weight}: how strongly seeing the object in a room says what the room is.
ROOM_EVIDENCE: dict[str, dict[str, float]] = {
    "refrigerator": {"kitchen": 5.0},
    "oven": {"kitchen": 3.0},
    "microwave": {"kitchen": 2.0},
    "stove": {"kitchen": 3.0},
    "sink": {"kitchen": 1.5, "bathroom": 1.5},
    "counter": {"kitchen": 1.5},
    "dining table": {"kitchen": 1.5},
    "cup": {"kitchen": 0.4},
    "bottle": {"kitchen": 0.3},
    "bowl": {"kitchen": 0.5},
    "stool": {"kitchen": 0.5},
    "bed": {"bedroom": 4.0},
    "wardrobe": {"bedroom": 2.0},
    "toilet": {"bathroom": 4.0},
    "bathtub": {"bathroom": 4.0},
    "shower": {"bathroom": 4.0},
    "sofa": {"living_room": 2.5},
    "couch": {"living_room": 2.5},
    "tv": {"living_room": 2.0},
    "table": {"living_room": 0.8},
    "desk": {"office": 2.5},
    "bookshelf": {"office": 2.0},
    "printer": {"office": 2.5},
    "laptop": {"office": 0.8, "living_room": 0.3},
    "monitor": {"office": 2.0},
    "keyboard": {"office": 1.5},
    "chair": {"office": 0.3},
    "bench": {"hall": 2.0},
    "notice board": {"hall": 2.0},
    "umbrella": {"hall": 0.5},
    "potted plant": {"hall": 0.3, "living_room": 0.3},
    "trash can": {"bathroom": 0.3, "kitchen": 0.2},
}

#: Least total evidence before a room gets a type.
MIN_EVIDENCE = 0.5


def room_type_from_objects(
    labels: Iterable[str],
    evidence: Mapping[str, Mapping[str, float]] | None = None,
    min_evidence: float = MIN_EVIDENCE,
) -> RoomClassification:
    """The room type the labels of the objects seen in a room vote for (see module docstring).

    Args:
        labels: Labels of the objects the robot saw in the room (one per instance).
        evidence: Label → {room type: weight}; default :data:`ROOM_EVIDENCE`.
        min_evidence: Least winning weight; below it the answer is ``unknown``.
    """
    table = evidence if evidence is not None else ROOM_EVIDENCE
    votes: dict[str, float] = {}
    why: dict[str, set[str]] = {}
    for label in labels:
        for room, weight in table.get(label.strip().lower(), {}).items():
            votes[room] = votes.get(room, 0.0) + weight
            why.setdefault(room, set()).add(label)
    if not votes:
        return RoomClassification(room_type="unknown", confidence=0.0, evidence=[])
    best = max(sorted(votes), key=lambda r: votes[r])
    if votes[best] < min_evidence:
        return RoomClassification(room_type="unknown", confidence=0.0, evidence=sorted(why[best]))
    return RoomClassification(
        room_type=best, confidence=round(votes[best] / sum(votes.values()), 4), evidence=sorted(why[best])
    )


def relative_size(size: tuple[float, float, float]) -> str:
    """``small`` (largest side under 0.4 m), ``medium`` (under 1.2 m) or ``large``."""
    largest = max(size)
    return "small" if largest < 0.4 else "medium" if largest < 1.2 else "large"


def shape_of(size: tuple[float, float, float]) -> str:
    """A word for the proportions: ``tall`` (height over 1.6 widths), ``flat`` (under 0.6), else ``boxy``."""
    width = max(size[0], size[1], 1e-3)
    ratio = size[2] / width
    return "tall" if ratio > 1.6 else "flat" if ratio < 0.6 else "boxy"


def measured_description(label: str, colour: str, size: tuple[float, float, float]) -> ObjectDescription:
    """The description of an instance from what was measured (colour from pixels, size from depth)."""
    rel = relative_size(size)
    shape = shape_of(size)
    colour_word = colour if colour and colour != "unknown" else ""
    text = f"a {colour_word + ' ' if colour_word else ''}{label}, {rel} ({max(size):.2f} m), {shape}"
    return ObjectDescription(label=label, colour=colour or "unknown", size=rel, shape=shape, description=text)
