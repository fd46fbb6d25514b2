"""A second family of seeded worlds, different in kind from the generator's apartments: floorplans.

``floorplan_world(seed)`` returns world-file data (the format of config/worlds/*.yaml, so it goes
through the same checks); ``load_world("floorplan:1003")`` builds it directly. The seed picks the
kind, ``KINDS[seed % len(KINDS)]``:

====  ===========  ===========================================================================
seed  kind         layout
====  ===========  ===========================================================================
% 7   0 corridor   a long straight corridor (16-28 m, 1.6-2.2 m wide), rooms on both sides,
                   each through one 0.8-0.9 m door
      1 l_corridor an L-shaped corridor, rooms along both arms (0.8-0.9 m doors)
      2 t_corridor a T-shaped corridor, rooms along the bar and both sides of the stem
      3 open_plan  one open floor split into zones (kitchen, living room, office) by partial
                   partitions, with a strip of closed rooms (bathroom, storage) behind doors
      4 suites     rooms off a corridor, some of them a suite: a back room (bathroom, storage,
                   bedroom) reached only through the front room
      5 clutter    a corridor with rooms whose doors have chairs, bins, plants and bags beside
                   them, on both sides, leaving the door passable for a 0.34 m-wide robot
      6 warehouse  a 20-30 x 30-50 m floor with rows of shelving, a loading area and a strip
                   of offices, a break room and a washroom
====  ===========  ===========================================================================

Rooms are axis-aligned polygons (corridors L- and T-shaped) with names and types; walls are the
rooms' outlines merged into few long segments (shelving is a closed wall polygon each), with door
gaps cut out, so the world loader stays cheap on the largest floors. Furniture and small objects
come from :func:`missiontree.backends.sim.placement.place_objects`, people walk between doors. A
layout whose rooms the planner cannot all reach from the start is drawn again from the same
generator: the world depends on the seed alone.
"""

from __future__ import annotations

import math
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import yaml

from missiontree.backends.sim.generator import MAX_SEED, object_entry
from missiontree.backends.sim.placement import keep_fitting, place_objects, unreachable_rooms
from missiontree.backends.sim.placer import build
from missiontree.backends.sim.world import register_world_source
from missiontree.errors import Problem, WorldFileError
from missiontree.yamlio import Located, parse_yaml

#: World names of this form are floorplans: ``floorplan:1003``.
FLOORPLAN_PREFIX = "floorplan:"
#: The kinds, in the order the seed picks them (``seed % len(KINDS)``).
KINDS = ("corridor", "l_corridor", "t_corridor", "open_plan", "suites", "clutter", "warehouse")
#: Door widths (m) of the doors between rooms and corridors.
DOOR_MIN, DOOR_MAX = 0.8, 0.9
#: Room types handed to rooms off corridors (shuffled per world).
CORRIDOR_ROOM_TYPES = ["office", "kitchen", "bedroom", "bathroom", "living room", "storage", "office"]
_ATTEMPTS = 8
_MIN_ROOM = 2.8

Rect = tuple[float, float, float, float]


def kind_of(seed: int) -> str:
    """The kind of floorplan a seed gives."""
    return KINDS[seed % len(KINDS)]


@dataclass
class _Plan:
    """A floorplan being drawn: rooms (polygons), door gaps, free-standing wall polygons."""

    rooms: list[tuple[str, list[tuple[float, float]]]] = field(default_factory=list)  # type, polygon
    openings: list[tuple[float, float, float, float]] = field(default_factory=list)  # gaps in walls
    doors: list[tuple[float, float, str]] = field(default_factory=list)  # centre, wall axis ("x"/"y")
    solids: list[list[tuple[float, float]]] = field(default_factory=list)  # shelving etc.
    start_room: int = 0
    clutter: bool = False

    def room(self, kind: str, rect: Rect) -> int:
        x0, y0, x1, y1 = rect
        self.rooms.append((kind, [(x0, y0), (x1, y0), (x1, y1), (x0, y1)]))
        return len(self.rooms) - 1

    def door(
        self,
        rng: np.random.Generator,
        a: tuple[float, float],
        b: tuple[float, float],
        width: float | None = None,
    ) -> None:
        """A door somewhere along the wall from ``a`` to ``b`` (axis-aligned), 0.4 m from its ends."""
        w = float(rng.uniform(DOOR_MIN, DOOR_MAX)) if width is None else width
        length = abs(b[0] - a[0]) + abs(b[1] - a[1])
        t = float(rng.uniform(0.4 + w / 2, max(0.4 + w / 2, length - 0.4 - w / 2)))
        self.open_at(a, b, t, w)

    def open_at(
        self, a: tuple[float, float], b: tuple[float, float], t: float, w: float, door: bool = True
    ) -> None:
        """A gap of width ``w`` centred ``t`` along the wall from ``a`` to ``b``."""
        if a[1] == b[1]:  # horizontal wall
            x = min(a[0], b[0]) + t
            self.openings.append((x - w / 2, a[1], x + w / 2, a[1]))
            if door:
                self.doors.append((x, a[1], "y"))
        else:
            y = min(a[1], b[1]) + t
            self.openings.append((a[0], y - w / 2, a[0], y + w / 2))
            if door:
                self.doors.append((a[0], y, "x"))


def _strip(
    plan: _Plan,
    rng: np.random.Generator,
    rect: Rect,
    door_side: str,
    types: list[str],
    widths: tuple[float, float] = (2.8, 4.5),
) -> list[int]:
    """Rooms side by side filling ``rect``, each with a door on its ``door_side`` (N, S, E, W)."""
    x0, y0, x1, y1 = rect
    along_x = door_side in "NS"
    lo, hi = (x0, x1) if along_x else (y0, y1)
    cuts = [lo]
    while hi - cuts[-1] > 2 * _MIN_ROOM:
        cuts.append(cuts[-1] + float(rng.uniform(widths[0], min(widths[1], hi - cuts[-1] - _MIN_ROOM))))
    cuts.append(hi)
    made = []
    for a, b in zip(cuts[:-1], cuts[1:], strict=True):
        r = (a, y0, b, y1) if along_x else (x0, a, x1, b)
        made.append(plan.room(types[len(plan.rooms) % len(types)], r))
        rx0, ry0, rx1, ry1 = r
        edge = {
            "N": ((rx0, ry1), (rx1, ry1)),
            "S": ((rx0, ry0), (rx1, ry0)),
            "E": ((rx1, ry0), (rx1, ry1)),
            "W": ((rx0, ry0), (rx0, ry1)),
        }[door_side]
        plan.door(rng, *edge)
    return made


def _types(rng: np.random.Generator) -> list[str]:
    return [CORRIDOR_ROOM_TYPES[int(k)] for k in rng.permutation(len(CORRIDOR_ROOM_TYPES))]


def _corridor(rng: np.random.Generator, suites: bool = False) -> _Plan:
    plan = _Plan()
    length = float(rng.uniform(16.0, 28.0))
    cw = float(rng.uniform(1.6, 2.2))
    deep = (5.6, 7.5) if suites else (3.0, 4.5)
    ds, dn = float(rng.uniform(*deep)), float(rng.uniform(*deep))
    plan.start_room = plan.room("corridor", (0.0, ds, length, ds + cw))
    types = _types(rng)
    south = _strip(plan, rng, (0.0, 0.0, length, ds), "N", types)
    north = _strip(plan, rng, (0.0, ds + cw, length, ds + cw + dn), "S", types)
    if suites:
        for i in south + north:
            if rng.random() < 0.6:
                _split_suite(plan, rng, i, back_at_south=i in south)
    return plan


#: What a suite's back room may be, by the front room's type.
_BACK_ROOMS = {
    "bedroom": ["bathroom", "storage"],
    "office": ["storage", "office"],
    "kitchen": ["storage"],
    "living room": ["bedroom", "office"],
    "bathroom": ["storage"],
    "storage": ["storage", "office"],
}


def _split_suite(plan: _Plan, rng: np.random.Generator, index: int, back_at_south: bool) -> None:
    """Split a room in depth: the front keeps its door, the back is reached only through the front."""
    kind, poly = plan.rooms[index]
    x0, y0 = poly[0]
    x1, y1 = poly[2]
    depth = y1 - y0
    back = float(rng.uniform(2.4, depth - 2.8))
    choices = _BACK_ROOMS.get(kind, ["storage"])
    back_type = choices[int(rng.integers(len(choices)))]
    if back_at_south:
        y = y0 + back
        plan.rooms[index] = (kind, [(x0, y), (x1, y), (x1, y1), (x0, y1)])
        plan.room(back_type, (x0, y0, x1, y))
    else:
        y = y1 - back
        plan.rooms[index] = (kind, [(x0, y0), (x1, y0), (x1, y), (x0, y)])
        plan.room(back_type, (x0, y, x1, y1))
    plan.door(rng, (x0, y), (x1, y))


def _l_corridor(rng: np.random.Generator) -> _Plan:
    plan = _Plan()
    a, b = float(rng.uniform(14.0, 22.0)), float(rng.uniform(12.0, 20.0))
    cw = float(rng.uniform(1.6, 2.2))
    d1, d2, d3 = (float(rng.uniform(3.0, 4.5)) for _ in range(3))
    # arms: horizontal y in [0, cw] x in [0, a]; vertical x in [a - cw, a] y in [0, b]
    plan.start_room = len(plan.rooms)
    plan.rooms.append(("corridor", [(0.0, 0.0), (a, 0.0), (a, b), (a - cw, b), (a - cw, cw), (0.0, cw)]))
    types = _types(rng)
    _strip(plan, rng, (0.0, -d1, a, 0.0), "N", types)  # south of the bar
    _strip(plan, rng, (a, 0.0, a + d2, b), "W", types)  # east of the stem
    _strip(plan, rng, (0.0, cw, a - cw - d3, cw + d3), "S", types)  # north of the bar
    _strip(plan, rng, (a - cw - d3, cw, a - cw, b), "E", types)  # west of the stem
    return plan


def _t_corridor(rng: np.random.Generator) -> _Plan:
    plan = _Plan()
    a, b = float(rng.uniform(18.0, 26.0)), float(rng.uniform(10.0, 18.0))
    cw = float(rng.uniform(1.6, 2.2))
    m = float(rng.uniform(a * 0.35, a * 0.65 - cw))
    d1, d2, d3 = (float(rng.uniform(3.0, 4.5)) for _ in range(3))
    plan.start_room = len(plan.rooms)
    plan.rooms.append(
        (
            "corridor",
            [(0.0, 0.0), (a, 0.0), (a, cw), (m + cw, cw), (m + cw, cw + b), (m, cw + b), (m, cw), (0.0, cw)],
        )
    )
    types = _types(rng)
    _strip(plan, rng, (0.0, -d1, a, 0.0), "N", types)
    _strip(plan, rng, (0.0, cw, m - d2, cw + d2), "S", types)
    _strip(plan, rng, (m - d2, cw, m, cw + b), "E", types)
    _strip(plan, rng, (m + cw + d3, cw, a, cw + d3), "S", types)
    _strip(plan, rng, (m + cw, cw, m + cw + d3, cw + b), "W", types)
    return plan


def _open_plan(rng: np.random.Generator) -> _Plan:
    plan = _Plan()
    w, h = float(rng.uniform(12.0, 17.0)), float(rng.uniform(8.0, 11.0))
    strip = float(rng.uniform(2.4, 3.2))
    zones = ["living room", "kitchen", "office"]
    zones = [zones[int(k)] for k in rng.permutation(3)]
    count = 3 if w >= 14.0 else 2
    cuts = sorted(float(c) for c in rng.uniform(3.8, w - 3.8, size=count - 1))
    if count == 3 and cuts[1] - cuts[0] < 3.8:
        cuts = [w / 3, 2 * w / 3]
    xs = [0.0, *cuts, w]
    first = len(plan.rooms)
    for i in range(count):
        plan.room(zones[i], (xs[i], 0.0, xs[i + 1], h - strip))
    plan.start_room = first + int(rng.integers(count))
    for x in cuts:  # partial partitions: a wall from one end, or from both ends with a gap
        length = h - strip
        gap = float(rng.uniform(1.6, 3.0))
        if rng.random() < 0.5:
            t = float(rng.uniform(gap / 2 + 0.01, length - gap / 2 - 0.01))
            plan.open_at((x, 0.0), (x, length), t, gap, door=False)
        else:  # open at one end, the partition running from the other
            at_top = rng.random() < 0.5
            open_len = float(rng.uniform(length * 0.35, length * 0.6))
            t = length - open_len / 2 if at_top else open_len / 2
            plan.open_at((x, 0.0), (x, length), t, open_len, door=False)
    # closed rooms along the north side, doors into the open floor
    _strip(
        plan,
        rng,
        (0.0, h - strip, w, h),
        "S",
        ["bathroom", "storage", "bedroom", "office"],
        widths=(2.8, 4.0),
    )
    return plan


def _clutter(rng: np.random.Generator) -> _Plan:
    plan = _corridor(rng)
    plan.clutter = True
    return plan


def _warehouse(rng: np.random.Generator) -> _Plan:
    plan = _Plan()
    w, h = float(rng.uniform(20.0, 30.0)), float(rng.uniform(30.0, 50.0))
    office = float(rng.uniform(3.5, 4.5))
    loading = float(rng.uniform(5.0, 7.0))
    types = ["office", "bathroom", "kitchen", "storage", "office", "storage"]
    _strip(plan, rng, (0.0, 0.0, w, office), "N", types, widths=(3.0, 5.0))
    plan.start_room = plan.room("hall", (0.0, office, w, office + loading))
    plan.openings.append((0.0, office + loading, w, office + loading))
    mid = office + loading + (h - office - loading) / 2
    plan.room("storage", (0.0, office + loading, w, mid))
    plan.room("storage", (0.0, mid, w, h))
    plan.openings.append((0.0, mid, w, mid))
    # shelving rows along x with aisles, a cross aisle in the middle and 2 m clear at the walls
    depth = float(rng.uniform(0.9, 1.2))
    aisle = float(rng.uniform(2.4, 3.4))
    cross = float(rng.uniform(2.4, 3.2))
    x0, x1 = 2.2, w - 2.2
    xm = (x0 + x1) / 2
    y = office + loading + 1.5
    while y + depth < h - 2.2:
        for a, b in ((x0, xm - cross / 2), (xm + cross / 2, x1)):
            if b - a > 2.0 and not (mid - 0.1 < y + depth and y < mid + 0.1):
                plan.solids.append([(a, y), (b, y), (b, y + depth), (a, y + depth)])
        y += depth + aisle
    return plan


_DRAW = {
    "corridor": _corridor,
    "l_corridor": _l_corridor,
    "t_corridor": _t_corridor,
    "open_plan": _open_plan,
    "suites": lambda rng: _corridor(rng, suites=True),
    "clutter": _clutter,
    "warehouse": _warehouse,
}


def _walls(plan: _Plan) -> list[tuple[float, float, float, float]]:
    """The rooms' outlines merged into the fewest segments per line, with the openings cut out."""
    lines: dict[tuple[str, float], list[tuple[float, float]]] = defaultdict(list)
    for _kind, poly in plan.rooms:
        for (ax, ay), (bx, by) in zip(poly, [*poly[1:], poly[0]], strict=True):
            if abs(ay - by) < 1e-9:
                lines[("h", round(ay, 4))].append((min(ax, bx), max(ax, bx)))
            else:
                lines[("v", round(ax, 4))].append((min(ay, by), max(ay, by)))
    cuts: dict[tuple[str, float], list[tuple[float, float]]] = defaultdict(list)
    for ax, ay, bx, by in plan.openings:
        if abs(ay - by) < 1e-9:
            cuts[("h", round(ay, 4))].append((min(ax, bx), max(ax, bx)))
        else:
            cuts[("v", round(ax, 4))].append((min(ay, by), max(ay, by)))
    segments: list[tuple[float, float, float, float]] = []
    for key, spans in sorted(lines.items()):
        for a, b in _subtract(_union(spans), _union(cuts.get(key, []))):
            if b - a < 0.02:
                continue
            axis, c = key
            segments.append((a, c, b, c) if axis == "h" else (c, a, c, b))
    return segments


def _union(spans: list[tuple[float, float]]) -> list[tuple[float, float]]:
    merged: list[tuple[float, float]] = []
    for a, b in sorted(spans):
        if merged and a <= merged[-1][1] + 1e-6:
            merged[-1] = (merged[-1][0], max(merged[-1][1], b))
        else:
            merged.append((a, b))
    return merged


def _subtract(
    spans: list[tuple[float, float]], holes: list[tuple[float, float]]
) -> list[tuple[float, float]]:
    out = []
    for a, b in spans:
        pieces = [(a, b)]
        for ha, hb in holes:
            pieces = [
                p for lo, hi in pieces for p in ((lo, min(hi, ha)), (max(lo, hb), hi)) if p[1] - p[0] > 1e-6
            ]
        out += pieces
    return out


def _names(plan: _Plan) -> list[dict[str, Any]]:
    counts: dict[str, int] = defaultdict(int)
    total: dict[str, int] = defaultdict(int)
    for kind, _ in plan.rooms:
        total[kind] += 1
    rooms = []
    for kind, poly in plan.rooms:
        counts[kind] += 1
        name = kind if total[kind] == 1 else f"{kind} {counts[kind]}"
        rooms.append({"name": name, "type": kind, "polygon": [[round(x, 3), round(y, 3)] for x, y in poly]})
    return rooms


def _start(plan: _Plan, rng: np.random.Generator) -> tuple[float, float]:
    """A point of the start room at least 0.6 m from its walls and shelving and 1 m from doors."""
    poly = np.array(plan.rooms[plan.start_room][1])
    x0, y0 = poly.min(axis=0)
    x1, y1 = poly.max(axis=0)
    contour = poly.astype(np.float32)
    for _ in range(400):
        x, y = float(rng.uniform(x0 + 0.6, x1 - 0.6)), float(rng.uniform(y0 + 0.6, y1 - 0.6))
        if cv2.pointPolygonTest(contour, (x, y), False) <= 0 or _edge_distance(x, y, poly) < 0.6:
            continue
        if all(math.hypot(x - dx, y - dy) > 1.0 for dx, dy, _ in plan.doors) and not any(
            _in_rect(x, y, s, 0.6) for s in plan.solids
        ):
            return x, y
    return float(poly[:, 0].mean()), float(poly[:, 1].mean())


def _edge_distance(x: float, y: float, poly: np.ndarray) -> float:
    best = math.inf
    for (ax, ay), (bx, by) in zip(poly, np.roll(poly, -1, axis=0), strict=True):
        dx, dy = bx - ax, by - ay
        t = max(0.0, min(1.0, ((x - ax) * dx + (y - ay) * dy) / max(dx * dx + dy * dy, 1e-12)))
        best = min(best, math.hypot(ax + t * dx - x, ay + t * dy - y))
    return best


def _in_rect(x: float, y: float, poly: list[tuple[float, float]], grow: float) -> bool:
    xs = [p[0] for p in poly]
    ys = [p[1] for p in poly]
    return min(xs) - grow <= x <= max(xs) + grow and min(ys) - grow <= y <= max(ys) + grow


def _people(plan: _Plan, rng: np.random.Generator, count: int) -> list[dict[str, Any]]:
    walkers = []
    for k in range(count if plan.doors else 0):
        dx, dy, axis = plan.doors[int(rng.integers(len(plan.doors)))]
        nx, ny = (1.2, 0.0) if axis == "x" else (0.0, 1.2)
        walkers.append(
            {
                "id": f"person_{k + 1}",
                "route": [[round(dx - nx, 3), round(dy - ny, 3)], [round(dx + nx, 3), round(dy + ny, 3)]],
                "speed": round(float(rng.uniform(0.6, 1.2)), 2),
                "start_time": round(float(rng.uniform(0, 10)), 1),
                "loop": True,
                "pause": 2.0,
                "shirt_rgb": [int(c) for c in rng.integers(30, 220, size=3)],
            }
        )
    return walkers


def _clutter_objects(plan: _Plan, rng: np.random.Generator) -> list[dict[str, Any]]:
    """Chairs, bins, plants and bags beside doors, against the wall, both sides, 0.1-0.3 m from the gap."""
    items = [
        ("chair", "black", (0.5, 0.5, 1.0), "box"),
        ("trash can", "grey", (0.35, 0.35, 0.5), "cylinder"),
        ("potted plant", "green", (0.45, 0.45, 0.9), "cylinder"),
        ("backpack", "blue", (0.32, 0.22, 0.45), "box"),
        ("chair", "blue", (0.45, 0.45, 0.9), "box"),
    ]
    objects: list[dict[str, Any]] = []
    for n, (dx, dy, axis) in enumerate(plan.doors):
        half = next(
            (abs(o[2] - o[0]) + abs(o[3] - o[1])) / 2
            for o in plan.openings
            if abs((o[0] + o[2]) / 2 - dx) < 1e-6 and abs((o[1] + o[3]) / 2 - dy) < 1e-6
        )
        for side in (-1.0, 1.0):
            if rng.random() < 0.35:
                continue
            label, colour, (sx, sy, sz), shape = items[int(rng.integers(len(items)))]
            along = half + float(rng.uniform(0.1, 0.3)) + sx / 2
            off = 0.06 + sy / 2 + 0.05
            normal = float(rng.choice([-1.0, 1.0]))
            x, y = (
                (dx + off * normal, dy + side * along)
                if axis == "x"
                else (dx + side * along, dy + off * normal)
            )
            obj = object_entry(f"door_{n + 1}_{int(side > 0)}", label, colour, shape, (sx, sy, sz), (x, y),
                               f"a {colour} {label} beside a door")
            if label in ("chair",):
                obj["movable"] = True
            objects.append(obj)
    return objects


def _draw_world(
    seed: int, rng: np.random.Generator, people: int
) -> tuple[dict[str, Any], list[dict[str, Any]]]:
    """The world's walls, rooms, start and people, and the clutter to try beside its doors."""
    kind = kind_of(seed)
    plan = _DRAW[kind](rng)
    clutter = _clutter_objects(plan, rng) if plan.clutter else []
    sx, sy = _start(plan, rng)
    walls = _walls(plan)
    rooms = _names(plan)
    data: dict[str, Any] = {
        "name": f"floorplan_{seed}",
        "description": f"Floorplan (seed {seed}, {kind}): {len(rooms)} rooms.",
        "robot": {
            "profile": "turtlebot4",
            "start": {
                "x": round(sx, 3),
                "y": round(sy, 3),
                "yaw": round(float(rng.uniform(-math.pi, math.pi)), 3),
            },
        },
        "walls": {
            "height": 2.5,
            "thickness": 0.1,
            "segments": [[[round(a, 3), round(b, 3)], [round(c, 3), round(d, 3)]] for a, b, c, d in walls],
            "polygons": [[[round(x, 3), round(y, 3)] for x, y in s] for s in plan.solids],
        },
        "rooms": rooms,
        "objects": [],
        # from a generator of their own: the layout and objects do not depend on how many walk
        "people": _people(plan, np.random.default_rng([seed, 1]), people),
    }
    return data, clutter


def floorplan_world(seed: int, people: int = 2, objects: bool = True) -> dict[str, Any]:
    """The floorplan of ``seed`` as world-file data, every room reachable from the start.

    Args:
        seed: Seeds every choice; ``seed % 7`` picks the kind (see the module docstring).
        people: How many people walk through doors.
        objects: Furnish the rooms and place small objects (with decoys).

    Raises:
        WorldFileError: The seed is not a whole number from 0 to MAX_SEED (or, never seen, no
            draw of the seed's kind gave a valid world with every room reachable).
    """
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or not 0 <= seed <= MAX_SEED:
        raise WorldFileError([_seed_problem(f"{FLOORPLAN_PREFIX}{seed}", seed)])
    seed = int(seed)
    rng = np.random.default_rng(seed)
    data: dict[str, Any] = {}
    for _ in range(_ATTEMPTS):
        data, clutter = _draw_world(seed, rng, people)
        try:
            if clutter:
                data = keep_fitting(data, clutter)
            if objects:
                data = place_objects(data, int(rng.integers(2**31)), decoys=True)
            world = build(data)
        except WorldFileError:
            continue
        if not unreachable_rooms(world):
            break
    else:
        raise WorldFileError(
            [
                Problem(
                    f"{FLOORPLAN_PREFIX}{seed}",
                    0,
                    0,
                    "",
                    f"no valid {kind_of(seed)} layout with every room reachable in {_ATTEMPTS} draws",
                    "try another seed",
                )
            ]
        )
    n_obj = len(data.get("objects", []))
    data["description"] = (
        f"Floorplan (seed {seed}, {kind_of(seed)}): {len(data['rooms'])} rooms, {n_obj} objects."
    )
    return data


def _seed_problem(name: str, found: Any) -> Problem:
    return Problem(
        name,
        0,
        0,
        "",
        f"expected `{FLOORPLAN_PREFIX}<seed>` with a whole number from 0 to {MAX_SEED}, found {found!r}",
        "write e.g. floorplan:1003",
    )


def floorplan_document(argument: str) -> tuple[Located, Path]:
    """The world source behind ``floorplan:<seed>``: the floorplan as a located document.

    Raises:
        WorldFileError: The seed is not a whole number from 0 to MAX_SEED.
    """
    name = f"{FLOORPLAN_PREFIX}{argument}"
    if not argument.isdigit() or len(argument) > 19 or int(argument) > MAX_SEED:
        raise WorldFileError([_seed_problem(name, argument)])
    text = yaml.dump(floorplan_world(int(argument)), Dumper=_DUMPER, sort_keys=False)
    return parse_yaml(text, f"<{name}>", error=WorldFileError), Path.cwd() / "floorplan.yaml"


register_world_source(FLOORPLAN_PREFIX, floorplan_document)
_DUMPER = getattr(yaml, "CSafeDumper", yaml.SafeDumper)
