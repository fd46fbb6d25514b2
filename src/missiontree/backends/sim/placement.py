"""Objects placed into any world: furniture against walls, small objects where a robot can find them.

:func:`place_objects` takes world-file data (a generated apartment, a floorplan, or a world drawn on
a map_server map) and returns it with objects added, chosen and placed from one seed:

- **furniture** per room type against the walls (``generator``'s classes, colours and sizes, the only
  ones the shipped detector knows), away from doors;
- **small objects** on open floor, on tables and other low furniture (tops up to 0.8 m, where a
  camera 40 cm high still sees them), against walls and in corners;
- **decoys**: for a small object, one of the same class in another colour and one of the same
  colour of another class, elsewhere.

It works on the world's occupancy grid, so the same code serves drawn walls and real maps. Every
object lies on known free floor, overlaps no wall and no other object, and an obstacle is kept only
if every place the robot reached before it was placed is still reached with a margin (a footprint
radius plus 8 cm): doors and corridors stay passable. A world without rooms (a real map) gets them
from :func:`missiontree.semantics.rooms.segment_rooms`, each given a type.
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import yaml

from missiontree.backends.sim.generator import _FURNITURE, _SMALL
from missiontree.backends.sim.mapimage import read_map_image
from missiontree.backends.sim.navigation import INSCRIBED, Costmap, plan
from missiontree.backends.sim.navmap import map_cells
from missiontree.backends.sim.schema import NavMapYaml
from missiontree.backends.sim.world import World, build_world, load_robot_profile
from missiontree.errors import WorldFileError
from missiontree.semantics.rooms import segment_rooms
from missiontree.types import OccupancyGrid, Pose2D
from missiontree.yamlio import parse_yaml

#: Footprint radius of the robot that must pass (TurtleBot 4: 0.34 m wide).
ROBOT_RADIUS = 0.17
#: Extra clearance kept on each side of the robot where objects are placed.
PASS_MARGIN = 0.08
#: Small objects may stand on furniture whose top is no higher than this (camera at 0.4 m).
MAX_TOP = 0.8
#: Furniture keeps this far from a door or an opening between rooms; small objects keep ``SMALL_DOOR_GAP``.
FURNITURE_DOOR_GAP = 0.9
SMALL_DOOR_GAP = 0.6
#: Room types handed to rooms that have none (rooms found on a real map), after the largest.
SEGMENTED_TYPES = ["kitchen", "office", "bedroom", "bathroom", "storage", "living room", "hall"]

#: Furniture for room types the apartment generator does not furnish (same classes as its).
EXTRA_FURNITURE: dict[str, list[tuple[str, str, tuple[float, float, float]]]] = {
    "storage": [("bookshelf", "brown", (1.2, 0.35, 1.9)), ("trash can", "grey", (0.35, 0.35, 0.5))],
    "corridor": [("potted plant", "green", (0.45, 0.45, 0.9)), ("bench", "brown", (1.2, 0.4, 0.45))],
}
#: Colours small objects and their decoys are drawn from.
DECOY_COLOURS = ["red", "blue", "green", "black", "white", "grey", "yellow", "pink", "silver", "orange"]


def furniture_for(room_type: str) -> list[tuple[str, str, tuple[float, float, float]]]:
    """The furniture (label, colour, size) a room of this type gets."""
    return list(_FURNITURE.get(room_type) or EXTRA_FURNITURE.get(room_type) or EXTRA_FURNITURE["storage"])


def small_kinds() -> dict[str, tuple[tuple[float, float, float], str]]:
    """Every small object class of the generator: label -> (size, shape)."""
    kinds: dict[str, tuple[tuple[float, float, float], str]] = {}
    for entries in _SMALL.values():
        for label, _colour, size, shape in entries:
            kinds.setdefault(label, (size, shape))
    return kinds


def small_for(room_type: str) -> list[tuple[str, str, tuple[float, float, float], str]]:
    """The small objects (label, colour, size, shape) the generator gives a room of this type."""
    return list(_SMALL.get(room_type, []))


@dataclass
class Scene:
    """A world's free space as rasters, for placing objects (built by :func:`scene_of`).

    Attributes:
        world: The built world.
        grid: Its occupancy grid (walls, obstacle objects; unknown cells are -1).
        blocked: Cells nothing new may cover: walls, unknown, every object's footprint.
        wall_dist: Distance (m) of each cell to the nearest wall or unknown cell.
        rooms: Room index + 1 per cell (0: no room).
        reach: Cells the robot's centre reaches from the start with :data:`PASS_MARGIN` to spare.
        doors: Free cells near an opening between two rooms (no furniture there).
    """

    world: World
    grid: OccupancyGrid
    blocked: np.ndarray
    wall_dist: np.ndarray
    rooms: np.ndarray
    reach: np.ndarray
    doors: np.ndarray
    tops: list[dict[str, Any]] = field(default_factory=list)

    def cell(self, x: float, y: float) -> tuple[int, int]:
        """(row, col) of a point."""
        return self.grid.world_to_cell(x, y)

    def point(self, row: int, col: int) -> tuple[float, float]:
        """Centre of a cell."""
        return self.grid.cell_to_world(row, col)


def world_path(data: dict[str, Any]) -> Path:
    """The path a world's data is built as: beside its map yaml (absolute) when it has one."""
    section = data.get("map")
    if (
        isinstance(section, dict)
        and isinstance(section.get("yaml"), str)
        and Path(section["yaml"]).is_absolute()
    ):
        return Path(section["yaml"]).parent / f"{data.get('name', 'world')}.yaml"
    return Path.cwd() / f"{data.get('name', 'world')}.yaml"


def build(data: dict[str, Any]) -> World:
    """Build world-file data (checked as a file is), resolving an absolute map path beside itself.

    Raises:
        WorldFileError: The data is not a valid world.
    """
    text = yaml.safe_dump(data, sort_keys=False)
    doc = parse_yaml(text, f"<{data.get('name', 'world')}>", error=WorldFileError)
    return build_world(doc, world_path(data))


def _footprint_mask(shape: tuple[int, int], grid: OccupancyGrid, poly: np.ndarray) -> np.ndarray:
    mask = np.zeros(shape, np.uint8)
    pts = ((poly - [grid.origin.x, grid.origin.y]) / grid.resolution * 16).astype(np.int32)
    cv2.fillPoly(mask, [pts], 1, cv2.LINE_8, shift=4)
    return mask.astype(bool)


def _box(x: float, y: float, yaw: float, sx: float, sy: float, grow: float = 0.0) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    hx, hy = sx / 2 + grow, sy / 2 + grow
    return np.array(
        [
            (x + c * px - s * py, y + s * px + c * py)
            for px, py in ((hx, hy), (-hx, hy), (-hx, -hy), (hx, -hy))
        ]
    )


def _disk(radius_cells: float) -> np.ndarray:
    k = int(math.ceil(radius_cells)) * 2 + 1
    return cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (k, k))


def reachable(free: np.ndarray, start: tuple[int, int]) -> np.ndarray:
    """The 8-connected piece of ``free`` holding ``start`` (or nearest to it)."""
    _, comp = cv2.connectedComponents(free.astype(np.uint8), connectivity=8)
    row, col = start
    h, w = free.shape
    label = int(comp[row, col]) if 0 <= row < h and 0 <= col < w else 0
    if label == 0:
        rows, cols = np.nonzero(comp)
        if not len(rows):
            return np.zeros_like(free)
        k = int(np.argmin((rows - row) ** 2 + (cols - col) ** 2))
        label = int(comp[rows[k], cols[k]])
    return comp == label


def scene_of(world: World) -> Scene:
    """The rasters :func:`place_objects` works on, for a built world."""
    grid = world.grid
    shape = grid.data.shape
    walls = (grid.data >= 50) | (grid.data < 0)
    blocked = walls.copy()
    for obj in world.objects:
        blocked |= _footprint_mask(shape, grid, obj.footprint())
    wall_dist = cv2.distanceTransform((~walls).astype(np.uint8), cv2.DIST_L2, 5) * grid.resolution
    rooms = np.zeros(shape, np.int32)
    for i in range(len(world.rooms) - 1, -1, -1):  # the first room wins, as World.room_at
        rooms[_footprint_mask(shape, grid, world.rooms[i].polygon)] = i + 1
    rooms[walls] = 0
    reach = _robot_reach(blocked, grid, world)
    doors = _door_cells(rooms, ~blocked, grid.resolution)
    return Scene(world, grid, blocked, wall_dist, rooms, reach, doors)


def _robot_free(blocked: np.ndarray, res: float) -> np.ndarray:
    dist = cv2.distanceTransform((~blocked).astype(np.uint8), cv2.DIST_L2, 5) * res
    return dist > ROBOT_RADIUS + PASS_MARGIN


def _robot_reach(blocked: np.ndarray, grid: OccupancyGrid, world: World) -> np.ndarray:
    return reachable(_robot_free(blocked, grid.resolution), grid.world_to_cell(world.start.x, world.start.y))


def _door_cells(rooms: np.ndarray, free: np.ndarray, res: float) -> np.ndarray:
    """Free cells within reach of a place where two rooms (or a room and no room) meet on free floor."""
    kernel = np.ones((3, 3), np.uint8)
    hi = cv2.dilate(rooms.astype(np.float32), kernel)
    lo = -cv2.dilate(-rooms.astype(np.float32), kernel)
    border = free & (hi != lo) & (rooms > 0)
    return border


def _near(mask: np.ndarray, metres: float, res: float) -> np.ndarray:
    if not mask.any():
        return mask
    return cv2.dilate(mask.astype(np.uint8), _disk(metres / res)).astype(bool)


class _Placer:
    """Places objects one by one into a scene, keeping the robot's reach."""

    def __init__(self, scene: Scene, rng: np.random.Generator, ids: set[str]) -> None:
        self.s = scene
        self.rng = rng
        self.ids = ids
        self.res = scene.grid.resolution
        self.near_door_furniture = _near(scene.doors, FURNITURE_DOOR_GAP, self.res)
        self.near_door_small = _near(scene.doors, SMALL_DOOR_GAP, self.res)
        self.reach_near = _near(scene.reach, 0.9, self.res)
        self._dist_dirty = True
        self._free_dist: np.ndarray = np.zeros(0)

    def free_dist(self) -> np.ndarray:
        if self._dist_dirty:
            self._free_dist = (
                cv2.distanceTransform((~self.s.blocked).astype(np.uint8), cv2.DIST_L2, 5) * self.res
            )
            self._dist_dirty = False
        return self._free_dist

    def new_id(self, label: str) -> str:
        n = 1
        base = label.replace(" ", "_")
        while f"{base}_{n}" in self.ids:
            n += 1
        self.ids.add(f"{base}_{n}")
        return f"{base}_{n}"

    def fits(self, poly: np.ndarray, obstacle: bool) -> np.ndarray | None:
        """The footprint's cells if it covers only free, unblocked cells (and keeps the reach)."""
        mask = _footprint_mask(self.s.blocked.shape, self.s.grid, poly)
        if not mask.any() or (mask & self.s.blocked).any():
            return None
        lo = poly.min(axis=0)
        hi = poly.max(axis=0)
        xmin, ymin, xmax, ymax = self.s.world.bounds()
        if lo[0] < xmin or lo[1] < ymin or hi[0] > xmax or hi[1] > ymax:
            return None
        if obstacle and not self._keeps_reach(mask):
            return None
        return mask

    def _keeps_reach(self, mask: np.ndarray) -> bool:
        blocked = self.s.blocked | mask
        lost = _near(mask, ROBOT_RADIUS + PASS_MARGIN + self.res, self.res)
        start = self.s.grid.world_to_cell(self.s.world.start.x, self.s.world.start.y)
        if lost[start] if 0 <= start[0] < lost.shape[0] and 0 <= start[1] < lost.shape[1] else False:
            return False
        reach = reachable(_robot_free(blocked, self.res), start)
        return not (self.s.reach & ~lost & ~reach).any()

    def commit(self, mask: np.ndarray, obstacle: bool) -> None:
        self.s.blocked |= mask
        self._dist_dirty = True
        if obstacle:
            self.s.reach = _robot_reach(self.s.blocked, self.s.grid, self.s.world)

    def candidates(self, room: int, where: np.ndarray) -> np.ndarray:
        """Cells (K, 2) of ``room`` (index + 1; 0: any room) satisfying ``where``, shuffled."""
        ok = where & (self.s.rooms == room) if room else where & (self.s.rooms > 0)
        cells = np.argwhere(ok)
        if len(cells) > 400:
            cells = cells[self.rng.choice(len(cells), 400, replace=False)]
        else:
            cells = cells[self.rng.permutation(len(cells))]
        return cells

    # -- furniture --------------------------------------------------------------------------

    def furniture(
        self, room: int, label: str, colour: str, size: tuple[float, float, float], against: bool = True
    ) -> dict[str, Any] | None:
        """Furniture against a wall of ``room`` (its long side to the wall), away from doors."""
        sx, sy, sz = size
        depth = sy
        band = (self.s.wall_dist >= depth / 2 + 0.03) & (self.s.wall_dist <= depth / 2 + 0.12)
        where = band & ~self.near_door_furniture & ~self.s.blocked & self.reach_near
        for row, col in self.candidates(room, where)[:60]:
            yaw = self._wall_yaw(int(row), int(col))
            x, y = self.s.point(int(row), int(col))
            poly = _box(x, y, yaw, sx, sy)
            mask = self.fits(_box(x, y, yaw, sx, sy, 0.05), obstacle=True)
            if mask is None or (self.s.rooms[_footprint_mask(mask.shape, self.s.grid, poly)] != room).any():
                continue
            self.commit(mask, True)
            obj = {
                "id": self.new_id(label),
                "label": label,
                "color": colour,
                "size": [sx, sy, sz],
                "pose": {"x": round(x, 3), "y": round(y, 3), "yaw": round(yaw, 4)},
                "movable": False,
            }
            if sz <= MAX_TOP and sx * sy >= 0.2:
                self.s.tops.append({"object": obj, "used": []})
            return obj
        return None

    def _wall_yaw(self, row: int, col: int) -> float:
        """Yaw that puts a box's long (x) side along the nearest wall, snapped to the axes when near."""
        r = max(2, int(round(0.6 / self.res)))
        h, w = self.s.blocked.shape
        r0, r1, c0, c1 = max(row - r, 0), min(row + r + 1, h), max(col - r, 0), min(col + r + 1, w)
        walls = self.s.wall_dist[r0:r1, c0:c1] <= self.res * 0.75
        rows, cols = np.nonzero(walls)
        if not len(rows):
            return 0.0
        d2 = (rows + r0 - row) ** 2 + (cols + c0 - col) ** 2
        k = int(np.argmin(d2))
        nx, ny = cols[k] + c0 - col, rows[k] + r0 - row  # toward the wall
        angle = math.atan2(ny, nx) + math.pi / 2  # the box's x axis runs along the wall
        snapped = round(angle / (math.pi / 2)) * (math.pi / 2)
        if abs(angle - snapped) < math.radians(15):
            angle = snapped
        return math.atan2(math.sin(angle), math.cos(angle))

    # -- small objects ----------------------------------------------------------------------

    def small(
        self, room: int, label: str, colour: str, size: tuple[float, float, float], shape: str, mode: str
    ) -> dict[str, Any] | None:
        """A small object in ``room`` placed by ``mode``: floor, wall, corner or top (of furniture)."""
        if mode == "top":
            obj = self._on_top(room, label, colour, size, shape)
            if obj is not None:
                return obj
            mode = "floor"
        sx, sy, sz = size
        half = math.hypot(sx, sy) / 2
        dist = self.free_dist()
        base = ~self.s.blocked & ~self.near_door_small & self.reach_near
        if mode == "floor":
            where = base & (dist >= half + 0.3)
        elif mode == "wall":
            where = (
                base & (self.s.wall_dist >= half + 0.02) & (self.s.wall_dist <= half + 0.1) & (dist >= half)
            )
        else:  # corner
            where = base & self._corners(half + 0.15) & (self.s.wall_dist >= half + 0.02) & (dist >= half)
        for row, col in self.candidates(room, where)[:40]:
            x, y = self.s.point(int(row), int(col))
            yaw = (
                self._wall_yaw(int(row), int(col))
                if mode != "floor"
                else float(self.rng.uniform(-math.pi, math.pi))
            )
            mask = self.fits(_box(x, y, yaw, sx, sy, 0.03), obstacle=True)
            if mask is None:
                continue
            self.commit(mask, True)
            where_text = {"floor": "on the floor", "wall": "against a wall", "corner": "in a corner"}[mode]
            return self._small_dict(label, colour, size, shape, x, y, yaw, 0.0, where_text)
        return None

    def _corners(self, reach: float) -> np.ndarray:
        """Cells with a wall within ``reach`` along an x direction and along a y direction."""
        walls = (self.s.grid.data >= 50) | (self.s.grid.data < 0)
        k = max(1, int(round(reach / self.res)))
        near_x = np.zeros_like(walls)
        near_y = np.zeros_like(walls)
        for step in range(1, k + 1):
            near_x[:, :-step] |= walls[:, step:]
            near_x[:, step:] |= walls[:, :-step]
            near_y[:-step, :] |= walls[step:, :]
            near_y[step:, :] |= walls[:-step, :]
        return near_x & near_y

    def _on_top(
        self, room: int, label: str, colour: str, size: tuple[float, float, float], shape: str
    ) -> dict[str, Any] | None:
        sx, sy, _ = size
        tops = [
            t
            for t in self.s.tops
            if self.s.rooms[self.s.cell(t["object"]["pose"]["x"], t["object"]["pose"]["y"])] == room
        ]
        for k in self.rng.permutation(len(tops)):
            top = tops[int(k)]
            f = top["object"]
            fx, fy, fz = f["size"]
            if fx < sx + 0.1 or fy < sy + 0.1:
                continue
            for _ in range(8):
                u = float(self.rng.uniform(-(fx - sx) / 2 + 0.05, (fx - sx) / 2 - 0.05))
                v = float(self.rng.uniform(-(fy - sy) / 2 + 0.05, (fy - sy) / 2 - 0.05))
                if any(
                    abs(u - a) < (sx + w) / 2 + 0.05 and abs(v - b) < (sy + d) / 2 + 0.05
                    for a, b, w, d in top["used"]
                ):
                    continue
                yaw = f["pose"]["yaw"]
                x = f["pose"]["x"] + math.cos(yaw) * u - math.sin(yaw) * v
                y = f["pose"]["y"] + math.sin(yaw) * u + math.cos(yaw) * v
                top["used"].append((u, v, sx, sy))
                return self._small_dict(label, colour, size, shape, x, y, yaw, fz, f"on the {f['label']}")
        return None

    def _small_dict(
        self,
        label: str,
        colour: str,
        size: tuple[float, float, float],
        shape: str,
        x: float,
        y: float,
        yaw: float,
        elevation: float,
        where: str,
    ) -> dict[str, Any]:
        room = self.s.world.room_at(x, y)
        place = (
            f" of the {room.name}"
            if room is not None and where in ("on the floor", "in a corner")
            else (f" in the {room.name}" if room is not None else "")
        )
        obj: dict[str, Any] = {
            "id": self.new_id(label),
            "label": label,
            "color": colour,
            "shape": shape,
            "size": list(size),
            "pose": {"x": round(x, 3), "y": round(y, 3)},
            "description": f"a {colour} {label} {where}{place}",
        }
        if shape == "box":
            obj["pose"]["yaw"] = round(yaw, 4)
        if elevation > 0:
            obj["elevation"] = round(elevation, 3)
        return obj


MODES = ("floor", "top", "wall", "corner")


def place_objects(
    data: dict[str, Any],
    seed: int,
    *,
    furniture: bool = True,
    small: int = 0,
    decoys: bool = True,
    room_types: bool = True,
) -> dict[str, Any]:
    """``data`` with furniture, small objects and decoys added (a copy; ``data`` is not changed).

    Args:
        data: World-file data; a map path in it must be absolute.
        seed: Seeds every choice: the same data and seed give the same objects.
        furniture: Furnish each room by its type, against the walls.
        small: At least this many small objects in all (each room also gets its type's own).
        decoys: Add a same-class and a same-colour decoy for some small objects.
        room_types: Give a world without rooms the rooms found on its map, each with a type.

    Raises:
        WorldFileError: The data is not a valid world.
    """
    out = copy.deepcopy(data)
    rng = np.random.default_rng(seed)
    world = build(out)
    if not out.get("rooms") and room_types:
        out["rooms"] = rooms_from_map(world, rng)
        world = build(out)
    scene = scene_of(world)
    placer = _Placer(scene, rng, {o.id for o in world.objects})
    objects: list[dict[str, Any]] = list(out.get("objects") or [])
    rooms = list(world.rooms)
    if furniture:
        for i, room in enumerate(rooms, start=1):
            for label, colour, size in furniture_for(room.type):
                obj = placer.furniture(i, label, colour, size)
                if obj is not None:
                    objects.append(obj)
    kinds = small_kinds()
    placed_small: list[dict[str, Any]] = []
    for i, room in enumerate(rooms, start=1):
        for label, colour, size, shape in small_for(room.type):
            obj = placer.small(i, label, colour, size, shape, MODES[int(rng.integers(len(MODES)))])
            if obj is not None:
                placed_small.append(obj)
    labels = sorted(kinds)
    tries = 0
    while len(placed_small) < small and tries < 20 * max(small, 1) and rooms:
        tries += 1
        label = labels[int(rng.integers(len(labels)))]
        colour = DECOY_COLOURS[int(rng.integers(len(DECOY_COLOURS)))]
        size, shape = kinds[label]
        index = int(rng.integers(len(rooms))) + 1
        obj = placer.small(index, label, colour, size, shape, MODES[int(rng.integers(len(MODES)))])
        if obj is not None:
            placed_small.append(obj)
    if decoys and rooms:
        for target in list(placed_small)[: max(2, len(placed_small) // 3)]:
            placed_small += _decoys(placer, target, kinds, rng, len(rooms))
    out["objects"] = objects + placed_small
    return out


def _decoys(
    placer: _Placer,
    target: dict[str, Any],
    kinds: dict[str, tuple[tuple[float, float, float], str]],
    rng: np.random.Generator,
    room_count: int,
) -> list[dict[str, Any]]:
    """A same-class decoy in another colour and a same-colour decoy of another class."""
    found: list[dict[str, Any]] = []
    colours = [c for c in DECOY_COLOURS if c != target["color"]]
    others = [label for label in sorted(kinds) if label != target["label"]]
    for label, colour in (
        (target["label"], colours[int(rng.integers(len(colours)))]),
        (others[int(rng.integers(len(others)))], target["color"]),
    ):
        size, shape = kinds[label]
        for _ in range(4):
            room = int(rng.integers(room_count)) + 1
            obj = placer.small(room, label, colour, size, shape, MODES[int(rng.integers(len(MODES)))])
            if obj is not None:
                found.append(obj)
                break
    return found


def rooms_from_map(world: World, rng: np.random.Generator) -> list[dict[str, Any]]:
    """Rooms for a world without any: its free space segmented at doors, each given a type.

    The largest room is a hall; the others take :data:`SEGMENTED_TYPES` in a seeded order (rooms
    under 6 m² a bathroom or storage). Polygons are simplified to about 10 cm.
    """
    seg = segment_rooms(world.grid, inside=(world.start.x, world.start.y))
    regions = sorted((r for r in seg.rooms if len(r.polygon) >= 3), key=lambda r: -r.area)
    order = [SEGMENTED_TYPES[int(k)] for k in rng.permutation(len(SEGMENTED_TYPES))]
    rooms: list[dict[str, Any]] = []
    counts: dict[str, int] = {}
    for n, region in enumerate(regions):
        if n == 0:
            kind = "hall"
        elif region.area < 6.0:
            kind = "bathroom" if n % 2 else "storage"
        else:
            kind = order[(n - 1) % len(order)]
        counts[kind] = counts.get(kind, 0) + 1
        poly = cv2.approxPolyDP(region.polygon.astype(np.float32).reshape(-1, 1, 2), 0.1, True).reshape(-1, 2)
        if len(poly) < 3:
            continue
        rooms.append(
            {
                "name": f"{kind} {counts[kind]}",
                "type": kind,
                "polygon": [[round(float(x), 3), round(float(y), 3)] for x, y in poly],
            }
        )
    return rooms


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
        inside = _footprint_mask(shape, world.grid, room.polygon) & reach
        if not inside.any():
            missing.append(room.name)
            continue
        score = np.where(inside, clear, -1.0)
        row, col = np.unravel_index(int(np.argmax(score)), shape)
        gx, gy = world.grid.cell_to_world(int(row), int(col))
        if plan(costmap, costmap.cost, world.start, Pose2D(gx, gy)) is None:
            missing.append(room.name)
    return missing


def _map_cells(map_yaml: Path) -> tuple[np.ndarray, float, tuple[float, float]]:
    """Occupancy values of a Nav2 map yaml's image (row 0 = lowest y), resolution, origin (x, y)."""
    meta = NavMapYaml.model_validate(yaml.safe_load(map_yaml.read_text(encoding="utf-8")))
    image = read_map_image((map_yaml.parent / meta.image).resolve())
    return map_cells(image, meta), meta.resolution, (meta.origin[0], meta.origin[1])


def map_start(map_yaml: Path, rng: np.random.Generator, clearance: float = 0.5) -> tuple[float, float]:
    """A start point on a map: known free floor ``clearance`` from anything, in its largest open piece."""
    cells, res, (ox, oy) = _map_cells(map_yaml)
    free = cells == 0
    dist = cv2.distanceTransform(free.astype(np.uint8), cv2.DIST_L2, 5) * res
    ok = dist > ROBOT_RADIUS + PASS_MARGIN
    count, comp = cv2.connectedComponents(ok.astype(np.uint8), connectivity=8)
    sizes = np.bincount(comp.ravel(), minlength=count)
    sizes[0] = 0
    piece = comp == int(sizes.argmax())
    rows, cols = np.nonzero(piece & (dist >= clearance))
    if not len(rows):
        rows, cols = np.nonzero(piece)
    k = int(rng.integers(len(rows)))
    return float(ox + (cols[k] + 0.5) * res), float(oy + (rows[k] + 0.5) * res)


def map_world(
    map_yaml: Path, seed: int, *, name: str | None = None, small: int = 0, people: int = 0
) -> dict[str, Any]:
    """A world on a Nav2 map (absolute path kept): seeded start, rooms found and typed, objects placed.

    Raises:
        WorldFileError: The map cannot be read as a world.
    """
    map_yaml = Path(map_yaml).resolve()
    rng = np.random.default_rng(seed)
    x, y = map_start(map_yaml, rng)
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
    data = place_objects(data, int(rng.integers(2**31)), small=small)
    if people:
        data["people"] = walkers(build(data), rng, people)
    return data


def walkers(world: World, rng: np.random.Generator, count: int) -> list[dict[str, Any]]:
    """People walking to and fro on straight lines of open floor (0.4 m from anything) the robot reaches."""
    scene = scene_of(world)
    res = scene.grid.resolution
    dist = cv2.distanceTransform((~scene.blocked).astype(np.uint8), cv2.DIST_L2, 5) * res
    cells = np.argwhere(scene.reach & (dist >= 0.5))
    found: list[dict[str, Any]] = []
    for k in range(count):
        for _ in range(200):
            if not len(cells):
                break
            r0, c0 = cells[int(rng.integers(len(cells)))]
            r1, c1 = cells[int(rng.integers(len(cells)))]
            length = math.hypot(float(r1 - r0), float(c1 - c0)) * res
            if not 3.0 <= length <= 8.0:
                continue
            steps = int(length / res) + 1
            rr = np.linspace(r0, r1, steps).round().astype(int)
            cc = np.linspace(c0, c1, steps).round().astype(int)
            if (dist[rr, cc] < 0.4).any():
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
