"""The semantic map: object instances in the map frame, kept true as things move and disappear.

An :class:`Instance` is one physical object the robot believes in: its class label, its position
(x, y, z of its centre in the map frame, metres), a size estimate (width, depth, height), a colour
name (one of :data:`missiontree.perception.colour.COLOUR_NAMES`), how many frames confirmed it,
a confidence in [0, 1], when it was first and last seen, the room it stands in and a ``doubtful``
flag (it should have been seen lately and was not).

:class:`SemanticMap` holds them and records every change as a :class:`Change` (``added``,
``moved``, ``removed``; ``updated`` for a new room, description or colour), which the scene-graph
leaf turns into ``scene_graph_changed`` tick-log events. Deciding *when* an instance is added,
moved or removed is the job of :mod:`missiontree.semantics.fusion`; this module only keeps the
books.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from dataclasses import asdict, dataclass, field
from typing import Any, Literal

ChangeKind = Literal["added", "moved", "removed", "updated"]

Vec3 = tuple[float, float, float]


@dataclass
class Instance:
    """One object instance (see module docstring).

    Attributes:
        id: Stable id, also the object node's id in the scene graph (``chair_3``).
        label: Class label (``chair``).
        position: Centre (x, y, z) in the map frame, metres.
        size: (width, depth, height) estimate, metres.
        colour: Colour name.
        observations: Frames that confirmed it.
        confidence: Belief that it is there, in [0, 1].
        first_seen: Time of the first observation (robot clock).
        last_seen: Time of the latest observation.
        room: Id of the room it stands in, None when unknown.
        doubtful: True after frames that should have shown it did not.
        description: One sentence (from the VLM or measured).
        shape: A word or two (``boxy``, ``tall``).
        relative_size: ``small``, ``medium`` or ``large``.
        misses: Consecutive frames that should have shown it and did not.
    """

    id: str
    label: str
    position: Vec3
    size: Vec3 = (0.0, 0.0, 0.0)
    colour: str = "unknown"
    observations: int = 1
    confidence: float = 0.5
    first_seen: float = 0.0
    last_seen: float = 0.0
    room: str | None = None
    doubtful: bool = False
    description: str = ""
    shape: str = ""
    relative_size: str = ""
    misses: int = 0

    @property
    def xy(self) -> tuple[float, float]:
        """Planar position."""
        return self.position[0], self.position[1]

    def distance_to(self, x: float, y: float) -> float:
        """Planar distance from the instance to (x, y)."""
        return math.hypot(self.position[0] - x, self.position[1] - y)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict (positions rounded to millimetres)."""
        data = asdict(self)
        data["position"] = [round(v, 3) for v in self.position]
        data["size"] = [round(v, 3) for v in self.size]
        data["confidence"] = round(self.confidence, 4)
        return data

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Instance:
        """Inverse of :meth:`to_dict`."""
        values = dict(data)
        values["position"] = tuple(float(v) for v in values["position"])
        values["size"] = tuple(float(v) for v in values.get("size", (0.0, 0.0, 0.0)))
        known = set(cls.__dataclass_fields__)
        return cls(**{k: v for k, v in values.items() if k in known})


@dataclass(frozen=True)
class Change:
    """One change of the semantic map.

    Attributes:
        kind: ``added``, ``moved``, ``removed`` or ``updated``.
        id: The instance's id.
        label: Its label.
        position: Its position after the change (before it, for ``removed``).
        stamp: Robot time of the change.
        previous: Position before a move.
        reason: Why (``confirmed in 10 frames``, ``not seen in 5 frames that should show it``).
    """

    kind: ChangeKind
    id: str
    label: str
    position: Vec3
    stamp: float
    previous: Vec3 | None = None
    reason: str = ""

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict for the tick log."""
        data: dict[str, Any] = {
            "id": self.id,
            "label": self.label,
            "position": [round(v, 3) for v in self.position],
        }
        if self.previous is not None:
            data["previous"] = [round(v, 3) for v in self.previous]
        if self.reason:
            data["reason"] = self.reason
        return data


@dataclass
class SemanticMap:
    """Object instances by id, with the changes made to them (see module docstring).

    Attributes:
        instances: Instances by id, in the order they were added.
        changes: Changes not yet taken by :meth:`drain_changes`.
    """

    instances: dict[str, Instance] = field(default_factory=dict)
    changes: list[Change] = field(default_factory=list)
    _counts: dict[str, int] = field(default_factory=dict, repr=False)
    _listeners: list[Callable[[Change], None]] = field(default_factory=list, repr=False)

    # -- reading ---------------------------------------------------------------------------------

    def __len__(self) -> int:
        return len(self.instances)

    def __iter__(self) -> Iterator[Instance]:
        return iter(list(self.instances.values()))

    def __contains__(self, instance_id: object) -> bool:
        return instance_id in self.instances

    def get(self, instance_id: str) -> Instance | None:
        """The instance with this id, or None."""
        return self.instances.get(instance_id)

    def by_label(self, label: str) -> list[Instance]:
        """Every instance of a label."""
        return [i for i in self.instances.values() if i.label == label]

    def near(self, x: float, y: float, radius: float, label: str | None = None) -> list[Instance]:
        """Instances within ``radius`` of (x, y) (of ``label`` when given), nearest first."""
        found = [
            i
            for i in self.instances.values()
            if (label is None or i.label == label) and i.distance_to(x, y) <= radius
        ]
        return sorted(found, key=lambda i: i.distance_to(x, y))

    # -- changing --------------------------------------------------------------------------------

    def subscribe(self, listener: Callable[[Change], None]) -> None:
        """Call ``listener`` with every change from now on."""
        self._listeners.append(listener)

    def new_id(self, label: str) -> str:
        """A fresh id for an instance of ``label`` (``potted_plant_2``)."""
        stem = "_".join(label.lower().split()) or "object"
        while True:
            self._counts[stem] = self._counts.get(stem, 0) + 1
            candidate = f"{stem}_{self._counts[stem]}"
            if candidate not in self.instances:
                return candidate

    def add(self, label: str, position: Vec3, stamp: float, *, reason: str = "", **fields: Any) -> Instance:
        """Add a new instance of ``label`` at ``position``; record an ``added`` change.

        Args:
            label: Class label.
            position: Centre (x, y, z) in the map frame.
            stamp: Robot time (first and last seen, unless given in ``fields``).
            reason: Why it was added, for the change.
            **fields: Any other :class:`Instance` attribute (``size``, ``colour``, ``id`` ...).
        """
        instance_id = fields.pop("id", None) or self.new_id(label)
        if instance_id in self.instances:
            raise ValueError(f"an instance with id {instance_id!r} exists already; use update() or move()")
        fields.setdefault("first_seen", stamp)
        fields.setdefault("last_seen", stamp)
        instance = Instance(id=instance_id, label=label, position=_vec(position), **fields)
        self.instances[instance_id] = instance
        self._record(Change("added", instance_id, label, instance.position, stamp, reason=reason))
        return instance

    def update(
        self,
        instance_id: str,
        stamp: float | None = None,
        *,
        announce: bool = False,
        reason: str = "",
        **fields: Any,
    ) -> Instance:
        """Set attributes of an instance; record an ``updated`` change when ``announce`` is true.

        Raises:
            KeyError: No such instance.
        """
        instance = self._instance(instance_id)
        for name, value in fields.items():
            if name not in Instance.__dataclass_fields__ or name in ("id", "label"):
                raise ValueError(f"cannot update {name!r} of an instance")
            setattr(instance, name, _vec(value) if name in ("position", "size") else value)
        if announce:
            self._record(
                Change(
                    "updated",
                    instance_id,
                    instance.label,
                    instance.position,
                    stamp if stamp is not None else instance.last_seen,
                    reason=reason,
                )
            )
        return instance

    def move(self, instance_id: str, position: Vec3, stamp: float, reason: str = "") -> Change:
        """Move an instance to ``position``; record a ``moved`` change (with where it was)."""
        instance = self._instance(instance_id)
        previous = instance.position
        instance.position = _vec(position)
        instance.last_seen = stamp
        instance.misses = 0
        instance.doubtful = False
        change = Change("moved", instance_id, instance.label, instance.position, stamp, previous, reason)
        self._record(change)
        return change

    def remove(self, instance_id: str, stamp: float, reason: str = "") -> Change:
        """Remove an instance; record a ``removed`` change."""
        instance = self._instance(instance_id)
        del self.instances[instance_id]
        change = Change("removed", instance_id, instance.label, instance.position, stamp, reason=reason)
        self._record(change)
        return change

    def drain_changes(self) -> list[Change]:
        """The changes recorded since the last call, oldest first (and forget them)."""
        taken, self.changes = self.changes, []
        return taken

    # -- persistence -----------------------------------------------------------------------------

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict of every instance."""
        return {"instances": [i.to_dict() for i in self.instances.values()]}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> SemanticMap:
        """Inverse of :meth:`to_dict` (no changes recorded)."""
        semantic_map = cls()
        for raw in data.get("instances", []):
            instance = Instance.from_dict(raw)
            semantic_map.instances[instance.id] = instance
        return semantic_map

    # -- internals -------------------------------------------------------------------------------

    def _instance(self, instance_id: str) -> Instance:
        try:
            return self.instances[instance_id]
        except KeyError:
            known = ", ".join(list(self.instances)[:20]) or "none"
            raise KeyError(f"no instance {instance_id!r} in the semantic map (known: {known})") from None

    def _record(self, change: Change) -> None:
        self.changes.append(change)
        for listener in self._listeners:
            listener(change)


def _vec(value: Any) -> Vec3:
    values = tuple(float(v) for v in value)
    if len(values) == 2:
        values = (*values, 0.0)
    if len(values) != 3 or not all(math.isfinite(v) for v in values):
        raise ValueError(f"expected a finite (x, y, z), found {value!r}")
    return values  # type: ignore[return-value]
