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

:func:`map_world` makes a world of a Nav2 map this way; ``load_world("map:depot:4")`` builds one of
the shipped maps (config/worlds/maps) by name and seed, with two people walking.
"""

from __future__ import annotations

import copy
import dataclasses
import hashlib
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import yaml
from scipy import ndimage

from missiontree.backends.sim.generator import _FURNITURE, _SMALL
from missiontree.backends.sim.mapimage import read_map_image
from missiontree.backends.sim.navigation import INSCRIBED, Costmap, plan
from missiontree.backends.sim.navmap import map_cells
from missiontree.backends.sim.schema import NavMapYaml
from missiontree.backends.sim.world import Room, World, build_world, load_robot_profile, register_world_source
from missiontree.errors import Problem, WorldFileError
from missiontree.paths import config_dirs
from missiontree.semantics.rooms import segment_rooms
from missiontree.types import OccupancyGrid, Pose2D
from missiontree.yamlio import Located, parse_yaml

#: Footprint radius of the robot that must pass (TurtleBot 4: 0.34 m wide).
ROBOT_RADIUS = 0.17
#: Extra clearance kept on each side of the robot where objects are placed.
PASS_MARGIN = 0.08
#: Furniture small objects may stand on (a tv or a sink is no shelf).
SURFACES = frozenset({"table", "dining table", "desk", "bench", "bed"})
#: Small objects may stand on furniture whose top is no higher than this (camera at 0.4 m).
MAX_TOP = 0.8
#: Furniture keeps this far from a door or an opening between rooms; small objects keep ``SMALL_DOOR_GAP``.
FURNITURE_DOOR_GAP = 0.9
SMALL_DOOR_GAP = 0.6
#: Distances to objects are kept up to this (m): no placement rule looks farther.
DIST_CAP = 1.2
#: No object comes nearer than this to the robot's start (m).
START_CLEAR = 0.6
#: Room types handed to rooms that have none (rooms found on a real map), after the largest.
SEGMENTED_TYPES = ["kitchen", "office", "bedroom", "bathroom", "storage", "living room", "hall"]

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
#: Small objects taller than this stand on the floor only (no umbrella upright on a bench).
MAX_ON_TOP = 0.5


def colours_for(label: str) -> list[str]:
    """The colours a small object of this class is given (a laptop is not orange)."""
    return CLASS_COLOURS.get(label, DECOY_COLOURS)


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
        doors: Free cells beside an opening between two rooms (no furniture near them).
        robot_free: Cells the robot's centre may take with the margin (reached or not).
        floor: Free cells joined to the robot's start (not the inside of a closed shelf or a pocket).
        keep_clear: Cells no object may cover: around the robot's start.
        tops: Furniture small objects may stand on, each ``{"object": dict, "used": [...]}``.
    """

    world: World
    grid: OccupancyGrid
    blocked: np.ndarray
    wall_dist: np.ndarray
    rooms: np.ndarray
    reach: np.ndarray
    doors: np.ndarray
    robot_free: np.ndarray
    floor: np.ndarray
    keep_clear: np.ndarray
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

    The data is handed to the loader as it is, without a round trip through YAML text (which cost
    a third of a floorplan's making); problems then point at the document, not at lines.

    Raises:
        WorldFileError: The data is not a valid world.
    """
    doc = Located(copy.deepcopy(data), f"<{data.get('name', 'world')}>", {}, {})
    return build_world(doc, world_path(data))


def _footprint_mask(shape: tuple[int, int], grid: OccupancyGrid, poly: np.ndarray) -> np.ndarray:
    mask = np.zeros(shape, np.uint8)
    # OpenCV's pixel k spans [k - 0.5, k + 0.5): the cell of x is pixel (x - origin) / res - 0.5
    pts = np.round(((poly - [grid.origin.x, grid.origin.y]) / grid.resolution - 0.5) * 16).astype(np.int32)
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
    robot_free = _robot_free(blocked, grid.resolution)
    reach = reachable(robot_free, grid.world_to_cell(world.start.x, world.start.y))
    doors = _door_cells(rooms, ~walls)
    _, comp = cv2.connectedComponents((~blocked).astype(np.uint8), connectivity=4)
    floor = np.isin(comp, np.unique(comp[reach & ~blocked])) & ~blocked
    keep_clear = np.zeros(shape, bool)
    row, col = grid.world_to_cell(world.start.x, world.start.y)
    if 0 <= row < shape[0] and 0 <= col < shape[1]:
        keep_clear[row, col] = True
        keep_clear = _near(keep_clear, START_CLEAR, grid.resolution)
    return Scene(world, grid, blocked, wall_dist, rooms, reach, doors, robot_free, floor, keep_clear)


def _robot_free(blocked: np.ndarray, res: float) -> np.ndarray:
    dist = cv2.distanceTransform((~blocked).astype(np.uint8), cv2.DIST_L2, 5) * res
    return dist > ROBOT_RADIUS + PASS_MARGIN


def _door_cells(rooms: np.ndarray, free: np.ndarray) -> np.ndarray:
    """Free cells beside a free cell of another room (or of no room): doors and openings."""
    border = np.zeros_like(free)
    for dr, dc in ((0, 1), (1, 0)):
        a = (slice(0, rooms.shape[0] - dr), slice(0, rooms.shape[1] - dc))
        b = (slice(dr, None), slice(dc, None))
        differ = free[a] & free[b] & (rooms[a] != rooms[b])
        border[a] |= differ
        border[b] |= differ
    return border


def _near(mask: np.ndarray, metres: float, res: float) -> np.ndarray:
    """Cells within ``metres`` of a cell of ``mask`` (a distance transform: one pass, any radius)."""
    if not mask.any():
        return mask
    return cv2.distanceTransform((~mask).astype(np.uint8), cv2.DIST_L2, 5) * res <= metres


#: A window of the grid: (rows, cols) slices.
Window = tuple[slice, slice]


@dataclass
class _Footprint:
    """An outline rasterised in a window of the grid: ``mask`` covers ``window``'s cells."""

    window: tuple[slice, slice]
    mask: np.ndarray
    lost: np.ndarray | None = None

    @staticmethod
    def of(poly: np.ndarray, grid: OccupancyGrid, shape: tuple[int, ...], pad: int) -> _Footprint | None:
        """The outline's cells in its bounding box grown by ``pad`` cells; None if it leaves the grid."""
        res = grid.resolution
        lo = np.floor((poly.min(axis=0) - [grid.origin.x, grid.origin.y]) / res).astype(int) - pad
        hi = np.ceil((poly.max(axis=0) - [grid.origin.x, grid.origin.y]) / res).astype(int) + pad + 1
        if lo[0] < 0 or lo[1] < 0 or hi[0] > shape[1] or hi[1] > shape[0]:
            return None
        window = (slice(int(lo[1]), int(hi[1])), slice(int(lo[0]), int(hi[0])))
        mask = np.zeros((int(hi[1] - lo[1]), int(hi[0] - lo[0])), np.uint8)
        corner = [grid.origin.x + lo[0] * res, grid.origin.y + lo[1] * res]
        pts = np.round(((poly - corner) / res - 0.5) * 16).astype(np.int32)  # as in _footprint_mask
        cv2.fillPoly(mask, [pts], 1, cv2.LINE_8, shift=4)
        return _Footprint(window, mask.astype(bool))


class _Placer:
    """Places objects one by one into a scene, keeping the robot's reach."""

    def __init__(self, scene: Scene, rng: np.random.Generator, ids: set[str]) -> None:
        self.s = scene
        self.rng = rng
        self.ids = ids
        self.res = scene.grid.resolution
        #: Outlines are grown by this before they are rasterised: a cell is covered when its centre
        #: is, so an outline may reach half a cell into a wall cell it does not cover
        self.grow = max(0.03, 0.55 * self.res)
        self.near_door_furniture = _near(scene.doors, FURNITURE_DOOR_GAP, self.res)
        self.near_door_small = _near(scene.doors, SMALL_DOOR_GAP, self.res)
        self.reach_near = _near(scene.reach, 0.9, self.res) & scene.floor
        self._free_dist: np.ndarray | None = None
        self._corner_cache: dict[int, np.ndarray] = {}
        self._boxes: list[Window | None] | None = None

    def free_dist(self) -> np.ndarray:
        """Distance (m, at most :data:`DIST_CAP`) of each cell to the nearest blocked one."""
        if self._free_dist is None:
            dist = cv2.distanceTransform((~self.s.blocked).astype(np.uint8), cv2.DIST_L2, 5) * self.res
            self._free_dist = np.minimum(dist, DIST_CAP)
        return self._free_dist

    def new_id(self, label: str) -> str:
        n = 1
        base = label.replace(" ", "_")
        while f"{base}_{n}" in self.ids:
            n += 1
        self.ids.add(f"{base}_{n}")
        return f"{base}_{n}"

    def fits(self, poly: np.ndarray, obstacle: bool) -> _Footprint | None:
        """The footprint if it covers only free, unblocked cells (and, an obstacle, keeps the reach)."""
        pad = int(math.ceil((ROBOT_RADIUS + PASS_MARGIN) / self.res)) + 2
        foot = _Footprint.of(poly, self.s.grid, self.s.blocked.shape, pad)
        if foot is None or not foot.mask.any():
            return None
        if (foot.mask & (self.s.blocked[foot.window] | self.s.keep_clear[foot.window])).any():
            return None
        if obstacle:
            foot.lost = cv2.dilate(
                foot.mask.astype(np.uint8), _disk((ROBOT_RADIUS + PASS_MARGIN) / self.res)
            ).astype(bool)
            if not self._keeps_reach(foot):
                return None
        return foot

    def _keeps_reach(self, foot: _Footprint) -> bool:
        """Whether every cell the robot reached, but those beside the footprint, is still reached.

        Sufficient locally: the reached cells of the window around the footprint still form one
        piece inside it. Otherwise (a window spanning a wall between two rooms) the whole map decides.
        """
        lost = foot.lost if foot.lost is not None else np.zeros_like(foot.mask)
        start = self.s.grid.world_to_cell(self.s.world.start.x, self.s.world.start.y)
        (rs, cs) = foot.window
        if rs.start <= start[0] < rs.stop and cs.start <= start[1] < cs.stop:
            if lost[start[0] - rs.start, start[1] - cs.start]:
                return False
        free = self.s.robot_free[foot.window] & ~lost
        before = self.s.reach[foot.window] & ~lost
        if not before.any():
            return True
        _, comp = cv2.connectedComponents(free.astype(np.uint8), connectivity=8)
        if len(np.unique(comp[before])) == 1:
            return True
        robot_free = self.s.robot_free.copy()
        robot_free[foot.window] &= ~lost
        after = reachable(robot_free, start)
        kept = self.s.reach.copy()
        kept[foot.window] &= ~lost
        return not (kept & ~after).any()

    def commit(self, foot: _Footprint) -> None:
        """Mark the footprint taken (and, an obstacle, the places beside it no longer reached)."""
        self.s.blocked[foot.window] |= foot.mask
        if self._free_dist is not None:  # lower the distances near the footprint, in a window
            pad = int(math.ceil(DIST_CAP / self.res)) + 1
            rs, cs = foot.window
            h, w = self.s.blocked.shape
            r0, r1 = max(rs.start - pad, 0), min(rs.stop + pad, h)
            c0, c1 = max(cs.start - pad, 0), min(cs.stop + pad, w)
            local = np.ones((r1 - r0, c1 - c0), np.uint8)
            local[rs.start - r0 : rs.stop - r0, cs.start - c0 : cs.stop - c0][foot.mask] = 0
            near = cv2.distanceTransform(local, cv2.DIST_L2, 5) * self.res
            self._free_dist[r0:r1, c0:c1] = np.minimum(self._free_dist[r0:r1, c0:c1], near)
        if foot.lost is not None:
            self.s.robot_free[foot.window] &= ~foot.lost
            self.s.reach[foot.window] &= ~foot.lost

    def candidates(self, room: int, where: Callable[[Window], np.ndarray]) -> np.ndarray:
        """Cells (K, 2) of ``room`` (index + 1) where ``where`` (of a window of the grid) holds, shuffled.

        ``where`` is computed on the room's bounding box only: a room is a small part of a large map.
        """
        if self._boxes is None:
            self._boxes = ndimage.find_objects(self.s.rooms)
        box = self._boxes[room - 1] if 0 < room <= len(self._boxes) else None
        if box is None:
            return np.zeros((0, 2), int)
        ok = where(box) & (self.s.rooms[box] == room)
        cells = np.argwhere(ok) + [box[0].start, box[1].start]
        if len(cells) > 400:
            cells = cells[self.rng.choice(len(cells), 400, replace=False)]
        else:
            cells = cells[self.rng.permutation(len(cells))]
        return cells

    # -- furniture --------------------------------------------------------------------------

    def furniture(
        self, room: int, label: str, colour: str, size: tuple[float, float, float]
    ) -> dict[str, Any] | None:
        """Furniture against a wall of ``room`` (its long side to the wall), away from doors."""
        sx, sy, sz = size
        depth = sy

        def where(w: Window) -> np.ndarray:
            wall = self.s.wall_dist[w]
            band = (wall >= depth / 2 + 0.03) & (wall <= depth / 2 + 0.12)
            return band & ~self.near_door_furniture[w] & ~self.s.blocked[w] & self.reach_near[w]

        for row, col in self.candidates(room, where)[:60]:
            yaw = self._wall_yaw(int(row), int(col))
            x, y = self.s.point(int(row), int(col))
            poly = _box(x, y, yaw, sx, sy)
            foot = self.fits(_box(x, y, yaw, sx, sy, max(0.05, self.grow)), obstacle=True)
            if foot is None:
                continue
            inner = _Footprint.of(poly, self.s.grid, self.s.blocked.shape, 0)
            if inner is None or (self.s.rooms[inner.window][inner.mask] != room).any():
                continue
            self.commit(foot)
            obj = {
                "id": self.new_id(label),
                "label": label,
                "color": colour,
                "size": [sx, sy, sz],
                "pose": {"x": round(x, 3), "y": round(y, 3), "yaw": round(yaw, 4)},
                "movable": False,
            }
            if label in SURFACES and sz <= MAX_TOP:
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
            obj = self._on_top(room, label, colour, size, shape) if size[2] <= MAX_ON_TOP else None
            if obj is not None:
                return obj
            mode = "floor"
        sx, sy, sz = size
        half = math.hypot(sx, sy) / 2
        dist = self.free_dist()
        corners = self._corners(half + 0.15) if mode == "corner" else None

        def where(w: Window) -> np.ndarray:
            ok = ~self.s.blocked[w] & ~self.near_door_small[w] & self.reach_near[w]
            wall = self.s.wall_dist[w]
            if mode == "floor":
                return ok & (dist[w] >= half + 0.3)
            ok &= (wall >= half + 0.02) & (dist[w] >= half)
            if mode == "wall":
                return ok & (wall <= half + 0.1)
            assert corners is not None
            return ok & corners[w]

        for row, col in self.candidates(room, where)[:40]:
            x, y = self.s.point(int(row), int(col))
            yaw = (
                self._wall_yaw(int(row), int(col))
                if mode != "floor"
                else float(self.rng.uniform(-math.pi, math.pi))
            )
            foot = self.fits(_box(x, y, yaw, sx, sy, self.grow), obstacle=True)
            if foot is None:
                continue
            self.commit(foot)
            where_text = {"floor": "on the floor", "wall": "against a wall", "corner": "in a corner"}[mode]
            return self._small_dict(label, colour, size, shape, x, y, yaw, 0.0, where_text)
        return None

    def _corners(self, reach: float) -> np.ndarray:
        """Cells with a wall within ``reach`` along an x direction and along a y direction."""
        key = int(round(reach / self.res))
        if key not in self._corner_cache:
            self._corner_cache[key] = self._find_corners(reach)
        return self._corner_cache[key]

    def _find_corners(self, reach: float) -> np.ndarray:
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
            "description": f"{'an' if colour[0] in 'aeiou' else 'a'} {colour} {label} {where}{place}",
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
    scene = scene_of(world)
    placer = _Placer(scene, rng, {o.id for o in world.objects})
    objects: list[dict[str, Any]] = list(out.get("objects") or [])
    rooms = list(world.rooms)
    if furniture:
        # round by round (every room's first piece, then every room's second): when space runs
        # out, every room still has its main piece
        lists = [furniture_for(room.type) for room in rooms]
        for k in range(max((len(f) for f in lists), default=0)):
            for i, pieces in enumerate(lists, start=1):
                if k < len(pieces):
                    label, colour, size = pieces[k]
                    obj = placer.furniture(i, label, colour, size)
                    if obj is not None:
                        objects.append(obj)
    kinds = small_kinds()
    placed_small: list[dict[str, Any]] = []
    labels = sorted(kinds)
    areas = np.bincount(scene.rooms.ravel(), minlength=len(rooms) + 1) * scene.grid.resolution**2
    for i, room in enumerate(rooms if per_room else [], start=1):
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
                placed_small.append(obj)
    tries = 0
    while len(placed_small) < small and tries < 20 * max(small, 1) and rooms:
        tries += 1
        label = labels[int(rng.integers(len(labels)))]
        colour = colours_for(label)[int(rng.integers(len(colours_for(label))))]
        size, shape = kinds[label]
        index = int(rng.integers(len(rooms))) + 1
        obj = placer.small(index, label, colour, size, shape, MODES[int(rng.integers(len(MODES)))])
        if obj is not None:
            placed_small.append(obj)
    if decoys and rooms:
        for target in list(placed_small)[: max(2, len(placed_small) // 4)]:
            placed_small += _decoys(placer, target, kinds, rng, len(rooms))
    out["objects"] = objects + placed_small
    return out


def keep_fitting(data: dict[str, Any], candidates: list[dict[str, Any]]) -> dict[str, Any]:
    """``data`` with those ``candidates`` (object dicts, in order) that fit, as placed objects do.

    An object fits when it covers only free floor no other object covers, and (reaching below
    0.3 m, an obstacle) every place the robot reached before is still reached with the margin.
    """
    out = copy.deepcopy(data)
    world = build(out)
    placer = _Placer(scene_of(world), np.random.default_rng(0), {o.id for o in world.objects})
    kept = []
    for obj in candidates:
        sx, sy, _ = obj["size"]
        pose = obj["pose"]
        if obj.get("shape") == "cylinder":
            a = np.linspace(0, 2 * np.pi, 16, endpoint=False)
            r = sx / 2 + placer.grow
            poly = np.stack([pose["x"] + r * np.cos(a), pose["y"] + r * np.sin(a)], axis=1)
        else:
            poly = _box(pose["x"], pose["y"], pose.get("yaw", 0.0), sx, sy, placer.grow)
        foot = placer.fits(poly, obstacle=float(obj.get("elevation", 0.0)) < 0.3)
        if foot is not None and obj["id"] not in placer.ids:
            placer.commit(foot)
            placer.ids.add(obj["id"])
            kept.append(obj)
    out["objects"] = list(out.get("objects") or []) + kept
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


def rooms_from_map(world: World, rng: np.random.Generator) -> list[dict[str, Any]]:
    """Rooms for a world without any: its free space segmented at doors, each given a type.

    A segmented room larger than :data:`ZONE_AREA` twice over (an open hall or warehouse floor
    with no doors to split it) is cut into zones of about that size, as a person would name the
    parts of an open floor. The largest room is a hall; the others take :data:`SEGMENTED_TYPES`
    in a seeded order (rooms under 6 m² a bathroom or storage). Polygons are simplified to 10 cm.
    """
    order = [SEGMENTED_TYPES[int(k)] for k in rng.permutation(len(SEGMENTED_TYPES))]
    rooms: list[dict[str, Any]] = []
    counts: dict[str, int] = {}
    for n, (poly, area) in enumerate(_map_pieces(world.grid, (world.start.x, world.start.y))):
        if n == 0:
            kind = "hall"
        elif area < 6.0:
            kind = "bathroom" if n % 2 else "storage"
        else:
            kind = order[(n - 1) % len(order)]
            if kind == "bathroom" and area > 25.0:  # no bathroom of an open floor's size
                kind = "storage"
        counts[kind] = counts.get(kind, 0) + 1
        rooms.append({"name": f"{kind} {counts[kind]}", "type": kind, "polygon": poly})
    return rooms


_PIECES: dict[tuple[Any, ...], list[tuple[list[list[float]], float]]] = {}


def _map_pieces(grid: OccupancyGrid, inside: tuple[float, float]) -> list[tuple[list[list[float]], float]]:
    """The rooms and zones of a map (outline, area), largest first; kept per map and piece of floor.

    Segmenting a large map takes seconds and gives the same rooms for every start in one piece of
    floor, so the result is kept for the process (keyed by the grid's content and that piece).
    """
    data = np.ascontiguousarray(grid.data)
    _, comp = cv2.connectedComponents(((data >= 0) & (data < 50)).astype(np.uint8), connectivity=4)
    row, col = grid.world_to_cell(*inside)
    piece = int(comp[row, col]) if 0 <= row < data.shape[0] and 0 <= col < data.shape[1] else -1
    key = (
        data.shape,
        grid.resolution,
        grid.origin.x,
        grid.origin.y,
        hashlib.sha1(data.tobytes()).hexdigest(),
        piece,
    )
    if key not in _PIECES:
        seg = segment_rooms(grid, inside=inside)
        res = grid.resolution
        masks: list[np.ndarray] = []
        for label in range(1, int(seg.labels.max()) + 1):
            region = seg.labels == label
            area = float(region.sum()) * res * res
            masks += _zones(region, res) if area > 2 * ZONE_AREA else [region]
        masks.sort(key=lambda m: -int(m.sum()))
        found = []
        for mask in masks:
            poly = _outline(mask, grid)
            if poly is not None:
                found.append((poly, float(mask.sum()) * res * res))
        if len(_PIECES) > 32:
            _PIECES.clear()
        _PIECES[key] = found
    return copy.deepcopy(_PIECES[key])


#: Open floors (a segmented room over twice this, m²) are cut into zones of about this area.
ZONE_AREA = 60.0


def _zones(region: np.ndarray, res: float) -> list[np.ndarray]:
    """``region`` cut into zones of about :data:`ZONE_AREA`: cells to the nearest of seeds on a grid."""
    rows, cols = np.nonzero(region)
    r0, r1, c0, c1 = rows.min(), rows.max() + 1, cols.min(), cols.max() + 1
    h, w = (r1 - r0) * res, (c1 - c0) * res
    area = float(region.sum()) * res * res
    count = max(2, int(round(area / ZONE_AREA)))
    # a grid of ny x nx seeds with about square zones
    nx = max(1, int(round(math.sqrt(count * w / max(h, 1e-6)))))
    ny = max(1, int(math.ceil(count / nx)))
    seeds = np.zeros(region.shape, bool)
    for i in range(ny):
        for j in range(nx):
            sr = int(r0 + (i + 0.5) * (r1 - r0) / ny)
            sc = int(c0 + (j + 0.5) * (c1 - c0) / nx)
            seeds[sr, sc] = True
    _, (ir, ic) = ndimage.distance_transform_edt(~seeds, return_indices=True)
    owner = ir * region.shape[1] + ic
    zones = []
    for key in np.unique(owner[region]):
        zone = region & (owner == key)
        if float(zone.sum()) * res * res >= 3.0:
            zones.append(zone)
    return zones


def _outline(mask: np.ndarray, grid: OccupancyGrid) -> list[list[float]] | None:
    """The outline of a mask's largest piece as a polygon simplified to 10 cm (None if too small)."""
    res = grid.resolution
    closed = cv2.morphologyEx(mask.astype(np.uint8), cv2.MORPH_CLOSE, np.ones((5, 5), np.uint8))
    contours, _ = cv2.findContours(closed, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    if not contours:
        return None
    outline = max(contours, key=cv2.contourArea).reshape(-1, 1, 2).astype(np.float32)
    pts = cv2.approxPolyDP(outline, 0.1 / res, True).reshape(-1, 2)
    if len(pts) < 3:
        return None
    return [
        [round(float(grid.origin.x + (x + 0.5) * res), 3), round(float(grid.origin.y + (y + 0.5) * res), 3)]
        for x, y in pts
    ]


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


def map_start(map_yaml: Path, rng: np.random.Generator, clearance: float = 0.5) -> tuple[float, float, float]:
    """A start point on a map, and the area (m²) it reaches.

    The point lies on known free floor ``clearance`` from anything, in the map's largest piece of
    floor a robot can drive (with :data:`PASS_MARGIN`); the area is that piece's.
    """
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
    area = float(piece.sum()) * res * res
    return float(ox + (cols[k] + 0.5) * res), float(oy + (rows[k] + 0.5) * res), area


def map_world(
    map_yaml: Path, seed: int, *, name: str | None = None, small: int = 0, people: int = 0
) -> dict[str, Any]:
    """A world on a Nav2 map (absolute path kept): seeded start, rooms found and typed, objects placed.

    Raises:
        WorldFileError: The map cannot be read as a world.
    """
    map_yaml = Path(map_yaml).resolve()
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
        world = build(data)
    if people:
        data["people"] = walkers(world, rng, people)
    return data


def walkers(world: World, rng: np.random.Generator, count: int) -> list[dict[str, Any]]:
    """People walking to and fro on straight lines of open floor (0.35 m from anything) the robot reaches."""
    scene = scene_of(world)
    res = scene.grid.resolution
    dist = cv2.distanceTransform((~scene.blocked).astype(np.uint8), cv2.DIST_L2, 5) * res
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
