"""Placing one object at a time into a world's free floor without blocking the robot.

:func:`scene_of` turns a built world into the rasters placement works on (:class:`Scene`: what is
blocked, how far each cell is from a wall, which room it is in, where the doors are, where the
robot reaches); a :class:`Placer` then fits objects into it one by one: furniture against a wall
and away from doors, small objects on open floor, on low furniture, against walls and in corners.
An object is kept only if it lies on known free floor, overlaps no wall and no other object, and
(when it is an obstacle) every place the robot reached before is still reached with a margin of a
footprint radius plus :data:`PASS_MARGIN`. :mod:`~missiontree.backends.sim.placement` decides
*what* to place; this module decides *where* it fits.
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

from missiontree.backends.sim.world import World, build_world
from missiontree.mapping.clearance import clearance_metres
from missiontree.mapping.occupancy import BLOCKED_FROM
from missiontree.types import OccupancyGrid
from missiontree.yamlio import Located

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
#: Small objects taller than this stand on the floor only (no umbrella upright on a bench).
MAX_ON_TOP = 0.5


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


def footprint_mask(shape: tuple[int, int], grid: OccupancyGrid, poly: np.ndarray) -> np.ndarray:
    """Cells of a grid of ``shape`` whose centres lie inside the outline ``poly`` (N, 2 in metres)."""
    mask = np.zeros(shape, np.uint8)
    # OpenCV's pixel k spans [k - 0.5, k + 0.5): the cell of x is pixel (x - origin) / res - 0.5
    pts = np.round(((poly - [grid.origin.x, grid.origin.y]) / grid.resolution - 0.5) * 16).astype(np.int32)
    cv2.fillPoly(mask, [pts], 1, cv2.LINE_8, shift=4)
    return mask.astype(bool)


def footprint_window(shape: tuple[int, int], grid: OccupancyGrid, poly: np.ndarray
                     ) -> tuple[np.ndarray, tuple[slice, slice]]:
    """:func:`footprint_mask` drawn in the outline's bounding box only: (mask, window of the grid).

    The same cells: the outline's fixed-point corners are those of :func:`footprint_mask`, moved by
    whole cells. The window is empty when the outline misses the grid.
    """
    pts = np.round(((poly - [grid.origin.x, grid.origin.y]) / grid.resolution - 0.5) * 16).astype(np.int32)
    c0, r0 = (max(int(v) // 16 - 1, 0) for v in pts.min(axis=0))
    c1, r1 = (int(v) // 16 + 2 for v in pts.max(axis=0))
    c1, r1 = max(min(c1, shape[1]), c0), max(min(r1, shape[0]), r0)
    mask = np.zeros((r1 - r0, c1 - c0), np.uint8)
    if mask.size:
        cv2.fillPoly(mask, [pts - np.array([c0 * 16, r0 * 16], np.int32)], 1, cv2.LINE_8, shift=4)
    return mask.astype(bool), (slice(r0, r1), slice(c0, c1))


def box(x: float, y: float, yaw: float, sx: float, sy: float, grow: float = 0.0) -> np.ndarray:
    """The four corners of a ``sx`` by ``sy`` box at (x, y) turned by ``yaw``, grown by ``grow`` a side."""
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
    walls = (grid.data >= BLOCKED_FROM) | (grid.data < 0)
    blocked = walls.copy()
    for obj in world.objects:  # each outline drawn in its own box (a real map holds hundreds)
        mask, window = footprint_window(shape, grid, obj.footprint())
        blocked[window] |= mask
    wall_dist = clearance_metres(~walls, grid.resolution)
    rooms = np.zeros(shape, np.int32)
    for i in range(len(world.rooms) - 1, -1, -1):  # the first room wins, as World.room_at
        mask, window = footprint_window(shape, grid, world.rooms[i].polygon)
        rooms[window][mask] = i + 1
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
    dist = clearance_metres(~blocked, res)
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
    return clearance_metres(~mask, res) <= metres


#: Cells an obstacle's window is grown by, in turn, to show locally that it keeps the robot's reach
#: before the whole map is labelled (a window spanning a wall between rooms needs the door).
_REACH_WINDOWS = (0, 60, 200)

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
        pts = np.round(((poly - corner) / res - 0.5) * 16).astype(np.int32)  # as in footprint_mask
        cv2.fillPoly(mask, [pts], 1, cv2.LINE_8, shift=4)
        return _Footprint(window, mask.astype(bool))


class Placer:
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
            dist = clearance_metres(~self.s.blocked, self.res)
            self._free_dist = np.minimum(dist, DIST_CAP)
        return self._free_dist

    def new_id(self, label: str) -> str:
        """A fresh object id for ``label`` (``cup_1``, ``cup_2``, ...), taken at once."""
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

        Sufficient locally: the reached cells of the window around the footprint (or of that window
        grown by :data:`_REACH_WINDOWS`, in turn) still form one piece inside it. Otherwise the
        whole map decides.
        """
        lost = foot.lost if foot.lost is not None else np.zeros_like(foot.mask)
        start = self.s.grid.world_to_cell(self.s.world.start.x, self.s.world.start.y)
        (rs, cs) = foot.window
        if rs.start <= start[0] < rs.stop and cs.start <= start[1] < cs.stop:
            if lost[start[0] - rs.start, start[1] - cs.start]:
                return False
        if not (self.s.reach[foot.window] & ~lost).any():
            return True
        for grow in _REACH_WINDOWS:
            if self._one_piece(foot.window, lost, grow):
                return True
        robot_free = self.s.robot_free.copy()
        robot_free[foot.window] &= ~lost
        after = reachable(robot_free, start)
        kept = self.s.reach.copy()
        kept[foot.window] &= ~lost
        return not (kept & ~after).any()

    def _one_piece(self, window: Window, lost: np.ndarray, grow: int) -> bool:
        """Whether the reached cells of ``window`` grown by ``grow`` cells, but ``lost``, are one piece in it.

        Sufficient for the reach to hold: a path to a reached cell outside the window enters and
        leaves it through reached cells of its edge, which ``lost`` (inside the footprint's own
        window, by its padding) never touches, and those the piece joins.
        """
        (rs, cs), (h, w) = window, self.s.reach.shape
        r0, r1 = max(rs.start - grow, 0), min(rs.stop + grow, h)
        c0, c1 = max(cs.start - grow, 0), min(cs.stop + grow, w)
        big = (slice(r0, r1), slice(c0, c1))
        keep = np.ones((r1 - r0, c1 - c0), bool)
        keep[rs.start - r0 : rs.stop - r0, cs.start - c0 : cs.stop - c0] = ~lost
        free = self.s.robot_free[big] & keep
        before = self.s.reach[big] & keep
        _, comp = cv2.connectedComponents(free.astype(np.uint8), connectivity=8)
        return len(np.unique(comp[before])) == 1

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
            near = clearance_metres(local, self.res)
            self._free_dist[r0:r1, c0:c1] = np.minimum(self._free_dist[r0:r1, c0:c1], near)
        if foot.lost is not None:
            self.s.robot_free[foot.window] &= ~foot.lost
            self.s.reach[foot.window] &= ~foot.lost

    def candidates(self, room: int, where: Callable[[Window], np.ndarray]) -> np.ndarray:
        """Cells (K, 2) of ``room`` (index + 1) where ``where`` (of a window of the grid) holds, shuffled.

        ``where`` is computed on the room's bounding box only: a room is a small part of a large map.
        """
        if self._boxes is None:
            from scipy import ndimage  # imported on use: a mission on a shipped world never places objects

            self._boxes = ndimage.find_objects(self.s.rooms)
        bounds = self._boxes[room - 1] if 0 < room <= len(self._boxes) else None
        if bounds is None:
            return np.zeros((0, 2), int)
        ok = where(bounds) & (self.s.rooms[bounds] == room)
        cells = np.argwhere(ok) + [bounds[0].start, bounds[1].start]
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
            poly = box(x, y, yaw, sx, sy)
            foot = self.fits(box(x, y, yaw, sx, sy, max(0.05, self.grow)), obstacle=True)
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
            foot = self.fits(box(x, y, yaw, sx, sy, self.grow), obstacle=True)
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
        walls = (self.s.grid.data >= BLOCKED_FROM) | (self.s.grid.data < 0)
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
