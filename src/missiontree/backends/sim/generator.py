"""Seeded apartment-like worlds for batch evaluation: rooms, doors, furniture, objects, people.

``generate_world(seed)`` returns the world as world-file data (the same format as
config/worlds/*.yaml, so it goes through the same checks); ``load_world("generated:42")`` and
``create_robot({"world": "generated:42"})`` build it directly, and ``write_world_file`` saves it
for inspection. The layout splits a rectangle recursively into rooms (binary space partition);
every split wall gets one door, so all rooms connect. Large furniture stands against walls and
away from doors, small objects lie on the floor or on low furniture where a camera 40 cm high can
see them (the NAIS paper), and the start pose is in free space. Everything random comes from one
``numpy.random.Generator`` seeded with ``seed``: the same seed gives the same world.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from missiontree.backends.sim.navigation import INSCRIBED, Costmap, plan
from missiontree.backends.sim.world import build_world, load_robot_profile, register_world_source
from missiontree.errors import WorldFileError
from missiontree.types import Pose2D
from missiontree.yamlio import Located, parse_yaml

#: World names of this form are generated apartments: ``generated:42``.
GENERATED_PREFIX = "generated:"
#: Largest seed accepted (numpy seeds are non-negative; this keeps names short).
MAX_SEED = 2**63 - 1

#: Room types in the order they are handed out, and what furnishes each.
ROOM_TYPES = ["kitchen", "living room", "office", "bedroom", "bathroom", "hall"]
FURNITURE: dict[str, list[tuple[str, str, tuple[float, float, float]]]] = {
    "kitchen": [
        ("refrigerator", "white", (0.7, 0.7, 1.8)),
        ("counter", "wood", (1.6, 0.6, 0.9)),
        ("sink", "silver", (0.6, 0.5, 0.92)),
        ("dining table", "wood", (1.2, 0.8, 0.75)),
    ],
    "living room": [
        ("sofa", "grey", (1.9, 0.9, 0.8)),
        ("tv", "black", (1.1, 0.4, 0.6)),
        ("table", "wood", (0.9, 0.6, 0.4)),
        ("potted plant", "green", (0.45, 0.45, 0.9)),
    ],
    "office": [
        ("desk", "white", (1.4, 0.7, 0.75)),
        ("bookshelf", "brown", (1.2, 0.35, 1.9)),
        ("chair", "black", (0.5, 0.5, 1.0)),
    ],
    "bedroom": [
        ("bed", "beige", (1.6, 2.0, 0.5)),
        ("wardrobe", "wood", (1.2, 0.6, 2.0)),
        ("chair", "blue", (0.45, 0.45, 0.9)),
    ],
    "bathroom": [("sink", "white", (0.6, 0.5, 0.9)), ("trash can", "grey", (0.35, 0.35, 0.5))],
    "hall": [("bench", "brown", (1.2, 0.4, 0.45)), ("potted plant", "green", (0.45, 0.45, 0.9))],
}
#: Small objects (label, colour, size, shape) each room type gets; placement draws from the same classes.
SMALL: dict[str, list[tuple[str, str, tuple[float, float, float], str]]] = {
    "kitchen": [
        ("bottle", "pink", (0.08, 0.08, 0.25), "cylinder"),
        ("cup", "red", (0.09, 0.09, 0.11), "cylinder"),
        ("bottle", "green", (0.08, 0.08, 0.3), "cylinder"),
        ("cup", "white", (0.09, 0.09, 0.11), "cylinder"),
    ],
    "living room": [
        ("laptop", "silver", (0.34, 0.25, 0.22), "box"),
        ("umbrella", "black", (0.1, 0.1, 0.9), "cylinder"),
        ("backpack", "red", (0.32, 0.22, 0.45), "box"),
    ],
    "office": [
        ("backpack", "grey", (0.32, 0.22, 0.45), "box"),
        ("laptop", "silver", (0.34, 0.25, 0.22), "box"),
        ("bottle", "blue", (0.07, 0.07, 0.22), "cylinder"),
    ],
    "bedroom": [
        ("backpack", "blue", (0.32, 0.22, 0.45), "box"),
        ("umbrella", "red", (0.1, 0.1, 0.9), "cylinder"),
    ],
    "bathroom": [("bottle", "white", (0.07, 0.07, 0.2), "cylinder")],
    "hall": [
        ("umbrella", "blue", (0.1, 0.1, 0.9), "cylinder"),
        ("backpack", "green", (0.32, 0.22, 0.45), "box"),
    ],
}
_MIN_ROOM = 2.6
_DOOR = 0.95
_WALL_GAP = 0.03
_ATTEMPTS = 20


@dataclass
class _Rect:
    x0: float
    y0: float
    x1: float
    y1: float

    @property
    def w(self) -> float:
        return self.x1 - self.x0

    @property
    def h(self) -> float:
        return self.y1 - self.y0


def generate_world(
    seed: int, rooms: int = 5, people: int = 2, size: tuple[float, float] | None = None
) -> dict[str, Any]:
    """An apartment-like world as world-file data, every room reachable from the start.

    Layouts whose furniture cuts a room off are drawn again (from the same generator, so the
    result still depends on the seed alone).

    Args:
        seed: Seeds every random choice.
        rooms: About how many rooms (the partition stops early when rooms would get too small).
        people: How many people walk between rooms.
        size: (width, height) of the apartment in metres; drawn from the seed when None.
    """
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or not 0 <= seed <= MAX_SEED:
        raise WorldFileError([_seed_problem(f"{GENERATED_PREFIX}{seed}", seed)])
    rng = np.random.default_rng(seed)
    data: dict[str, Any] = {}
    for _ in range(_ATTEMPTS):
        data = _draw(rng, seed, rooms, people, size)
        if _all_rooms_reachable(data):
            break
    return data


def _all_rooms_reachable(data: dict[str, Any]) -> bool:
    """Plan from the start to a free point of every room on the world's costmap."""
    try:
        world = build_world(
            parse_yaml(yaml.safe_dump(data), "<generated>", error=WorldFileError),
            Path.cwd() / "generated.yaml",
        )
    except WorldFileError:
        return False
    profile = load_robot_profile(world.profile_name)
    costmap = Costmap(world.grid, profile.body.radius, profile.navigation)
    free = costmap.cost < INSCRIBED
    for room in world.rooms:
        x0, y0 = room.polygon.min(axis=0)
        x1, y1 = room.polygon.max(axis=0)
        r0, c0 = world.grid.world_to_cell(x0, y0)
        r1, c1 = world.grid.world_to_cell(x1, y1)
        rows, cols = np.nonzero(free[r0:r1, c0:c1])
        if not len(rows):
            return False
        mid = len(rows) // 2
        gx, gy = world.grid.cell_to_world(int(rows[mid] + r0), int(cols[mid] + c0))
        if plan(costmap, costmap.cost, world.start, Pose2D(gx, gy)) is None:
            return False
    return True


def _draw(
    rng: np.random.Generator, seed: int, rooms: int, people: int, size: tuple[float, float] | None
) -> dict[str, Any]:
    width, height = (
        size if size is not None else (float(rng.uniform(9.0, 13.0)), float(rng.uniform(7.0, 10.0)))
    )
    leaves, walls, doors = _partition(_Rect(0.0, 0.0, width, height), rooms, rng)
    types = [ROOM_TYPES[i % len(ROOM_TYPES)] for i in range(len(leaves))]
    order = rng.permutation(len(leaves))
    room_data: list[Any] = []
    objects: list[Any] = []
    placed: list[Any] = []
    for n, i in enumerate(order):
        rect, kind = leaves[i], types[n]
        room_data.append(
            {
                "name": f"{kind} {n + 1}",
                "type": kind,
                "polygon": [[rect.x0, rect.y0], [rect.x1, rect.y0], [rect.x1, rect.y1], [rect.x0, rect.y1]],
            }
        )
        objects += _furnish(rect, kind, doors, placed, rng, len(objects))
    start_rect = leaves[order[0]]
    start = _free_point(start_rect, placed, doors, rng, clearance=0.45)
    walkers = []
    for k in range(people if doors else 0):
        dx, dy, axis = doors[int(rng.integers(len(doors)))]
        nx, ny = (1.2, 0.0) if axis == "x" else (0.0, 1.2)
        route = [[round(dx - nx, 3), round(dy - ny, 3)], [round(dx + nx, 3), round(dy + ny, 3)]]
        walkers.append(
            {
                "id": f"person_{k + 1}",
                "route": route,
                "speed": round(float(rng.uniform(0.6, 1.2)), 2),
                "start_time": round(float(rng.uniform(0, 10)), 1),
                "loop": True,
                "pause": 2.0,
                "shirt_rgb": [int(c) for c in rng.integers(30, 220, size=3)],
            }
        )
    return {
        "name": f"generated_{seed}",
        "description": f"Generated apartment (seed {seed}): {len(leaves)} rooms, {len(objects)} objects.",
        "robot": {
            "profile": "turtlebot4",
            "start": {
                "x": round(start[0], 3),
                "y": round(start[1], 3),
                "yaw": round(float(rng.uniform(-math.pi, math.pi)), 3),
            },
        },
        "walls": {
            "height": 2.5,
            "thickness": 0.1,
            "segments": [[[round(a, 3), round(b, 3)], [round(c, 3), round(d, 3)]] for a, b, c, d in walls],
        },
        "rooms": room_data,
        "objects": objects,
        "people": walkers,
    }


def _seed_problem(name: str, found: Any) -> Any:
    from missiontree.errors import Problem

    return Problem(name, 0, 0, "", f"expected `{GENERATED_PREFIX}<seed>` with a whole number from 0 to "
                   f"{MAX_SEED}, found {found!r}", "write e.g. generated:42")


def generated_document(argument: str) -> tuple[Located, Path]:
    """The world source behind ``generated:<seed>``: the generated world as a located document.

    Raises:
        WorldFileError: The seed is not a whole number from 0 to :data:`MAX_SEED`.
    """
    name = f"{GENERATED_PREFIX}{argument}"
    if not argument.isdigit() or len(argument) > 19 or int(argument) > MAX_SEED:
        raise WorldFileError([_seed_problem(name, argument)])
    text = yaml.safe_dump(generate_world(int(argument)), sort_keys=False)
    return parse_yaml(text, f"<{name}>", error=WorldFileError), Path.cwd() / "generated.yaml"


register_world_source(GENERATED_PREFIX, generated_document)


def write_world_file(seed: int, path: str | Path, **kwargs: Any) -> Path:
    """Write ``generate_world(seed, **kwargs)`` as a world file and return its path."""
    path = Path(path)
    path.write_text(
        f"# generated by missiontree.backends.sim.generator (seed {seed})\n"
        + yaml.safe_dump(generate_world(seed, **kwargs), sort_keys=False)
    )
    return path


def _partition(
    outer: _Rect, rooms: int, rng: np.random.Generator
) -> tuple[list[_Rect], list[tuple], list[tuple]]:
    """Split ``outer`` into up to ``rooms`` rooms; walls (segments) with a door gap in every split."""
    leaves = [outer]
    doors: list[tuple[float, float, str]] = []  # door centre x, y and the wall's axis
    walls: list[tuple[float, float, float, float]] = [
        (outer.x0, outer.y0, outer.x1, outer.y0),
        (outer.x1, outer.y0, outer.x1, outer.y1),
        (outer.x1, outer.y1, outer.x0, outer.y1),
        (outer.x0, outer.y1, outer.x0, outer.y0),
    ]
    while len(leaves) < rooms:
        candidates = [r for r in leaves if max(r.w, r.h) >= 2 * _MIN_ROOM]
        if not candidates:
            break
        rect = max(candidates, key=lambda r: r.w * r.h)
        leaves.remove(rect)
        vertical = rect.w >= rect.h
        span = rect.w if vertical else rect.h
        cut = float(rng.uniform(_MIN_ROOM, span - _MIN_ROOM))
        length = rect.h if vertical else rect.w
        door = float(rng.uniform(0.3 + _DOOR / 2, length - 0.3 - _DOOR / 2))
        if vertical:
            x = rect.x0 + cut
            leaves += [_Rect(rect.x0, rect.y0, x, rect.y1), _Rect(x, rect.y0, rect.x1, rect.y1)]
            y = rect.y0 + door
            walls += [(x, rect.y0, x, y - _DOOR / 2), (x, y + _DOOR / 2, x, rect.y1)]
            doors.append((x, y, "x"))
        else:
            y = rect.y0 + cut
            leaves += [_Rect(rect.x0, rect.y0, rect.x1, y), _Rect(rect.x0, y, rect.x1, rect.y1)]
            x = rect.x0 + door
            walls += [(rect.x0, y, x - _DOOR / 2, y), (x + _DOOR / 2, y, rect.x1, y)]
            doors.append((x, y, "y"))
    return leaves, walls, doors


def _near_door(x: float, y: float, doors: list[tuple[float, float, str]], radius: float) -> bool:
    return any(math.hypot(x - dx, y - dy) < radius for dx, dy, _ in doors)


def _overlaps(
    box: tuple[float, float, float, float], placed: list[tuple[float, float, float, float]]
) -> bool:
    x0, y0, x1, y1 = box
    return any(x0 < b[2] and b[0] < x1 and y0 < b[3] and b[1] < y1 for b in placed)


def _furnish(
    rect: _Rect,
    kind: str,
    doors: list[tuple[float, float, str]],
    placed: list[tuple[float, float, float, float]],
    rng: np.random.Generator,
    count: int,
) -> list[dict[str, Any]]:
    """Large furniture against the walls, then small objects on the floor."""
    objects: list[dict[str, Any]] = []
    for label, colour, (sx, sy, sz) in FURNITURE[kind]:
        for _ in range(30):
            side = int(rng.integers(4))
            along_x = side in (0, 2)
            w, d = (sx, sy) if along_x else (sy, sx)
            if along_x:
                x = float(
                    rng.uniform(rect.x0 + w / 2 + 0.1, max(rect.x0 + w / 2 + 0.1, rect.x1 - w / 2 - 0.1))
                )
                y = rect.y0 + d / 2 + _WALL_GAP + 0.05 if side == 0 else rect.y1 - d / 2 - _WALL_GAP - 0.05
            else:
                y = float(
                    rng.uniform(rect.y0 + d / 2 + 0.1, max(rect.y0 + d / 2 + 0.1, rect.y1 - d / 2 - 0.1))
                )
                x = rect.x0 + w / 2 + _WALL_GAP + 0.05 if side == 3 else rect.x1 - w / 2 - _WALL_GAP - 0.05
            box = (x - w / 2 - 0.05, y - d / 2 - 0.05, x + w / 2 + 0.05, y + d / 2 + 0.05)
            if _near_door(x, y, doors, 1.0 + max(w, d) / 2) or _overlaps(box, placed):
                continue
            if not (rect.x0 < box[0] and box[2] < rect.x1 and rect.y0 < box[1] and box[3] < rect.y1):
                continue
            placed.append(box)
            yaw = 0.0 if along_x else math.pi / 2
            objects.append(
                {
                    "id": f"{label.replace(' ', '_')}_{count + len(objects) + 1}",
                    "label": label,
                    "color": colour,
                    "size": [sx, sy, sz],
                    "pose": {"x": round(x, 3), "y": round(y, 3), "yaw": round(yaw, 4)},
                    "movable": False,
                }
            )
            break
    for label, colour, (sx, sy, sz), shape in SMALL[kind]:
        x, y = _free_point(rect, placed, doors, rng, clearance=0.25, door_gap=1.2)
        placed.append((x - sx / 2, y - sy / 2, x + sx / 2, y + sy / 2))
        objects.append(object_entry(f"{count + len(objects) + 1}", label, colour, shape, (sx, sy, sz), (x, y),
                                    f"a {colour} {label} on the floor of the {kind}"))
    return objects


def object_entry(suffix: str, label: str, colour: str, shape: str, size: tuple[float, float, float],
                 xy: tuple[float, float], description: str) -> dict[str, Any]:
    """A world file's object standing on the floor at ``xy`` (rounded to mm), id ``<label>_<suffix>``.

    The one shape of entry the generated apartments and the floorplans write for a loose object.
    """
    return {
        "id": f"{label.replace(' ', '_')}_{suffix}",
        "label": label,
        "color": colour,
        "shape": shape,
        "size": list(size),
        "pose": {"x": round(xy[0], 3), "y": round(xy[1], 3)},
        "description": description,
    }


def _free_point(
    rect: _Rect,
    placed: list[tuple[float, float, float, float]],
    doors: list[tuple[float, float, str]],
    rng: np.random.Generator,
    clearance: float,
    door_gap: float = 0.7,
) -> tuple[float, float]:
    """A point in ``rect`` at least ``clearance`` from its walls, the furniture and the doors."""
    margin = clearance + 0.1
    for _ in range(200):
        x = float(rng.uniform(rect.x0 + margin, rect.x1 - margin))
        y = float(rng.uniform(rect.y0 + margin, rect.y1 - margin))
        box = (x - clearance, y - clearance, x + clearance, y + clearance)
        if not _overlaps(box, placed) and not _near_door(x, y, doors, door_gap):
            return x, y
    return (rect.x0 + rect.x1) / 2, (rect.y0 + rect.y1) / 2
