"""Where a searched-for object is likely: the target phrase read, rooms and regions ranked.

The vision-language object-search report explores by scan points alone, wherever the object may be.
A searcher that knows a cup belongs in a kitchen looks there first. This module holds that
knowledge for the search leaves:

- :func:`parse_target` reads "the red backpack" into the class the detector knows and its colour
  words (:class:`Target`).
- :func:`room_priors` gives, for a class, how likely each room type is to hold it. The offline
  stand-in's table is the offline vision model's room objects (a cup, a sink and a refrigerator
  say kitchen) plus the places everyday carried things are left (a backpack in an office, a bedroom,
  a hall). A language model can rank the rooms instead: :func:`room_ranking_messages` asks it,
  :class:`RoomRanking` is the answer's schema and :func:`priors_from_ranking` turns a checked answer
  into priors (a malformed one raises, and the caller keeps the stand-in's table).
- :func:`region_score` scores a place (a frontier) in [0, 1]: the prior of the room it lies in when
  that room's type is known, and of the rooms the objects already seen around it point to (a
  frontier beside a refrigerator leads into the kitchen's unknown part).

Nothing here reads ground truth or drives: the leaves pass in what the robot has seen.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass

from pydantic import BaseModel, Field

from missiontree.errors import ConfigError
from missiontree.reasoning.phrases import colour_words, find_label, fold_label
from missiontree.reasoning.protocols import Message
from missiontree.reasoning.providers.offline_vlm import ROOM_OBJECTS

#: Places people leave things the room-typing table does not list (backpacks, umbrellas, ...).
CARRIED_PLACES: dict[str, dict[str, float]] = {
    "backpack": {"office": 1.0, "bedroom": 0.9, "hall": 0.8, "living room": 0.7, "corridor": 0.5},
    "umbrella": {"hall": 1.0, "corridor": 0.9, "bedroom": 0.5, "living room": 0.4},
    "laptop": {"office": 1.0, "living room": 0.7, "bedroom": 0.5},
    "bottle": {"kitchen": 1.0, "office": 0.5, "bathroom": 0.5, "living room": 0.4},
    "cup": {"kitchen": 1.0, "office": 0.5, "living room": 0.5},
    "book": {"office": 1.0, "living room": 0.7, "bedroom": 0.6},
    "chair": {"office": 1.0, "kitchen": 0.7, "living room": 0.5, "bedroom": 0.4},
}
#: Prior of a room type that no table links to the class (nothing known: still worth a look).
UNKNOWN_PRIOR = 0.3
#: Objects seen within this distance of a place vote for the room type they point to (m).
REGION_RADIUS = 2.5


@dataclass(frozen=True)
class Target:
    """What is searched for.

    Attributes:
        text: The phrase as given ("red backpack").
        label: The class named in it that the detector knows ("backpack").
        colours: Canonical colour words of the phrase (["red"]).
    """

    text: str
    label: str
    colours: tuple[str, ...] = ()

    @property
    def wanted(self) -> str:
        """What the vision-language model must confirm: colour words, then the class."""
        return " ".join([*self.colours, self.label])


def parse_target(text: str, labels: Sequence[str]) -> Target:
    """Read a target phrase against the classes a detector knows.

    Raises:
        ConfigError: The phrase names no class of ``labels`` (the message lists them): bad input,
            reported as such (it is also a ValueError).
    """
    found = find_label(text, labels) if text.strip() else None
    if found is None:
        shown = ", ".join(sorted(labels)[:20]) or "none"
        raise ConfigError(
            f"the target {text!r} names no class the detector knows (it knows: {shown}); "
            f'give e.g. --set target="red backpack"'
        )
    return Target(text=text.strip(), label=found[0], colours=tuple(colour_words(text)))


def room_priors(label: str, table: Mapping[str, Sequence[str]] | None = None) -> dict[str, float]:
    """Room type -> likelihood in [0, 1] that a ``label`` is found there (offline stand-in).

    Room types whose typing objects include the class count 1.0 (a cup types a kitchen); the
    carried-things table adds the places such things are left.
    """
    want = fold_label(label)
    priors: dict[str, float] = {}
    for room, labels in (table or ROOM_OBJECTS).items():
        if want in {fold_label(x) for x in labels}:
            priors[room] = 1.0
    for room, weight in CARRIED_PLACES.get(want, {}).items():
        priors[room] = max(priors.get(room, 0.0), weight)
    return priors


def priors_from_answer(ranked_rooms: Sequence[str]) -> dict[str, float]:
    """Priors from a language model's ranking of room types, most likely first (1.0, 0.8, 0.6, ...)."""
    priors: dict[str, float] = {}
    for i, room in enumerate(ranked_rooms):
        key = room.strip().lower()
        if key and key not in priors:
            priors[key] = max(0.2, 1.0 - 0.2 * i)
    return priors


class RoomRanking(BaseModel):
    """A language model's answer: room types where the object is likely, most likely first."""

    rooms: list[str] = Field(description="Room types from the list given, most likely first.")
    reason: str = Field("", description="One short sentence.")


def room_types(table: Mapping[str, Sequence[str]] | None = None) -> list[str]:
    """The room types a ranking may name: the room-typing table's and the carried-things table's."""
    names = set(table or ROOM_OBJECTS)
    for places in CARRIED_PLACES.values():
        names.update(places)
    return sorted(names)


def room_ranking_messages(target: str, rooms: Sequence[str]) -> list[Message]:
    """The conversation asking a language model where ``target`` is likely found, among ``rooms``."""
    return [
        Message(
            "system",
            "You help a mobile robot search a home or office for an object. Answer with only a JSON "
            'object {"rooms": [...], "reason": "..."}.',
        ),
        Message(
            "user",
            f"Where is a {target} most likely to be found? Rank these room types, most likely first, "
            f"leaving out the unlikely ones: {', '.join(rooms)}.",
        ),
    ]


def priors_from_ranking(answer: RoomRanking, rooms: Sequence[str]) -> dict[str, float]:
    """Priors from a checked ranking; room types outside ``rooms`` are dropped.

    Raises:
        ValueError: The ranking names none of ``rooms`` (a malformed or off-topic answer).
    """
    known = {r.lower() for r in rooms}
    named = [r.strip().lower().replace("_", " ") for r in answer.rooms]
    kept = [r for r in named if r in known]
    if not kept:
        shown = ", ".join(repr(r) for r in answer.rooms[:5]) or "nothing"
        raise ValueError(f"the ranking names no known room type ({shown})")
    return priors_from_answer(kept)


def room_of_labels(table: Mapping[str, Sequence[str]] | None = None) -> dict[str, list[str]]:
    """Class -> room types it points to (the inverse of the room-typing table)."""
    inverse: dict[str, list[str]] = {}
    for room, labels in (table or ROOM_OBJECTS).items():
        for label in labels:
            inverse.setdefault(fold_label(label), []).append(room)
    return inverse


def region_score(
    xy: tuple[float, float],
    priors: Mapping[str, float],
    seen: Iterable[tuple[str, tuple[float, float]]] = (),
    room_type: str | None = None,
    radius: float = REGION_RADIUS,
) -> float:
    """How likely the target is found by going to ``xy``, in [0, 1].

    Args:
        xy: The place (a frontier goal).
        priors: Room type -> likelihood (:func:`room_priors`).
        seen: (label, position) of the objects seen so far.
        room_type: Type of the room ``xy`` lies in, when known.
        radius: Objects this close to ``xy`` vote for the room types they point to.
    """
    if not priors:
        return UNKNOWN_PRIOR
    best = UNKNOWN_PRIOR
    if room_type and room_type != "unknown":
        best = max(best, priors.get(room_type, 0.0))
    inverse = room_of_labels()
    for label, (x, y) in seen:
        d = math.hypot(x - xy[0], y - xy[1])
        if d > radius:
            continue
        for room in inverse.get(fold_label(label), []):
            # nearer evidence counts more; an object at the radius still counts half
            best = max(best, priors.get(room, 0.0) * (1.0 - 0.5 * d / radius))
    return float(min(1.0, best))
