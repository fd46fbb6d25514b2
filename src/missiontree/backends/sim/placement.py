"""Objects placed into any world: furniture against walls, small objects where a robot can find them.

:func:`place_objects` takes world-file data (a generated apartment, a floorplan, or a world drawn on
a map_server map) and returns it with objects added, chosen and placed from one seed:

- **furniture** per room type against the walls (``generator``'s classes, colours and sizes, the only
  ones the shipped detector knows), away from doors;
- **small objects** on open floor, on tables and other low furniture (tops up to 0.8 m, where a
  camera 40 cm high still sees them), against walls and in corners;
- **decoys**: for a small object, one of the same class in another colour and one of the same
  colour of another class, elsewhere.

It works on the world's occupancy grid, so the same code serves drawn walls and real maps: where an
object fits (on free floor, off walls and other objects, doors and corridors kept passable) is
:mod:`~missiontree.backends.sim.placer`'s to decide. A world without rooms (a real map) gets them
from :func:`missiontree.semantics.rooms.segment_rooms`, each given a type.

:func:`map_world` makes a world of a Nav2 map this way; ``load_world("map:depot:4")`` builds one of
the shipped maps (config/worlds/maps) by name and seed, with two people walking.
"""

from __future__ import annotations

import copy
import dataclasses
import hashlib
import math
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import yaml

from missiontree.backends.sim.generator import FURNITURE, SMALL
from missiontree.backends.sim.map_rooms import SEGMENTED_TYPES as SEGMENTED_TYPES
from missiontree.backends.sim.map_rooms import rooms_from_map
from missiontree.backends.sim.mapimage import read_map_image
from missiontree.backends.sim.navigation import INSCRIBED, Costmap, plan
from missiontree.backends.sim.navmap import map_cells
from missiontree.backends.sim.placer import (
    PASS_MARGIN,
    ROBOT_RADIUS,
    Placer,
    box,
    build,
    footprint_window,
    reachable,
    scene_of,
)
from missiontree.backends.sim.schema import NavMapYaml
from missiontree.backends.sim.world import Room, World, load_robot_profile, register_world_source
from missiontree.errors import Problem, WorldFileError
from missiontree.mapping.clearance import clearance_metres
from missiontree.paths import config_dirs
from missiontree.types import Pose2D
from missiontree.yamlio import Located, load_yaml, parse_yaml

#: Furniture for room types the apartment generator does not furnish (same classes as its).
EXTRA_FURNITURE: dict[str, list[tuple[str, str, tuple[float, float, float]]]] = {
    "storage": [("bookshelf", "brown", (1.2, 0.35, 1.9)), ("trash can", "grey", (0.35, 0.35, 0.5))],
    "corridor": [("potted plant", "green", (0.45, 0.45, 0.9)), ("bench", "brown", (1.2, 0.4, 0.45))],
}
#: A room gets one small object of a random class beyond its type's own per this many m².
SMALL_AREA = 40.0
#: Colours small objects and their decoys are drawn from, and those a class comes in when fewer.
DECOY_COLOURS = ["red", "blue", "green", "black", "white", "grey", "yellow", "pink", "silver", "orange"]
CLASS_COLOURS = {"laptop": ["silver", "black", "grey", "white"]}

def colours_for(label: str) -> list[str]:
    """The colours a small object of this class is given (a laptop is not orange)."""
    return CLASS_COLOURS.get(label, DECOY_COLOURS)


def furniture_for(room_type: str) -> list[tuple[str, str, tuple[float, float, float]]]:
    """The furniture (label, colour, size) a room of this type gets."""
    return list(FURNITURE.get(room_type) or EXTRA_FURNITURE.get(room_type) or EXTRA_FURNITURE["storage"])


def small_kinds() -> dict[str, tuple[tuple[float, float, float], str]]:
    """Every small object class of the generator: label -> (size, shape)."""
    kinds: dict[str, tuple[tuple[float, float, float], str]] = {}
    for entries in SMALL.values():
        for label, _colour, size, shape in entries:
            kinds.setdefault(label, (size, shape))
    return kinds


def small_for(room_type: str) -> list[tuple[str, str, tuple[float, float, float], str]]:
    """The small objects (label, colour, size, shape) the generator gives a room of this type."""
    return list(SMALL.get(room_type, []))


MODES = ("floor", "top", "wall", "corner")


def place_objects(
    data: dict[str, Any],
    seed: int,
    *,
    furniture: bool = True,
    small: int = 0,
    decoys: bool = True,
    room_types: bool = True,
    per_room: bool = True,
) -> dict[str, Any]:
    """``data`` with furniture, small objects and decoys added (a copy; ``data`` is not changed).

    Args:
        data: World-file data; a map path in it must be absolute.
        seed: Seeds every choice: the same data and seed give the same objects.
        furniture: Furnish each room by its type, against the walls.
        small: At least this many small objects in all (each room also gets its type's own).
        decoys: Add a same-class and a same-colour decoy for some small objects.
        room_types: Give a world without rooms the rooms found on its map, each with a type.
        per_room: Give each room one or two of its type's small objects (and one more per
            :data:`SMALL_AREA` m²) before ``small`` is made up; without, only ``small`` are added.

    Raises:
        WorldFileError: The data is not a valid world.
    """
    out = copy.deepcopy(data)
    rng = np.random.default_rng(seed)
    world = build(out)
    if not out.get("rooms") and room_types:
        out["rooms"] = rooms_from_map(world, rng)
        # the rooms only, as the loader makes them (building the world again costs a second on a
        # large map, for floor colours placement does not read)
        rooms = [Room(r["name"], r["type"], np.array(r["polygon"], float)) for r in out["rooms"]]
        world = dataclasses.replace(world, rooms=rooms)
    placer = Placer(scene_of(world), rng, {o.id for o in world.objects})
    objects: list[dict[str, Any]] = list(out.get("objects") or [])
    if furniture:
        objects += _furnish(placer, world.rooms)
    placed_small = _small_per_room(placer, world.rooms) if per_room else []
    placed_small += _small_anywhere(placer, len(world.rooms), small, len(placed_small))
    if decoys and world.rooms:
        kinds = small_kinds()
        for target in list(placed_small)[: max(2, len(placed_small) // 4)]:
            placed_small += _decoys(placer, target, kinds, rng, len(world.rooms))
    out["objects"] = objects + placed_small
    return out


def _furnish(placer: Placer, rooms: list[Room]) -> list[dict[str, Any]]:
    """Each room's furniture by its type, round by round.

    Every room's first piece, then every room's second: when space runs out, every room still has
    its main piece.
    """
    placed = []
    lists = [furniture_for(room.type) for room in rooms]
    for k in range(max((len(f) for f in lists), default=0)):
        for i, pieces in enumerate(lists, start=1):
            if k < len(pieces):
                label, colour, size = pieces[k]
                obj = placer.furniture(i, label, colour, size)
                if obj is not None:
                    placed.append(obj)
    return placed


def _small_per_room(placer: Placer, rooms: list[Room]) -> list[dict[str, Any]]:
    """One or two of each room's own small objects, and one of any class per :data:`SMALL_AREA` m²."""
    rng, scene = placer.rng, placer.s
    kinds = small_kinds()
    labels = sorted(kinds)
    areas = np.bincount(scene.rooms.ravel(), minlength=len(rooms) + 1) * scene.grid.resolution**2
    placed = []
    for i, room in enumerate(rooms, start=1):
        own = small_for(room.type)
        take = min(len(own), 1 + int(rng.integers(2)))
        wanted = [own[int(k)] for k in rng.permutation(len(own))[:take]]
        for _ in range(int(areas[i] // SMALL_AREA)):  # large rooms: one more per SMALL_AREA m²
            label = labels[int(rng.integers(len(labels)))]
            size, shape = kinds[label]
            colours = colours_for(label)
            wanted.append((label, colours[int(rng.integers(len(colours)))], size, shape))
        for label, colour, size, shape in wanted:
            obj = placer.small(i, label, colour, size, shape, MODES[int(rng.integers(len(MODES)))])
            if obj is not None:
                placed.append(obj)
    return placed


def _small_anywhere(placer: Placer, room_count: int, small: int, already: int) -> list[dict[str, Any]]:
    """Small objects of random classes and colours in random rooms, until ``small`` are placed in all.

    ``already`` are placed before; at most 20 tries per object asked for.
    """
    rng = placer.rng
    kinds = small_kinds()
    labels = sorted(kinds)
    placed: list[dict[str, Any]] = []
    tries = 0
    while already + len(placed) < small and tries < 20 * max(small, 1) and room_count:
        tries += 1
        label = labels[int(rng.integers(len(labels)))]
        colour = colours_for(label)[int(rng.integers(len(colours_for(label))))]
        size, shape = kinds[label]
        index = int(rng.integers(room_count)) + 1
        obj = placer.small(index, label, colour, size, shape, MODES[int(rng.integers(len(MODES)))])
        if obj is not None:
            placed.append(obj)
    return placed


def keep_fitting(data: dict[str, Any], candidates: list[dict[str, Any]]) -> dict[str, Any]:
    """``data`` with those ``candidates`` (object dicts, in order) that fit, as placed objects do.

    An object fits when it covers only free floor no other object covers, and (reaching below
    0.3 m, an obstacle) every place the robot reached before is still reached with the margin.
    """
    out = copy.deepcopy(data)
    world = build(out)
    placer = Placer(scene_of(world), np.random.default_rng(0), {o.id for o in world.objects})
    kept = []
    for obj in candidates:
        sx, sy, _ = obj["size"]
        pose = obj["pose"]
        if obj.get("shape") == "cylinder":
            a = np.linspace(0, 2 * np.pi, 16, endpoint=False)
            r = sx / 2 + placer.grow
            poly = np.stack([pose["x"] + r * np.cos(a), pose["y"] + r * np.sin(a)], axis=1)
        else:
            poly = box(pose["x"], pose["y"], pose.get("yaw", 0.0), sx, sy, placer.grow)
        foot = placer.fits(poly, obstacle=float(obj.get("elevation", 0.0)) < 0.3)
        if foot is not None and obj["id"] not in placer.ids:
            placer.commit(foot)
            placer.ids.add(obj["id"])
            kept.append(obj)
    out["objects"] = list(out.get("objects") or []) + kept
    return out


def _decoys(
    placer: Placer,
    target: dict[str, Any],
    kinds: dict[str, tuple[tuple[float, float, float], str]],
    rng: np.random.Generator,
    room_count: int,
) -> list[dict[str, Any]]:
    """A same-class decoy in another colour and a same-colour decoy of another class."""
    found: list[dict[str, Any]] = []
    colours = [c for c in colours_for(target["label"]) if c != target["color"]]
    others = [
        label for label in sorted(kinds) if label != target["label"] and target["color"] in colours_for(label)
    ]
    pairs = []
    if colours:
        pairs.append((target["label"], colours[int(rng.integers(len(colours)))]))
    if others:
        pairs.append((others[int(rng.integers(len(others)))], target["color"]))
    for label, colour in pairs:
        size, shape = kinds[label]
        for _ in range(4):
            room = int(rng.integers(room_count)) + 1
            obj = placer.small(room, label, colour, size, shape, MODES[int(rng.integers(len(MODES)))])
            if obj is not None:
                found.append(obj)
                break
    return found


def unreachable_rooms(world: World) -> list[str]:
    """Names of the rooms the robot cannot reach from its start, judged by the planner's costmap.

    A room counts as reached when the free cells (costmap below inscribed) connected to the start
    hold a piece of it at least a robot's footprint across, and the planner finds a path there.
    """
    profile = load_robot_profile(world.profile_name)
    costmap = Costmap(world.grid, profile.body.radius, profile.navigation)
    free = costmap.cost < INSCRIBED
    start = world.grid.world_to_cell(world.start.x, world.start.y)
    reach = reachable(free, start)
    clear = cv2.distanceTransform(reach.astype(np.uint8), cv2.DIST_L2, 3)
    missing: list[str] = []
    shape = world.grid.data.shape
    for room in world.rooms:
        mask, (rows, cols) = footprint_window(shape, world.grid, room.polygon)  # the room's box only
        inside = mask & reach[rows, cols]
        if not inside.any():
            missing.append(room.name)
            continue
        score = np.where(inside, clear[rows, cols], -1.0)  # the first best cell, as on the whole map
        row, col = np.unravel_index(int(np.argmax(score)), inside.shape)
        row, col = row + rows.start, col + cols.start
        gx, gy = world.grid.cell_to_world(int(row), int(col))
        if plan(costmap, costmap.cost, world.start, Pose2D(gx, gy)) is None:
            missing.append(room.name)
    return missing


def _map_cells(map_yaml: Path) -> tuple[np.ndarray, float, tuple[float, float]]:
    """Occupancy values of a Nav2 map yaml's image (row 0 = lowest y), resolution, origin (x, y)."""
    meta = NavMapYaml.model_validate(load_yaml(map_yaml, error=WorldFileError).data)
    image = read_map_image((map_yaml.parent / meta.image).resolve())
    return map_cells(image, meta), meta.resolution, (meta.origin[0], meta.origin[1])


def map_start(map_yaml: Path, rng: np.random.Generator, clearance: float = 0.5) -> tuple[float, float, float]:
    """A start point on a map, and the area (m²) it reaches.

    The point lies on known free floor ``clearance`` from anything, in the map's largest piece of
    floor a robot can drive (with :data:`PASS_MARGIN`); the area is that piece's.
    """
    cells, res, (ox, oy) = _map_cells(map_yaml)
    free = cells == 0
    dist = clearance_metres(free, res)
    ok = dist > ROBOT_RADIUS + PASS_MARGIN
    count, comp = cv2.connectedComponents(ok.astype(np.uint8), connectivity=8)
    sizes = np.bincount(comp.ravel(), minlength=count)
    sizes[0] = 0
    piece = comp == int(sizes.argmax())
    rows, cols = np.nonzero(piece & (dist >= clearance))
    if not len(rows):
        rows, cols = np.nonzero(piece)
    k = int(rng.integers(len(rows)))
    area = float(piece.sum()) * res * res
    return float(ox + (cols[k] + 0.5) * res), float(oy + (rows[k] + 0.5) * res), area


_WORLDS: dict[tuple[Any, ...], dict[str, Any]] = {}


def map_world(
    map_yaml: Path, seed: int, *, name: str | None = None, small: int = 0, people: int = 0
) -> dict[str, Any]:
    """A world on a Nav2 map (absolute path kept): seeded start, rooms found and typed, objects placed.

    Kept for the process, keyed by the map files' bytes and the arguments: a run's preflight check
    and its robot load the same world (about 20 s of CPU each on MRPT's whole Malaga campus).

    Raises:
        WorldFileError: The map cannot be read as a world.
    """
    map_yaml = Path(map_yaml).resolve()
    meta = NavMapYaml.model_validate(load_yaml(map_yaml, error=WorldFileError).data)
    try:
        digest = hashlib.sha1(map_yaml.read_bytes() + (map_yaml.parent / meta.image).resolve().read_bytes())
    except OSError:  # the build says what is wrong with the map
        return _map_world(map_yaml, seed, name, small, people)
    key = (str(map_yaml), digest.hexdigest(), seed, name, small, people)
    if key not in _WORLDS:
        if len(_WORLDS) > 8:
            _WORLDS.clear()
        _WORLDS[key] = _map_world(map_yaml, seed, name, small, people)
    return copy.deepcopy(_WORLDS[key])


def _map_world(map_yaml: Path, seed: int, name: str | None, small: int, people: int) -> dict[str, Any]:
    rng = np.random.default_rng(seed)
    x, y, area = map_start(map_yaml, rng)
    label = name or f"{map_yaml.stem}_{seed}"
    data: dict[str, Any] = {
        "name": label,
        "description": f"Real map {map_yaml.stem} with objects placed (seed {seed}).",
        "robot": {
            "profile": "turtlebot4",
            "start": {
                "x": round(x, 3),
                "y": round(y, 3),
                "yaw": round(float(rng.uniform(-math.pi, math.pi)), 3),
            },
        },
        "map": {"yaml": str(map_yaml), "height": 2.5},
        "rooms": [],
        "objects": [],
        "people": [],
    }
    # about one small object per 25 m² of floor the robot reaches (4 to 30), or as many as asked
    data = place_objects(data, int(rng.integers(2**31)), small=max(small, min(30, 4 + int(area / 25))))
    world = build(data)
    missing = set(unreachable_rooms(world))
    if missing:  # a piece of floor the segmentation kept but the robot cannot drive to
        data["rooms"] = [r for r in data["rooms"] if r["name"] not in missing]
        # the walkers read the rooms only, not the floor colours a second build would repaint
        world = dataclasses.replace(world, rooms=[r for r in world.rooms if r.name not in missing])
    if people:
        data["people"] = walkers(world, rng, people)
    return data


def walkers(world: World, rng: np.random.Generator, count: int) -> list[dict[str, Any]]:
    """People walking to and fro on straight lines of open floor (0.35 m from anything) the robot reaches."""
    scene = scene_of(world)
    res = scene.grid.resolution
    dist = clearance_metres(~scene.blocked, res)
    cells = np.argwhere(scene.reach & (dist >= 0.45))
    found: list[dict[str, Any]] = []
    for k in range(count):
        for _ in range(200):
            if not len(cells):
                break
            r0, c0 = cells[int(rng.integers(len(cells)))]
            r1, c1 = cells[int(rng.integers(len(cells)))]
            length = math.hypot(float(r1 - r0), float(c1 - c0)) * res
            if not 2.0 <= length <= 8.0:
                continue
            steps = int(length / res) + 1
            rr = np.linspace(r0, r1, steps).round().astype(int)
            cc = np.linspace(c0, c1, steps).round().astype(int)
            if (dist[rr, cc] < 0.35).any():
                continue
            a, b = scene.point(int(r0), int(c0)), scene.point(int(r1), int(c1))
            found.append(
                {
                    "id": f"person_{k + 1}",
                    "route": [[round(a[0], 3), round(a[1], 3)], [round(b[0], 3), round(b[1], 3)]],
                    "speed": round(float(rng.uniform(0.6, 1.2)), 2),
                    "start_time": round(float(rng.uniform(0, 10)), 1),
                    "loop": True,
                    "pause": 2.0,
                    "shirt_rgb": [int(c) for c in rng.integers(30, 220, size=3)],
                }
            )
            break
    return found


#: World names of this form are shipped real maps with placed objects: ``map:depot:4``.
MAP_PREFIX = "map:"


def shipped_map(name: str) -> Path:
    """The Nav2 map yaml ``worlds/maps/<name>.yaml`` of the configuration folders, absolute.

    Raises:
        FileNotFoundError: No configuration folder holds it (the message names the ones that exist).
    """
    if name and all(c.isalnum() or c in "_-" for c in name):
        for folder in config_dirs():
            candidate = folder / "worlds" / "maps" / f"{name}.yaml"
            if candidate.is_file():
                return candidate.resolve()
    known = sorted({p.stem for d in config_dirs() for p in (d / "worlds" / "maps").glob("*.yaml")})
    raise FileNotFoundError(f"expected a map of worlds/maps ({', '.join(known)}), found {name!r}")


def map_document(argument: str) -> tuple[Located, Path]:
    """The world source behind ``map:<name>:<seed>``: :func:`map_world` of a shipped map, two walkers.

    Raises:
        WorldFileError: Not ``<name>:<seed>`` with a shipped map and a whole-number seed.
    """
    name, _, seed = argument.rpartition(":")
    hint = "write e.g. map:depot:4 (a map of config/worlds/maps and a seed)"
    if not seed.isdigit() or len(seed) > 18:
        raise WorldFileError(
            [
                Problem(
                    f"{MAP_PREFIX}{argument}",
                    0,
                    0,
                    "",
                    f"expected `map:<name>:<seed>` with a whole-number seed, found {argument!r}",
                    hint,
                )
            ]
        )
    try:
        path = shipped_map(name)
    except FileNotFoundError as exc:
        raise WorldFileError([Problem(f"{MAP_PREFIX}{argument}", 0, 0, "", str(exc), hint)]) from None
    data = map_world(path, int(seed), name=f"map_{name}_{seed}", people=2)
    text = yaml.dump(data, Dumper=getattr(yaml, "CSafeDumper", yaml.SafeDumper), sort_keys=False)
    return parse_yaml(
        text, f"<{MAP_PREFIX}{argument}>", error=WorldFileError
    ), path.parent / f"{data['name']}.yaml"


register_world_source(MAP_PREFIX, map_document)
