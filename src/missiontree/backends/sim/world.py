"""The simulated world: loading and checking world files and robot profiles, and the runtime model.

:func:`load_world` reads a world file (a shipped name such as ``office`` or a path), checks it
whole and raises :class:`~missiontree.errors.WorldFileError` with every problem as
``file:line:col`` — unknown keys, missing fields, an object inside a wall, a robot starting
inside a wall, an unknown robot profile, a map image that does not exist. The result is a
:class:`World`: walls and objects as prisms for the sensors, a static occupancy grid for the
planner, rooms, people and the instance table ground truth uses.

Inputs are checked where they enter (docs/worlds.md lists the limits): every number finite and in
range (the schema), the grid a world needs no larger than ``MAX_MAP_CELLS`` (computed before it is
allocated), a map yaml and image inside the world's folder or ``$MISSIONTREE_MAP_PATH``, read with
size bounds and never echoed. Names such as ``generated:42`` come from world sources registered
with :func:`register_world_source` (the generator registers itself), so this module imports no
generator.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pydantic

from missiontree.backends.sim.mapimage import MAX_MAP_CELLS
from missiontree.backends.sim.navmap import contour_segments, read_nav2_map, resolve_reference
from missiontree.backends.sim.patterns import pattern_for
from missiontree.backends.sim.people import Crowd, Person
from missiontree.backends.sim.raycast import BOX, CYLINDER, SEGMENT, Primitives, Row
from missiontree.backends.sim.robot_profiles import load_robot_profile as load_robot_profile  # re-exported
from missiontree.backends.sim.robot_profiles import profile_problems
from missiontree.backends.sim.robot_profiles import validate_model as _validate
from missiontree.backends.sim.schema import (
    ObjectSpec,
    WorldSpec,
)
from missiontree.errors import ConfigError, Problem, WorldFileError
from missiontree.mapping.occupancy import BLOCKED_FROM
from missiontree.paths import find_config
from missiontree.types import OccupancyGrid, Pose2D
from missiontree.yamlio import Located, load_yaml

#: Instance ids: 0 is floor and ceiling, 1 every wall; objects and people follow.
FLOOR_INSTANCE, WALL_INSTANCE = 0, 1
#: Objects reaching below this height block the robot unless the file says otherwise.
OBSTACLE_BELOW = 0.3
_CONTACT_SLACK = 0.02

#: A world source: turns the text after its prefix (``42`` of ``generated:42``) into a located
#: world document and the path its relative references resolve against.
WorldSource = Callable[[str], tuple[Located, Path]]
_SOURCES: dict[str, WorldSource] = {}


def register_world_source(prefix: str, source: WorldSource) -> None:
    """Let :func:`load_world` build worlds named ``<prefix><argument>`` (e.g. ``generated:42``).

    The generator registers ``generated:`` this way, so this module never imports it (a world
    source sits above the loader, not beside it).
    """
    _SOURCES[prefix] = source


@dataclass(frozen=True)
class InstanceInfo:
    """What an instance id in a mask stands for."""

    inst: int
    kind: str  # "wall", "object" or "person"
    name: str
    label: str


@dataclass(frozen=True)
class WorldObject:
    """An object as placed in the world."""

    id: str
    label: str
    color: str
    rgb: tuple[int, int, int]
    attributes: tuple[str, ...]
    description: str
    shape: str
    size: tuple[float, float, float]
    pose: Pose2D
    elevation: float
    movable: bool
    obstacle: bool
    inst: int
    pattern: int = 0

    @property
    def top(self) -> float:
        """Height of the object's top above the floor."""
        return self.elevation + self.size[2]

    def footprint(self) -> np.ndarray:
        """Corners (box) or a 24-gon (cylinder) of the object's outline, shape (N, 2)."""
        if self.shape == "cylinder":
            a = np.linspace(0, 2 * np.pi, 24, endpoint=False)
            r = self.size[0] / 2
            return np.stack([self.pose.x + r * np.cos(a), self.pose.y + r * np.sin(a)], axis=1)
        hx, hy = self.size[0] / 2, self.size[1] / 2
        corners = ((hx, hy), (-hx, hy), (-hx, -hy), (hx, -hy))
        return np.array([self.pose.transform(px, py) for px, py in corners])


@dataclass(frozen=True)
class Room:
    """A named room polygon."""

    name: str
    type: str
    polygon: np.ndarray
    floor_rgb: tuple[int, int, int] | None = None

    def contains(self, x: float, y: float) -> bool:
        """Whether the point lies inside the polygon."""
        return cv2.pointPolygonTest(self.polygon.astype(np.float32), (float(x), float(y)), False) >= 0


@dataclass
class World:
    """A loaded world: geometry for the sensors, a grid for the planner, rooms, objects, people."""

    name: str
    source: str
    spec: WorldSpec
    start: Pose2D
    profile_name: str
    wall_segments: np.ndarray            # (S, 4) x1, y1, x2, y2
    static: Primitives                   # walls and objects
    grid: OccupancyGrid                  # static obstacles (walls and obstacle objects), 0 / 100
    walls_grid: np.ndarray               # bool, walls only
    rooms: list[Room]
    objects: list[WorldObject]
    crowd: Crowd
    instances: dict[int, InstanceInfo]
    ceiling: float
    floor_rgb: np.ndarray                # (rows, cols, 3) floor colour per grid cell
    _clearance: np.ndarray = field(repr=False, default_factory=lambda: np.zeros((0, 0)))

    def clearance(self, x: float, y: float) -> float:
        """Distance (m) from (x, y) to the nearest static obstacle cell; 0 outside the grid."""
        row, col = self.grid.world_to_cell(x, y)
        h, w = self._clearance.shape
        if not (0 <= row < h and 0 <= col < w):
            return 0.0
        return float(self._clearance[row, col])

    def room_at(self, x: float, y: float) -> Room | None:
        """The first room whose polygon holds (x, y)."""
        for room in self.rooms:
            if room.contains(x, y):
                return room
        return None

    def object(self, object_id: str) -> WorldObject:
        """The object with this id (KeyError naming the known ones otherwise)."""
        for obj in self.objects:
            if obj.id == object_id:
                return obj
        raise KeyError(f"no object {object_id!r}; known: {', '.join(o.id for o in self.objects)}")

    def bounds(self) -> tuple[float, float, float, float]:
        """(xmin, ymin, xmax, ymax) of the grid."""
        h, w = self.grid.data.shape
        r = self.grid.resolution
        return self.grid.origin.x, self.grid.origin.y, self.grid.origin.x + w * r, self.grid.origin.y + h * r


# -- loading -----------------------------------------------------------------------------------


def load_world(name_or_path: str | Path) -> World:
    """Load and check a world file; a shipped name (``office``), a path, or a registered source.

    Raises:
        WorldFileError: Every problem found, each with file:line:col.
    """
    text = str(name_or_path)
    for prefix, source in _SOURCES.items():
        if text.startswith(prefix):
            doc, path = source(text[len(prefix):])
            return build_world(doc, path)
    try:
        path = find_config("worlds", name_or_path)
    except ConfigError as exc:
        raise WorldFileError([Problem(text, 0, 0, "", str(exc))]) from None
    return build_world(load_yaml(path, error=WorldFileError), path)


def build_world(doc: Located, path: Path) -> World:
    """Check a located world document whole and build the world.

    Args:
        doc: The world file as read by :func:`missiontree.yamlio.load_yaml`.
        path: The world file; ``map: {yaml: ...}`` resolves against its folder.

    Raises:
        WorldFileError: Every problem found, each with file:line:col.
    """
    try:
        spec = _validate(doc, WorldSpec)
    except WorldFileError as exc:
        # report what can be checked without a valid file together with the schema problems: the
        # profile, the map reference, and the geometry of everything that is valid on its own
        raise WorldFileError(exc.problems + profile_problems(doc) + _lenient_geometry(doc, path)) from None
    problems = profile_problems(doc)
    world = _build(spec, doc, path, problems)
    if problems:
        raise WorldFileError(problems)
    assert world is not None
    return world


def _lenient_geometry(doc: Located, path: Path) -> list[Problem]:
    """Geometric problems of a world whose schema failed, found on the file without its broken parts.

    Unknown keys are left out and broken objects, people and rooms dropped; if the rest is a valid
    world, it is built so objects in walls, routes through walls and a blocked start are reported
    in the same run as the schema mistakes. Otherwise only the map reference is checked.
    """
    if not isinstance(doc.data, dict):
        return []
    data = copy.deepcopy(doc.data)
    dropped: dict[str, set[int]] = {"objects": set(), "people": set(), "rooms": set()}
    try:
        WorldSpec.model_validate(data)
        return []
    except pydantic.ValidationError as exc:
        for err in exc.errors():
            loc = err["loc"]
            if len(loc) >= 2 and loc[0] in dropped and isinstance(loc[1], int):
                dropped[str(loc[0])].add(loc[1])
            elif err["type"] == "extra_forbidden" and not _remove_key(data, loc):
                return _map_reference_problems(doc, path)
            elif err["type"] != "extra_forbidden":
                return _map_reference_problems(doc, path)
    kept: dict[str, list[int]] = {}
    for key, bad in dropped.items():
        items = data.get(key)
        if isinstance(items, list):
            kept[key] = [i for i in range(len(items)) if i not in bad]
            data[key] = [items[i] for i in kept[key]]
    try:
        spec = WorldSpec.model_validate(data)
    except pydantic.ValidationError:
        return _map_reference_problems(doc, path)
    problems: list[Problem] = []
    _build(spec, doc, path, problems, kept)
    return problems


def _remove_key(data: Any, loc: tuple[Any, ...]) -> bool:
    for part in loc[:-1]:
        try:
            data = data[part]
        except (KeyError, IndexError, TypeError):
            return False
    if isinstance(data, dict) and loc[-1] in data:
        del data[loc[-1]]
        return True
    return False


def _map_reference_problems(doc: Located, path: Path) -> list[Problem]:
    """A world's map reference checked on its own (when the rest of the file is broken)."""
    data = doc.data if isinstance(doc.data, dict) else {}
    section = data.get("map")
    target = section.get("yaml") if isinstance(section, dict) else None
    if not isinstance(target, str):
        return []
    problems: list[Problem] = []
    resolve_reference(doc, ("map", "yaml"), target, path.parent, "map yaml", problems)
    return problems


# -- building ----------------------------------------------------------------------------------


def _build(spec: WorldSpec, doc: Located, path: Path, problems: list[Problem],
           kept: dict[str, list[int]] | None = None) -> World | None:
    """Build the world, adding geometric problems; ``kept`` maps list positions to the file's (lenient)."""
    kept = kept or {}
    object_at = kept.get("objects") or list(range(len(spec.objects)))
    person_at = kept.get("people") or list(range(len(spec.people)))
    seg_array, rows, ceiling, map_grid = _wall_rows(spec, doc, path, problems)
    instances = {FLOOR_INSTANCE: InstanceInfo(0, "floor", "floor", "floor"),
                 WALL_INSTANCE: InstanceInfo(1, "wall", "wall", "wall")}
    objects = _object_rows(spec, doc, problems, object_at, rows, instances)
    people = [Person(pspec, 2 + len(objects) + j) for j, pspec in enumerate(spec.people)]
    instances.update({p.inst: InstanceInfo(p.inst, "person", p.spec.id, "person") for p in people})
    try:
        grid, walls_grid = _rasterise(spec, seg_array, objects, map_grid)
    except WorldTooLargeError as exc:
        problems.append(doc.problem_at((), str(exc), "a world may span at most "
                                       f"{MAX_MAP_CELLS:,} grid cells; raise `resolution:` or shrink it",
                                       where=""))
        return None
    _check_objects(doc, objects, seg_array, walls_grid, grid, problems, object_at)
    _check_routes(doc, spec, seg_array, problems, person_at)
    open_cells = (grid.data < BLOCKED_FROM).astype(np.uint8)
    clearance = cv2.distanceTransform(open_cells, cv2.DIST_L2, 5) * grid.resolution
    start = Pose2D(spec.robot.start.x, spec.robot.start.y, spec.robot.start.heading)
    rooms = [Room(r.name, r.type, np.array(r.polygon, float), r.floor_rgb) for r in spec.rooms]
    world = World(
        name=spec.name, source=str(path), spec=spec, start=start, profile_name=spec.robot.profile,
        wall_segments=seg_array, static=Primitives.build(rows), grid=grid, walls_grid=walls_grid,
        rooms=rooms, objects=objects, crowd=Crowd(people), instances=instances, ceiling=ceiling,
        floor_rgb=_floor_colours(grid, rooms), _clearance=clearance,
    )
    if spec.map is None or map_grid is not None:  # without its map the start cannot be judged
        _check_start(doc, world, problems)
    return world


def _wall_rows(spec: WorldSpec, doc: Located, path: Path, problems: list[Problem]
               ) -> tuple[np.ndarray, list[Row], float, tuple[np.ndarray, float, Pose2D] | None]:
    """The walls: their segments (n x 4), their render rows, the ceiling and the map they came from."""
    segments: list[tuple[float, float, float, float]] = []
    rows: list[Row] = []
    ceiling = 2.5
    map_grid: tuple[np.ndarray, float, Pose2D] | None = None
    if spec.walls is not None:
        walls = spec.walls
        segments += [(a[0], a[1], b[0], b[1]) for a, b in walls.segments]
        for line in walls.polylines:
            segments += [(a[0], a[1], b[0], b[1]) for a, b in zip(line[:-1], line[1:], strict=True)]
        for poly in walls.polygons:
            closed = [*poly, poly[0]]
            segments += [(a[0], a[1], b[0], b[1]) for a, b in zip(closed[:-1], closed[1:], strict=True)]
        rows += [(SEGMENT, s, 0.0, walls.height, walls.rgb, WALL_INSTANCE) for s in segments]
        ceiling = walls.height
    if spec.map is not None:
        map_grid = read_nav2_map(spec, doc, path, problems)
        if map_grid is not None:
            cells, res, origin = map_grid
            map_segments = contour_segments(cells >= BLOCKED_FROM, res, origin)
            segments += map_segments
            rows += [(SEGMENT, s, 0.0, spec.map.height, spec.map.rgb, WALL_INSTANCE) for s in map_segments]
            ceiling = max(ceiling if spec.walls else 0.0, spec.map.height)
    return np.array(segments, dtype=float).reshape(-1, 4), rows, ceiling, map_grid


def _object_rows(spec: WorldSpec, doc: Located, problems: list[Problem], object_at: list[int],
                 rows: list[Row], instances: dict[int, InstanceInfo]) -> list[WorldObject]:
    """The world's objects, with their render rows and instances added; duplicate ids are problems."""
    objects: list[WorldObject] = []
    counts: dict[str, int] = {}
    for i, ospec in enumerate(spec.objects):
        inst = 2 + i
        counts[ospec.label] = counts.get(ospec.label, 0) + 1
        oid = ospec.id or f"{ospec.label.replace(' ', '_')}_{counts[ospec.label]}"
        obj = _make_object(ospec, oid, inst)
        objects.append(obj)
        instances[inst] = InstanceInfo(inst, "object", oid, obj.label)
        if obj.shape == "cylinder":
            rows.append((CYLINDER, (obj.pose.x, obj.pose.y, obj.size[0] / 2), obj.elevation, obj.top, obj.rgb,
                         inst, obj.pattern))
        else:
            rows.append((BOX, (obj.pose.x, obj.pose.y, math.cos(obj.pose.yaw), math.sin(obj.pose.yaw),
                               obj.size[0] / 2, obj.size[1] / 2), obj.elevation, obj.top, obj.rgb, inst,
                         obj.pattern))
    ids = [o.id for o in objects]
    for i, oid in enumerate(ids):
        if oid in ids[:i]:
            problems.append(doc.problem_at(("objects", object_at[i], "id"), f"duplicate object id {oid!r}",
                                           "give every object a unique id"))
    return objects


def _make_object(ospec: ObjectSpec, oid: str, inst: int) -> WorldObject:
    obstacle = ospec.obstacle if ospec.obstacle is not None else ospec.elevation < OBSTACLE_BELOW
    size = ospec.size if ospec.shape == "box" else (ospec.size[0], ospec.size[0], ospec.size[2])
    return WorldObject(
        id=oid, label=ospec.label, color=(ospec.color or "").lower(), rgb=ospec.rgb_value,
        attributes=tuple(ospec.attributes), description=ospec.description, shape=ospec.shape,
        size=size, pose=Pose2D(ospec.pose.x, ospec.pose.y, ospec.pose.heading),
        elevation=ospec.elevation, movable=ospec.movable, obstacle=obstacle, inst=inst,
        pattern=pattern_for(ospec.label, ospec.pattern),
    )


def _rasterise(spec: WorldSpec, segs: np.ndarray, objects: list[WorldObject],
               map_grid: tuple[np.ndarray, float, Pose2D] | None) -> tuple[OccupancyGrid, np.ndarray]:
    unknown = None
    if map_grid is not None:
        cells, res, origin = map_grid
        walls = cells >= BLOCKED_FROM
        unknown = cells < 0
    else:
        res = spec.resolution
        pts = [segs[:, :2], segs[:, 2:]] + [o.footprint() for o in objects]
        allp = np.concatenate([p for p in pts if len(p)]) if any(len(p) for p in pts) else np.zeros((1, 2))
        lo, hi = allp.min(axis=0) - 0.5, allp.max(axis=0) + 0.5
        origin = Pose2D(math.floor(lo[0] / res) * res, math.floor(lo[1] / res) * res, 0.0)
        cols = int(math.ceil((hi[0] - origin.x) / res))
        rows = int(math.ceil((hi[1] - origin.y) / res))
        if rows * cols > MAX_MAP_CELLS:
            raise WorldTooLargeError(rows, cols, res)
        walls = np.zeros((rows, cols), bool)
    thickness = spec.walls.thickness if spec.walls is not None else res
    canvas = walls.astype(np.uint8)
    px = max(1, int(round(thickness / res)))
    for x1, y1, x2, y2 in segs if spec.walls is not None else []:
        p1 = (int((x1 - origin.x) / res * 16), int((y1 - origin.y) / res * 16))
        p2 = (int((x2 - origin.x) / res * 16), int((y2 - origin.y) / res * 16))
        cv2.line(canvas, p1, p2, 1, px, cv2.LINE_8, shift=4)
    walls_grid = canvas.astype(bool)
    for obj in objects:
        if obj.obstacle:
            poly = ((obj.footprint() - [origin.x, origin.y]) / res * 16).astype(np.int32)
            cv2.fillPoly(canvas, [poly], 1, cv2.LINE_8, shift=4)
    data = (canvas > 0).astype(np.int8) * np.int8(100)  # no int64 image in between
    if unknown is not None:
        data[unknown & (canvas == 0)] = -1
    return OccupancyGrid(0.0, res, origin, data), walls_grid


class WorldTooLargeError(ValueError):
    """Internal: the occupancy grid a world needs is larger than :data:`MAX_MAP_CELLS`."""

    def __init__(self, rows: int, cols: int, res: float) -> None:
        super().__init__(f"expected a world of at most {MAX_MAP_CELLS:,} grid cells, found "
                         f"{cols} x {rows} cells of {res:g} m ({cols * res:,.0f} x {rows * res:,.0f} m)")


def _floor_colours(grid: OccupancyGrid, rooms: list[Room]) -> np.ndarray:
    # uint8: the colours are whole numbers 0-255 (the schema's RGB); a 100 m world's float64 image
    # held 98 MB for the run
    rgb = np.empty(grid.data.shape + (3,), np.uint8)
    rgb[:] = (170, 160, 145)
    for room in rooms:  # drawn straight into the image (a later room over an earlier one, as listed)
        colour = room.floor_rgb or _ROOM_FLOORS.get(room.type, (170, 160, 145))
        poly = ((room.polygon - [grid.origin.x, grid.origin.y]) / grid.resolution * 16).astype(np.int32)
        cv2.fillPoly(rgb, [poly], tuple(int(c) for c in colour), cv2.LINE_8, shift=4)
    return rgb


_ROOM_FLOORS = {
    "kitchen": (196, 190, 178), "office": (128, 118, 104), "corridor": (160, 158, 150),
    "hall": (180, 176, 168), "living room": (150, 120, 90), "bedroom": (140, 115, 95),
    "bathroom": (200, 205, 210),
}


def _check_objects(doc: Located, objects: list[WorldObject], segs: np.ndarray, walls_grid: np.ndarray,
                   grid: OccupancyGrid, problems: list[Problem], object_at: list[int]) -> None:
    boxes = _segment_boxes(segs) if len(segs) else None  # once for all objects, not once each
    for i, obj in enumerate(objects):
        hit = _footprint_hits_walls(obj, segs, boxes) if len(segs) else False
        if not hit and walls_grid.any():
            hit = _footprint_hits_grid(obj, walls_grid, grid) and not len(segs)
        if hit:
            problems.append(doc.problem_at(
                ("objects", object_at[i], "pose"),
                f"object {obj.id!r} ({obj.label}, {obj.size[0]:.2f} x {obj.size[1]:.2f} m at "
                f"{obj.pose.x:.2f}, {obj.pose.y:.2f}) overlaps a wall",
                "move it off the wall or make it smaller",
            ))


def _check_routes(doc: Located, spec: WorldSpec, segs: np.ndarray, problems: list[Problem],
                  person_at: list[int]) -> None:
    """People must not walk through walls (their route legs may not cross a wall segment)."""
    if not len(segs):
        return
    for i, person in enumerate(spec.people):
        points = list(person.route)
        if person.loop and len(points) > 2:
            points.append(points[0])
        for j, (a, b) in enumerate(zip(points[:-1], points[1:], strict=True)):
            if _crosses_any(a, b, segs):
                k = min(j + 1, len(person.route) - 1)
                problems.append(doc.problem_at(
                    ("people", person_at[i], "route", k),
                    f"person {person.id!r} walks through a wall between ({a[0]:g}, {a[1]:g}) and "
                    f"({b[0]:g}, {b[1]:g})" + (" (the loop closes back to the first point)"
                                               if j == len(person.route) - 1 else ""),
                    "add a route point at a door, or set loop: false",
                ))
                break


def _crosses_any(a: tuple[float, float], b: tuple[float, float], segs: np.ndarray) -> bool:
    """Whether the segment a-b properly crosses any wall segment (touching does not count)."""
    ax, ay, bx, by = a[0], a[1], b[0], b[1]
    p, q = segs[:, :2], segs[:, 2:]

    def side(ox: Any, oy: Any, px: Any, py: Any, qx: Any, qy: Any) -> Any:
        return (px - ox) * (qy - oy) - (py - oy) * (qx - ox)

    d1 = side(ax, ay, bx, by, p[:, 0], p[:, 1])
    d2 = side(ax, ay, bx, by, q[:, 0], q[:, 1])
    d3 = side(p[:, 0], p[:, 1], q[:, 0], q[:, 1], ax, ay)
    d4 = side(p[:, 0], p[:, 1], q[:, 0], q[:, 1], bx, by)
    return bool(np.any((d1 * d2 < -1e-12) & (d3 * d4 < -1e-12)))


def _segment_boxes(segs: np.ndarray) -> np.ndarray:
    """Each segment's bounding box (n x 4: x min, x max, y min, y max)."""
    xs, ys = segs[:, 0::2], segs[:, 1::2]
    return np.stack([xs.min(1), xs.max(1), ys.min(1), ys.max(1)], 1)


def _footprint_hits_walls(obj: WorldObject, segs: np.ndarray, boxes: np.ndarray | None = None) -> bool:
    """Whether a wall segment passes through the object's outline shrunk by a contact slack."""
    b = _segment_boxes(segs) if boxes is None else boxes
    x, y, c, s = obj.pose.x, obj.pose.y, math.cos(obj.pose.yaw), math.sin(obj.pose.yaw)
    hx, hy = obj.size[0] / 2 - _CONTACT_SLACK, obj.size[1] / 2 - _CONTACT_SLACK
    reach = hx if obj.shape == "cylinder" else math.hypot(hx, hy)
    # only segments whose box meets the square round the outline can reach it (few of a real map's)
    near = (b[:, 0] <= x + reach) & (b[:, 1] >= x - reach) & (b[:, 2] <= y + reach) & (b[:, 3] >= y - reach)
    if obj.shape == "cylinder":
        return bool(np.any(_point_segment_distance(x, y, segs[near]) < reach))
    if hx <= 0 or hy <= 0:
        return False
    # segment endpoints in the box frame; Liang-Barsky clip against the box
    for x1, y1, x2, y2 in segs[near].tolist():
        ax, ay = c * (x1 - obj.pose.x) + s * (y1 - obj.pose.y), -s * (x1 - obj.pose.x) + c * (y1 - obj.pose.y)
        bx, by = c * (x2 - obj.pose.x) + s * (y2 - obj.pose.y), -s * (x2 - obj.pose.x) + c * (y2 - obj.pose.y)
        t0, t1 = 0.0, 1.0
        ok = True
        for p, q in ((-(bx - ax), ax + hx), (bx - ax, hx - ax), (-(by - ay), ay + hy), (by - ay, hy - ay)):
            if abs(p) < 1e-12:
                if q < 0:
                    ok = False
                    break
                continue
            r = q / p
            if p < 0:
                t0 = max(t0, r)
            else:
                t1 = min(t1, r)
            if t0 > t1:
                ok = False
                break
        if ok:
            return True
    return False


def _footprint_hits_grid(obj: WorldObject, walls_grid: np.ndarray, grid: OccupancyGrid) -> bool:
    """Whether occupied map cells lie under the object's outline (eroded by one cell of slack).

    Drawn in a window round the outline (two cells of margin), not on a map-sized mask per object.
    """
    cells = (obj.footprint() - [grid.origin.x, grid.origin.y]) / grid.resolution
    rows, cols = walls_grid.shape
    c0, r0 = (max(0, int(math.floor(v)) - 2) for v in cells.min(axis=0))
    c1, r1 = (int(math.ceil(v)) + 3 for v in cells.max(axis=0))
    c1, r1 = min(c1, cols), min(r1, rows)
    if c0 >= c1 or r0 >= r1:
        return False
    mask: np.ndarray = np.zeros((r1 - r0, c1 - c0), np.uint8)
    poly = ((cells - [c0, r0]) * 16).astype(np.int32)
    cv2.fillPoly(mask, [poly], 1, cv2.LINE_8, shift=4)
    mask = cv2.erode(mask, np.ones((3, 3), np.uint8))
    return bool((mask.astype(bool) & walls_grid[r0:r1, c0:c1]).any())


def _point_segment_distance(x: float, y: float, segs: np.ndarray) -> np.ndarray:
    a, b = segs[:, :2], segs[:, 2:]
    ab = b - a
    denom = np.maximum((ab * ab).sum(axis=1), 1e-12)
    t = np.clip(((np.array([x, y]) - a) * ab).sum(axis=1) / denom, 0.0, 1.0)
    closest = a + ab * t[:, None]
    return np.hypot(closest[:, 0] - x, closest[:, 1] - y)


def _check_start(doc: Located, world: World, problems: list[Problem]) -> None:
    try:
        profile = load_robot_profile(world.profile_name)
    except WorldFileError:
        return  # reported as an unknown profile (or its own file's problems) elsewhere
    s = world.start
    xmin, ymin, xmax, ymax = world.bounds()
    if not (xmin <= s.x <= xmax and ymin <= s.y <= ymax):
        problems.append(doc.problem_at(("robot", "start"), f"robot start ({s.x:.2f}, {s.y:.2f}) lies outside "
                                       f"the world ({xmin:.1f}..{xmax:.1f}, {ymin:.1f}..{ymax:.1f})",
                                       "move the start inside the walls"))
        return
    gap = min(world.clearance(s.x, s.y),
              float(np.min(_point_segment_distance(s.x, s.y, world.wall_segments)))
              if len(world.wall_segments) else math.inf)
    if gap < profile.body.radius:
        problems.append(doc.problem_at(
            ("robot", "start"),
            f"robot start ({s.x:.2f}, {s.y:.2f}) is {gap:.2f} m from a wall or obstacle; the "
            f"{profile.name} body needs {profile.body.radius:.2f} m (it would start inside the wall)",
            "move the start into free space",
        ))
