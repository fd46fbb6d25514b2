"""Spatial relations between objects, computed from geometry: deterministic, in milliseconds.

For every pair of objects whose footprints are within ``near_gap`` of each other, the smaller
object (by footprint area, ties by id) is related to the larger one, its *anchor*, by exactly one
relation, ``source relation target`` reading "the cup is on the table":

- ``on``: the source's footprint centre lies over the anchor's footprint (grown by ``on_margin``)
  and its bottom is within ``on_tolerance`` of the anchor's top;
- ``next_to``: the gap between their footprints is at most ``next_gap`` and neither is on the
  other; refined to ``in_front_of`` / ``behind`` / ``left_of`` / ``right_of`` when the anchor has a
  facing and the source lies clearly (more than ``side_ratio`` times) along one of its axes;
- ``near``: the gap is at most ``near_gap``; refined in the same way.

**Facing.** The anchor's front is the side turned towards the middle of its room (furniture stands
against walls and faces into the room); for an object in no known room, the side turned towards
the room's door is not known either and the plain ``next_to`` / ``near`` is kept. ``left_of`` and
``right_of`` are as seen by someone standing in front of the anchor and looking at it (the sofa's
own left is the viewer's right).

Each object keeps relations to its ``max_per_object`` nearest anchors, so a crowded room does not
become a complete graph. Relation names are those of
:data:`RELATIONS`; :func:`normalise_relation` maps the NAIS paper's phrasing ("on top of",
"next to", "in front of") onto them.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from missiontree.semantics.scene_graph import RelationEdge

#: Relation names, as the reasoning layer's reference schema spells them.
RELATIONS = ("on", "next_to", "near", "in_front_of", "behind", "left_of", "right_of")

_SYNONYMS = {
    "on top of": "on",
    "on_top_of": "on",
    "atop": "on",
    "on": "on",
    "next to": "next_to",
    "beside": "next_to",
    "by": "next_to",
    "adjacent to": "next_to",
    "in front of": "in_front_of",
    "before": "in_front_of",
    "behind": "behind",
    "in back of": "behind",
    "left of": "left_of",
    "to the left of": "left_of",
    "right of": "right_of",
    "to the right of": "right_of",
    "near": "near",
    "close to": "near",
    "nearby": "near",
}


def normalise_relation(text: str) -> str:
    """Our name for a relation phrase (``"on top of"`` → ``on``); unknown phrases snake_cased."""
    key = " ".join(text.strip().lower().replace("_", " ").split())
    return _SYNONYMS.get(key, key.replace(" ", "_"))


@dataclass(frozen=True)
class RelationParams:
    """Thresholds of the relations (metres, ratios).

    Attributes:
        near_gap: Largest footprint gap for ``near``.
        next_gap: Largest footprint gap for ``next_to``.
        on_margin: Growth of the anchor's footprint when testing ``on``.
        on_tolerance: Largest difference between the source's bottom and the anchor's top for ``on``.
        side_ratio: How much longer one axis offset must be than the other to name a side.
        max_per_object: Anchors kept per object, nearest first.
        min_facing_distance: An anchor this close to its room's middle has no facing.
    """

    near_gap: float = 1.5
    next_gap: float = 0.5
    on_margin: float = 0.1
    on_tolerance: float = 0.2
    side_ratio: float = 1.5
    max_per_object: int = 3
    min_facing_distance: float = 0.5


@dataclass(frozen=True)
class Body:
    """What relations need of an object: id, centre, size (width, depth, height), room."""

    id: str
    x: float
    y: float
    z: float
    w: float
    d: float
    h: float
    room: str | None = None


def bodies_of(objects: Sequence[object]) -> list[Body]:
    """:class:`Body` of each instance-like object (``id``, ``position``, ``size``, ``room``)."""
    out = []
    for o in objects:
        x, y, z = o.position  # type: ignore[attr-defined]
        w, d, h = getattr(o, "size", (0.0, 0.0, 0.0))
        out.append(
            Body(
                str(o.id),  # type: ignore[attr-defined]
                float(x),
                float(y),
                float(z),
                max(float(w), 0.05),
                max(float(d), 0.05),  # type: ignore[attr-defined]
                max(float(h), 0.05),
                getattr(o, "room", None),
            )
        )
    return out


def compute_relations(
    bodies: Sequence[Body],
    room_centres: Mapping[str, tuple[float, float]] | None = None,
    params: RelationParams | None = None,
) -> list[RelationEdge]:
    """Relations between ``bodies`` (see module docstring), sorted by source id, then nearest anchor.

    Args:
        bodies: The objects.
        room_centres: Room id → (x, y) of its middle, for the anchors' facing.
        params: Thresholds.
    """
    p = params or RelationParams()
    n = len(bodies)
    if n < 2:
        return []
    centres = room_centres or {}
    b = sorted(bodies, key=lambda o: o.id)
    table = np.array([(o.x, o.y, o.z, o.w, o.d, o.h) for o in b], dtype=float)
    xy = table[:, :2]
    half = table[:, 3:5] / 2.0
    radius = half.max(axis=1)  # footprints as discs of the larger half-size: orientation is unknown
    bottom = table[:, 2] - table[:, 5] / 2.0
    top = table[:, 2] + table[:, 5] / 2.0
    area = table[:, 3] * table[:, 4]
    # candidate pairs: centres closer than the largest possible gap allows (a k-d tree, not n x n)
    tree = cKDTree(xy)
    pairs = tree.query_pairs(p.near_gap + 2.0 * float(radius.max()), output_type="ndarray")
    if not len(pairs):
        return []
    a, c = pairs[:, 0], pairs[:, 1]
    # the smaller (by area, ties: the later id) is the source, the other its anchor
    a_small = (area[a] < area[c]) | ((area[a] == area[c]) & (a > c))
    src = np.where(a_small, a, c)
    anc = np.where(a_small, c, a)
    offset = xy[src] - xy[anc]
    dist = np.hypot(offset[:, 0], offset[:, 1])
    gap = dist - radius[src] - radius[anc]
    keep = gap <= p.near_gap
    src, anc, offset, gap = src[keep], anc[keep], offset[keep], gap[keep]
    # each source keeps its max_per_object nearest anchors
    order = np.lexsort((anc, gap, src))
    src, anc, offset, gap = src[order], anc[order], offset[order], gap[order]
    first = np.r_[0, np.flatnonzero(np.diff(src)) + 1]
    rank = np.arange(len(src)) - np.repeat(first, np.diff(np.r_[first, len(src)]))
    keep = rank < p.max_per_object
    src, anc, offset, gap = src[keep], anc[keep], offset[keep], gap[keep]
    over = (np.abs(offset[:, 0]) <= half[anc, 0] + p.on_margin) & (
        np.abs(offset[:, 1]) <= half[anc, 1] + p.on_margin
    )
    on = over & (np.abs(bottom[src] - top[anc]) <= p.on_tolerance) & (bottom[src] > 0.05)
    facing = np.zeros((n, 2))
    has_facing = np.zeros(n, bool)
    for j, o in enumerate(b):
        centre = centres.get(o.room) if o.room is not None else None
        if centre is None:
            continue
        fx, fy = centre[0] - o.x, centre[1] - o.y
        norm = math.hypot(fx, fy)
        if norm >= p.min_facing_distance:
            facing[j] = (fx / norm, fy / norm)
            has_facing[j] = True
    f = facing[anc]
    along = offset[:, 0] * f[:, 0] + offset[:, 1] * f[:, 1]
    # the anchor's own left is (-fy, fx); a viewer in front of it sees that side on their right
    own_left = -offset[:, 0] * f[:, 1] + offset[:, 1] * f[:, 0]
    relation = np.where(gap <= p.next_gap, "next_to", "near").astype(object)
    sided = has_facing[anc]
    front_back = sided & (np.abs(along) >= p.side_ratio * np.abs(own_left))
    left_right = sided & ~front_back & (np.abs(own_left) >= p.side_ratio * np.abs(along))
    relation[front_back] = np.where(along[front_back] > 0, "in_front_of", "behind")
    relation[left_right] = np.where(own_left[left_right] > 0, "right_of", "left_of")
    relation[on] = "on"
    ids = [o.id for o in b]
    return [
        RelationEdge(ids[i], ids[j], str(r))
        for i, j, r in zip(src.tolist(), anc.tolist(), relation, strict=True)
    ]
