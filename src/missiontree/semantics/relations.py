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

**Rooms.** Two objects in different known rooms are not related (``same_room_only``): a wall
stands between them, and "the plant is behind the sofa" through it would send a robot the wrong
way. An object in no known room may still be related to anything near it.

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
        same_room_only: Objects in two different known rooms are not related.
    """

    near_gap: float = 1.5
    next_gap: float = 0.5
    on_margin: float = 0.1
    on_tolerance: float = 0.2
    side_ratio: float = 1.5
    max_per_object: int = 3
    min_facing_distance: float = 0.5
    same_room_only: bool = True


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
    if len(bodies) < 2:
        return []
    b = sorted(bodies, key=lambda o: o.id)
    table = np.array([(o.x, o.y, o.z, o.w, o.d, o.h) for o in b], dtype=float)
    return _relations(
        [o.id for o in b], table, [o.room for o in b], room_centres or {}, params or RelationParams()
    )


def relations_of(
    objects: Sequence[object],
    room_centres: Mapping[str, tuple[float, float]] | None = None,
    params: RelationParams | None = None,
) -> list[RelationEdge]:
    """``compute_relations(bodies_of(objects), ...)`` without a :class:`Body` per object (the rebuild's path).

    Args:
        objects: Instance-like objects (``id``, ``position``, ``size``, ``room``).
        room_centres: Room id → (x, y) of its middle, for the anchors' facing.
        params: Thresholds.
    """
    if len(objects) < 2:
        return []
    keyed = sorted(((str(o.id), o) for o in objects), key=_first)  # type: ignore[attr-defined]
    no_size = (0.0, 0.0, 0.0)
    table = np.array(
        [(*o.position, *getattr(o, "size", no_size)) for _, o in keyed],  # type: ignore[attr-defined]
        dtype=np.float64,
    )
    np.maximum(table[:, 3:], _MIN_SIZE, out=table[:, 3:])  # as bodies_of: no footprint under 5 cm
    rooms = [getattr(o, "room", None) for _, o in keyed]
    return _relations([k for k, _ in keyed], table, rooms, room_centres or {}, params or RelationParams())


def _first(pair: tuple[str, object]) -> str:
    return pair[0]


#: Smallest side of a footprint or height, metres (a point-like detection still has a body).
_MIN_SIZE = 0.05


def _relations(
    ids: list[str],
    table: np.ndarray,
    rooms: list[str | None],
    centres: Mapping[str, tuple[float, float]],
    p: RelationParams,
) -> list[RelationEdge]:
    """The relations of objects sorted by id: ``table`` rows (x, y, z, w, d, h), ``rooms`` their rooms."""
    xy = table[:, :2]
    half = table[:, 3:5] / 2.0
    bottom = table[:, 2] - table[:, 5] / 2.0
    top = table[:, 2] + table[:, 5] / 2.0
    src, anc, gap, offset = _nearest_anchors(table, rooms, p)
    if not len(src):
        return []
    over = (np.abs(offset[:, 0]) <= half[anc, 0] + p.on_margin) & (
        np.abs(offset[:, 1]) <= half[anc, 1] + p.on_margin
    )
    on = over & (np.abs(bottom[src] - top[anc]) <= p.on_tolerance) & (bottom[src] > 0.05)
    facing, has_facing = _facing(xy, rooms, centres, p.min_facing_distance, np.unique(anc).tolist())
    f = facing[anc]
    along = offset[:, 0] * f[:, 0] + offset[:, 1] * f[:, 1]
    # the anchor's own left is (-fy, fx); a viewer in front of it sees that side on their right
    own_left = -offset[:, 0] * f[:, 1] + offset[:, 1] * f[:, 0]
    code = np.where(gap <= p.next_gap, _NEXT_TO, _NEAR)
    sided = has_facing[anc]
    front_back = sided & (np.abs(along) >= p.side_ratio * np.abs(own_left))
    left_right = sided & ~front_back & (np.abs(own_left) >= p.side_ratio * np.abs(along))
    code[front_back] = np.where(along[front_back] > 0, _IN_FRONT_OF, _BEHIND)
    code[left_right] = np.where(own_left[left_right] > 0, _RIGHT_OF, _LEFT_OF)
    code[on] = _ON
    names = [RELATIONS[k] for k in code.tolist()]
    edge = RelationEdge
    return [edge(ids[i], ids[j], r) for i, j, r in zip(src.tolist(), anc.tolist(), names, strict=True)]


def _nearest_anchors(
    table: np.ndarray, rooms: list[str | None], p: RelationParams
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Each object's nearest anchors within ``near_gap``: (source, anchor, gap, offset) rows.

    Of each close pair the smaller object (by footprint area; ties: the later id) is the source,
    the other its anchor; a source keeps its ``max_per_object`` nearest anchors (ties: the lower
    anchor id). Rows are sorted by source, then gap; the offset is the source's centre from the
    anchor's (N, 2).
    """
    xy = table[:, :2]
    x, y = table[:, 0].copy(), table[:, 1].copy()
    radius = (table[:, 3:5] / 2.0).max(axis=1)  # footprints as discs of the larger half-size
    area = table[:, 3] * table[:, 4]
    none = np.zeros(0, int)
    # candidate pairs: centres closer than the largest possible gap allows (a k-d tree, not n x n)
    pairs = cKDTree(xy).query_pairs(p.near_gap + 2.0 * float(radius.max()), output_type="ndarray")
    if len(pairs) and p.same_room_only:
        room_code = _room_codes(rooms)
        ca, cc = room_code[pairs[:, 0]], room_code[pairs[:, 1]]
        pairs = pairs[(ca == cc) | (ca < 0) | (cc < 0)]
    if not len(pairs):
        return none, none, np.zeros(0), np.zeros((0, 2))
    a, c = pairs[:, 0], pairs[:, 1]
    a_small = (area[a] < area[c]) | ((area[a] == area[c]) & (a > c))
    src = np.where(a_small, a, c)
    anc = np.where(a_small, c, a)
    dx, dy = x[src] - x[anc], y[src] - y[anc]
    gap = np.hypot(dx, dy) - radius[src] - radius[anc]
    row = np.flatnonzero(gap <= p.near_gap)  # rows of dx, dy; the offsets are taken at the end
    src, anc, gap = src[row], anc[row], gap[row]
    if len(src) > _PRESELECT_FROM:
        pick = _best_candidates(src, gap, p.max_per_object)
        src, anc, gap, row = src[pick], anc[pick], gap[pick], row[pick]
    order = np.lexsort((anc, gap, src))
    src, anc, gap, row = src[order], anc[order], gap[order], row[order]
    first = np.flatnonzero(np.concatenate(([True], src[1:] != src[:-1])))  # each source's first row
    rank = np.arange(len(src)) - np.repeat(first, np.diff(np.append(first, len(src))))
    keep = rank < p.max_per_object
    src, anc, gap, row = src[keep], anc[keep], gap[keep], row[keep]
    return src, anc, gap, np.stack((dx[row], dy[row]), axis=1)


_ON, _NEXT_TO, _NEAR, _IN_FRONT_OF, _BEHIND, _LEFT_OF, _RIGHT_OF = range(len(RELATIONS))

#: Above this many candidate pairs, :func:`_best_candidates` thins them before the exact sort.
_PRESELECT_FROM = 2048


def _best_candidates(src: np.ndarray, gap: np.ndarray, k: int) -> np.ndarray:
    """Rows that may be among each source's ``k`` smallest gaps (a superset of them, far fewer rows).

    The gaps are quantised to 16 bits by a non-decreasing map, so a row whose quantised gap exceeds
    the ``k``-th smallest quantised gap of its source has a larger gap than ``k`` others of that
    source and cannot be among its best; the two 16-bit keys sort in linear time (numpy's radix
    sort) where the exact float sort of a crowded room's tens of thousands of pairs takes
    milliseconds. The exact order is then taken on what is left.
    """
    if int(src.max()) > np.iinfo(np.uint16).max:
        return np.arange(len(src))
    low, high = float(gap.min()), float(gap.max())
    scale = 65535.0 / (high - low) if high > low else 0.0
    quantised = np.minimum((gap - low) * scale, 65535.0).astype(np.uint16)
    order = np.argsort(quantised, kind="stable")
    order = order[np.argsort(src[order].astype(np.uint16), kind="stable")]
    by_source, q = src[order], quantised[order]
    starts = np.flatnonzero(np.concatenate(([True], by_source[1:] != by_source[:-1])))
    sizes = np.diff(np.append(starts, len(order)))
    kth = q[starts + np.minimum(sizes, k) - 1]
    return order[q <= np.repeat(kth, sizes)]


def _room_codes(rooms: list[str | None]) -> np.ndarray:
    """A number per object's room, -1 for none (equal numbers: the same room)."""
    numbers: dict[str, int] = {}
    return np.fromiter(
        (-1 if r is None else numbers.setdefault(r, len(numbers)) for r in rooms),
        dtype=np.intp,
        count=len(rooms),
    )


def _facing(
    xy: np.ndarray,
    rooms: list[str | None],
    centres: Mapping[str, tuple[float, float]],
    min_distance: float,
    anchors: list[int],
) -> tuple[np.ndarray, np.ndarray]:
    """Unit vector from each of the ``anchors`` (rows) towards its room's middle, and whether it has one.

    An object in no known room, or closer than ``min_distance`` to its room's middle, has none;
    rows not in ``anchors`` are left without one (nothing is related to them as an anchor).
    """
    n = len(rooms)
    facing = np.zeros((n, 2))
    has = np.zeros(n, bool)
    known = [(j, centres[r]) for j in anchors if (r := rooms[j]) is not None and r in centres]
    if not known:
        return facing, has
    rows = np.fromiter((j for j, _ in known), dtype=np.intp, count=len(known))
    middle = np.array([c for _, c in known], dtype=float).reshape(len(known), 2)
    fx = middle[:, 0] - xy[rows, 0]
    fy = middle[:, 1] - xy[rows, 1]
    # math.hypot, not np.hypot: the two differ in the last bit now and then, and a facing on the
    # edge of a side's cone must come out the same whichever path computed it
    norm = np.array([math.hypot(u, v) for u, v in zip(fx.tolist(), fy.tolist(), strict=True)])
    ok = norm >= min_distance
    rows, norm = rows[ok], norm[ok]
    facing[rows, 0] = fx[ok] / norm
    facing[rows, 1] = fy[ok] / norm
    has[rows] = True
    return facing, has
