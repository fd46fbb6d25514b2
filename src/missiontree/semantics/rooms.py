"""Rooms: the occupancy map segmented at doors and narrow passages, or polygons from a file.

**Segmentation** follows the distance-transform method of ROS's ``ipa_room_segmentation``: every
free cell gets its distance to the nearest obstacle; a room's middle lies far from walls, a door or
narrow passage near them. Thresholding that distance at a radius splits the free space where the
passages are narrower than twice the radius. Radii from ``min_door_half`` to ``max_door_half`` are
tried and the one giving the most room-sized pieces (between ``min_room_area`` and
``max_room_area``) wins; the pieces then grow back over all free cells by a watershed on the
distance map, whose ridges lie in the doorways, so each boundary falls in its door. Pieces grown to
less than ``min_room_area`` join their largest neighbour.

Unknown cells count as obstacles: on a map being explored the rooms grow as the map does. Specks
(occupied or unknown pieces smaller than ``speckle_area``: a real map's lidar noise, a cell never
seen) count as floor, and holes narrower than ``close_gaps`` in walls are closed while finding rooms.
:class:`RoomTracker` keeps room ids stable across re-segmentations (a new region takes the id of the
old region it overlaps most).

**From a file**: a YAML or JSON list of rooms, each ``{name, type, polygon: [[x, y], ...]}`` (the
world-file ``rooms:`` format; a mapping with a ``rooms:`` key is accepted).

A :class:`RoomRegion` carries a type (``unknown`` until a classifier gives one; see
``missiontree.reasoning.providers.offline_scene`` for the offline one) and answers which room a point is in.
"""

from __future__ import annotations

import json
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import yaml
from scipy import ndimage

from missiontree.errors import ConfigError
from missiontree.file_limits import MAX_ROOMS_BYTES, read_input_text
from missiontree.semantics.room_watershed import drop_small_cores as _drop_small_cores
from missiontree.semantics.room_watershed import flood as _flood
from missiontree.semantics.room_watershed import grow as _grow
from missiontree.semantics.room_watershed import late_cores as _late_cores
from missiontree.semantics.room_watershed import merge_open as _merge_open
from missiontree.semantics.room_watershed import merge_small as _merge_small
from missiontree.types import OccupancyGrid


@dataclass
class RoomRegion:
    """One room.

    Attributes:
        id: Stable id (``room_1``).
        type: Room type (``kitchen``) or ``unknown``.
        polygon: (N, 2) outline in map coordinates.
        area: Floor area, square metres.
        centroid: (x, y) of the free cells.
        name: A human name (from a file), else the id.
        type_confidence: Confidence of the type, in [0, 1].
        evidence: What decided the type.
    """

    id: str
    type: str = "unknown"
    polygon: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    area: float = 0.0
    centroid: tuple[float, float] = (0.0, 0.0)
    name: str = ""
    type_confidence: float = 0.0
    evidence: list[str] = field(default_factory=list)

    @property
    def label(self) -> str:
        """The room's name in the scene graph: its type, or ``room`` while unknown."""
        return self.type if self.type and self.type != "unknown" else "room"

    def describe(self) -> str:
        """One sentence for the graph node."""
        what = self.type.replace("_", " ") if self.type != "unknown" else "a room of unknown type"
        text = f"{what} ({self.name or self.id}), about {self.area:.0f} m2"
        if self.evidence:
            text += f"; seen: {', '.join(self.evidence)}"
        return text

    def contains(self, x: float, y: float) -> bool:
        """Whether (x, y) lies inside the polygon."""
        if len(self.polygon) < 3:
            return False
        return cv2.pointPolygonTest(self.polygon.astype(np.float32), (float(x), float(y)), False) >= 0

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict."""
        return {
            "id": self.id,
            "name": self.name or self.id,
            "type": self.type,
            "type_confidence": round(self.type_confidence, 3),
            "area": round(self.area, 2),
            "centroid": [round(c, 3) for c in self.centroid],
            "polygon": [[round(float(x), 3), round(float(y), 3)] for x, y in self.polygon],
        }


@dataclass(frozen=True)
class SegmentationParams:
    """Parameters of the distance-transform segmentation (metres, square metres).

    Attributes:
        min_door_half: Smallest threshold radius tried (half the narrowest passage that splits).
        max_door_half: Largest threshold radius tried.
        step: Step between radii.
        min_room_area: Pieces smaller than this are not rooms (they join a neighbour).
        max_room_area: Pieces larger than this do not count as rooms when choosing the radius.
        occupied: Occupancy value from which a cell is an obstacle.
        max_door_width: Two regions whose shared border has a cell farther than half this from any
            obstacle (they meet on open floor, not in a door), or who touch along more than one
            stretch (around a table, on both sides of a sofa), are one room.
        close_gaps: Gaps in walls narrower than this are closed first (a learned map's walls have
            holes where the lidar grazed them), metres.
        speckle_area: Obstacles (occupied or unknown cells) smaller than this, square metres, are
            the map's noise (a lidar speck, a cell never seen) and count as free floor: a real map's
            specks would otherwise break every room's distance map and join the rooms through
            the closing of wall gaps.
    """

    min_door_half: float = 0.35
    max_door_half: float = 0.9
    step: float = 0.05
    min_room_area: float = 3.0
    max_room_area: float = 80.0
    occupied: int = 50
    max_door_width: float = 1.5
    close_gaps: float = 0.5
    speckle_area: float = 0.01


@dataclass
class Segmentation:
    """A segmented map: a label per cell (0: no room) and the rooms."""

    grid: OccupancyGrid
    labels: np.ndarray
    rooms: list[RoomRegion]
    _nearest: tuple[np.ndarray, np.ndarray] | None = field(default=None, repr=False)

    def room_at(self, x: float, y: float, reach: float = 0.8) -> RoomRegion | None:
        """The room of the cell at (x, y), or of the nearest room cell within ``reach`` metres."""
        row, col = self.grid.world_to_cell(x, y)
        h, w = self.labels.shape
        if not (0 <= row < h and 0 <= col < w):
            return None
        label = int(self.labels[row, col])
        if label == 0:
            if self._nearest is None:
                dist, idx = ndimage.distance_transform_edt(self.labels == 0, return_indices=True)
                self._nearest = (dist, idx)
            dist, idx = self._nearest
            if dist[row, col] * self.grid.resolution > reach:
                return None
            label = int(self.labels[idx[0][row, col], idx[1][row, col]])
        return self.rooms[label - 1] if 0 < label <= len(self.rooms) else None

    def rooms_at(self, xy: np.ndarray, reach: np.ndarray) -> list[RoomRegion | None]:
        """:meth:`room_at` of many points at once: ``xy`` (N, 2), ``reach`` (N,) metres."""
        xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        if not len(xy):
            return []
        g = self.grid
        rows = np.floor((xy[:, 1] - g.origin.y) / g.resolution)
        cols = np.floor((xy[:, 0] - g.origin.x) / g.resolution)
        h, w = self.labels.shape
        inside = (rows >= 0) & (rows < h) & (cols >= 0) & (cols < w)
        r = np.where(inside, rows, 0).astype(np.intp)
        c = np.where(inside, cols, 0).astype(np.intp)
        label = np.where(inside, self.labels[r, c], 0)
        off_floor = inside & (label == 0)
        if off_floor.any():
            if self._nearest is None:
                dist, idx = ndimage.distance_transform_edt(self.labels == 0, return_indices=True)
                self._nearest = (dist, idx)
            dist, idx = self._nearest
            near = off_floor & (dist[r, c] * g.resolution <= np.asarray(reach, dtype=np.float64))
            label = np.where(near, self.labels[idx[0][r, c], idx[1][r, c]], label)
        count = len(self.rooms)
        return [self.rooms[k - 1] if 0 < k <= count else None for k in label.tolist()]


def segment_rooms(
    grid: OccupancyGrid, params: SegmentationParams | None = None, inside: tuple[float, float] | None = None
) -> Segmentation:
    """Segment ``grid`` into rooms (see module docstring); ids ``room_1``... in row-major order.

    Args:
        grid: The occupancy map.
        params: Segmentation parameters.
        inside: A point known to be inside the building (the robot's position): free space not
            connected to it (the outside of a simulated building, a pocket behind a wall) is left
            out. Without it, free space touching the map's edge is left out when more free space
            lies inside (a simulated building surrounded by floor), else (a SLAM map cropped to what
            was seen, the building reaching the edge) the largest connected free space is taken.
    """
    p = params or SegmentationParams()
    res = grid.resolution
    full = np.asarray(grid.data)
    known_free = (full >= 0) & (full < p.occupied)
    specks = _specks(~known_free, p.speckle_area / res**2)
    building = _building_free(known_free | specks, grid, inside)
    side = int(round(p.close_gaps / res))
    # Everything below happens within the building's box: on a growing map (a robot exploring a
    # large unknown area) the cost follows the known building, not the map's size. The margin holds
    # the closing's reach and the distance transform's 5x5 mask, so the result is the same.
    window = _box(building, full.shape, max(side, 0) + 3)
    if window is None:
        return Segmentation(grid, np.zeros(full.shape, np.int32), [])
    data, specks, building = full[window], specks[window], building[window]
    free = building.copy()
    if side > 1:
        # holes in walls are closed for finding rooms (a narrow passage closed this way is reopened below)
        kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (side | 1, side | 1))
        walls = cv2.morphologyEx(((data >= p.occupied) & ~specks).astype(np.uint8), cv2.MORPH_CLOSE, kernel)
        free &= walls == 0
    if not free.any():
        return Segmentation(grid, np.zeros(full.shape, np.int32), [])
    dist = cv2.distanceTransform(free.astype(np.uint8), cv2.DIST_L2, 5) * res
    min_cells, max_cells = p.min_room_area / res**2, p.max_room_area / res**2
    best_markers, best_radius = _room_cores(dist, p, min_cells, max_cells)
    markers = _drop_small_cores(best_markers, min_cells * 0.1)
    small = (best_markers > 0) & (markers == 0)
    markers = _late_cores(
        markers, small, dist, best_radius, p.min_door_half, p.step, (min_cells * 0.1, max_cells)
    )
    labels = _flood(markers, dist, free, p.step)
    labels = _merge_open(labels, dist, p.max_door_width)
    labels = _grow(labels, building)  # the cells the closing took back: to the nearest room
    labels = _merge_small(labels, min_cells)
    placed = np.zeros(full.shape, np.int32)
    placed[window] = labels
    rooms = _regions(grid, placed)
    return Segmentation(grid, placed, rooms)


def _room_cores(dist: np.ndarray, p: SegmentationParams, min_cells: float,
                max_cells: float) -> tuple[np.ndarray, float]:
    """The cores of rooms: free space farther from walls than a door's half width.

    The radius is tried from ``min_door_half`` to ``max_door_half``; the one giving the most
    room-sized pieces wins.

    Returns:
        The labelled cores and the radius that made them.
    """
    best_markers, best_count, best_radius = None, -1, p.min_door_half
    radius = p.min_door_half
    while radius <= p.max_door_half + 1e-9:
        count, markers = cv2.connectedComponents((dist > radius).astype(np.uint8), connectivity=8)
        sizes = np.bincount(markers.ravel(), minlength=count)[1:]
        # a piece at this radius is the core of a room: its room is larger than the core itself
        found = int(np.sum((sizes >= min_cells * 0.1) & (sizes <= max_cells)))
        if found > best_count:
            best_markers, best_count, best_radius = markers, found, radius
        radius += p.step
    assert best_markers is not None
    return best_markers, best_radius


def _box(mask: np.ndarray, shape: tuple[int, ...], margin: int) -> tuple[slice, slice] | None:
    """The bounding box of ``mask``'s cells grown by ``margin`` within ``shape`` (None: no cell)."""
    rows = np.flatnonzero(mask.any(axis=1))
    if not rows.size:
        return None
    cols = np.flatnonzero(mask.any(axis=0))
    return (slice(max(int(rows[0]) - margin, 0), min(int(rows[-1]) + 1 + margin, shape[0])),
            slice(max(int(cols[0]) - margin, 0), min(int(cols[-1]) + 1 + margin, shape[1])))


def _specks(obstacle: np.ndarray, max_cells: float) -> np.ndarray:
    """Cells of the 8-connected obstacle pieces smaller than ``max_cells`` (the map's noise)."""
    if max_cells <= 1:
        return np.zeros_like(obstacle)
    count, comp, stats, _ = cv2.connectedComponentsWithStats(obstacle.astype(np.uint8), connectivity=8)
    small = stats[:, cv2.CC_STAT_AREA] < max_cells
    small[0] = False  # the background: the free cells
    return small[comp]


def _building_free(free: np.ndarray, grid: OccupancyGrid, inside: tuple[float, float] | None) -> np.ndarray:
    count, comp = cv2.connectedComponents(free.astype(np.uint8), connectivity=4)
    if inside is not None:
        row, col = grid.world_to_cell(*inside)
        h, w = free.shape
        if 0 <= row < h and 0 <= col < w:
            label = int(comp[row, col])
            if label == 0:  # on an obstacle cell: the nearest free component
                _, (rows, cols) = ndimage.distance_transform_edt(comp == 0, return_indices=True)
                label = int(comp[rows[row, col], cols[row, col]])
            return comp == label if label else free
    edge = set(np.unique(np.concatenate([comp[0], comp[-1], comp[:, 0], comp[:, -1]])).tolist()) - {0}
    inner = free & ~np.isin(comp, list(edge))
    sizes = np.bincount(comp.ravel(), minlength=count)
    sizes[0] = 0
    if not edge or int(inner.sum()) > int(sizes[list(edge)].max()):
        return inner  # a simulated building in free floor that runs off the map
    # a SLAM map cropped to what the robot saw: the building itself reaches the edge; take its
    # largest piece of free space (what is seen through a window or a gap stays out)
    return comp == int(sizes.argmax())


def _regions(grid: OccupancyGrid, labels: np.ndarray) -> list[RoomRegion]:
    res = grid.resolution
    rooms: list[RoomRegion] = []
    for label in range(1, int(labels.max()) + 1):
        region = labels == label
        cells = int(region.sum())
        rows, cols = np.nonzero(region)
        centroid = grid.cell_to_world(int(round(rows.mean())), int(round(cols.mean())))
        cx = grid.origin.x + (cols.mean() + 0.5) * res
        cy = grid.origin.y + (rows.mean() + 0.5) * res
        closed = cv2.morphologyEx(region.astype(np.uint8), cv2.MORPH_CLOSE, np.ones((5, 5), np.uint8))
        contours, _ = cv2.findContours(closed, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
        polygon = np.zeros((0, 2))
        if contours:
            biggest = max(contours, key=cv2.contourArea)
            pts = biggest.reshape(-1, 2).astype(float)
            polygon = np.stack(
                [grid.origin.x + (pts[:, 0] + 0.5) * res, grid.origin.y + (pts[:, 1] + 0.5) * res], axis=1
            )
        del centroid
        rooms.append(
            RoomRegion(
                id=f"room_{label}", polygon=polygon, area=cells * res * res, centroid=(float(cx), float(cy))
            )
        )
    return rooms


def rooms_from_polygons(
    entries: Iterable[dict[str, Any]], grid: OccupancyGrid | None = None
) -> list[RoomRegion]:
    """Rooms from ``{name, type, polygon}`` entries (the world-file ``rooms:`` format)."""
    rooms = []
    for i, entry in enumerate(entries, start=1):
        try:
            polygon = np.array(entry["polygon"], dtype=float).reshape(-1, 2)
        except (KeyError, TypeError, ValueError):
            raise ConfigError(
                f"rooms[{i - 1}]: expected a polygon [[x, y], ...] (at least 3 points), "
                f"found {entry.get('polygon') if isinstance(entry, dict) else entry!r}"
            ) from None
        if len(polygon) < 3:
            raise ConfigError(f"rooms[{i - 1}]: a polygon needs at least 3 points, found {len(polygon)}")
        area, centroid = _area_and_centroid(polygon)
        name = str(entry.get("name") or f"room_{i}")
        room_type = str(entry.get("type") or "unknown").strip().lower().replace(" ", "_")
        rooms.append(
            RoomRegion(
                id=f"room_{i}",
                type=room_type,
                polygon=polygon,
                area=area,
                centroid=centroid,
                name=name,
                type_confidence=1.0 if room_type != "unknown" else 0.0,
            )
        )
    return rooms


def _area_and_centroid(polygon: np.ndarray) -> tuple[float, tuple[float, float]]:
    """Area and centre of mass of a simple polygon (the mean of its corners if it has no area).

    The centre of mass, not the mean of the corners: an L-shaped room, or a wall drawn with more
    points on one side, would put the mean off the room's middle (the anchors' facing reads it).
    """
    x, y = polygon[:, 0], polygon[:, 1]
    xn, yn = np.roll(x, -1), np.roll(y, -1)
    cross = x * yn - xn * y
    signed = 0.5 * float(cross.sum())
    if abs(signed) < 1e-12:
        return 0.0, (float(x.mean()), float(y.mean()))
    cx = float(((x + xn) * cross).sum()) / (6.0 * signed)
    cy = float(((y + yn) * cross).sum()) / (6.0 * signed)
    return abs(signed), (cx, cy)


def load_room_polygons(path: str | Path) -> list[RoomRegion]:
    """Read room polygons from a YAML or JSON file (a list, or a mapping with ``rooms:``).

    Raises:
        ConfigError: The file is missing or not in that shape (says what was found).
    """
    target = Path(path)
    text = read_input_text(target, MAX_ROOMS_BYTES, "room polygon file", "room polygons are YAML or JSON",
                           ConfigError)
    try:
        data = json.loads(text) if target.suffix == ".json" else yaml.safe_load(text)
    except (json.JSONDecodeError, yaml.YAMLError) as exc:
        raise ConfigError(
            f"{target}: not valid {'JSON' if target.suffix == '.json' else 'YAML'}: {exc}"
        ) from None
    if isinstance(data, dict):
        data = data.get("rooms")
    if not isinstance(data, list) or not data:
        raise ConfigError(
            f"{target}: expected a list of rooms ({{name, type, polygon}}) or a mapping with "
            "'rooms:', found none"
        )
    try:
        return rooms_from_polygons(data)
    except ConfigError as exc:
        raise ConfigError(f"{target}: {exc}") from None


def polygon_segmentation(grid: OccupancyGrid, rooms: Sequence[RoomRegion]) -> Segmentation:
    """A :class:`Segmentation` of ``grid`` whose labels come from room polygons."""
    labels = np.zeros(np.asarray(grid.data).shape, np.int32)
    res = grid.resolution
    for i, room in enumerate(rooms, start=1):
        pts = ((room.polygon - [grid.origin.x, grid.origin.y]) / res * 16).astype(np.int32)
        canvas = np.zeros_like(labels, dtype=np.uint8)
        cv2.fillPoly(canvas, [pts], 1, cv2.LINE_8, shift=4)
        labels[(canvas > 0) & (labels == 0)] = i
    return Segmentation(grid, labels, list(rooms))


class RoomTracker:
    """Keeps room ids (and types) stable while the map grows and is segmented again."""

    def __init__(self, params: SegmentationParams | None = None, min_overlap: float = 0.3) -> None:
        self.params = params or SegmentationParams()
        self.min_overlap = min_overlap
        self.current: Segmentation | None = None
        self._next = 1

    def update(self, grid: OccupancyGrid, inside: tuple[float, float] | None = None) -> Segmentation:
        """Segment ``grid``; rename its rooms after the previous segmentation's where they overlap."""
        return self.adopt(segment_rooms(grid, self.params, inside=inside))

    def adopt(self, fresh: Segmentation) -> Segmentation:
        """Take a new segmentation, its rooms renamed after the previous one's where they overlap."""
        old = self.current
        renamed: dict[int, RoomRegion] = {}
        if old is not None and old.rooms:
            overlap = _overlaps(old, fresh)
            used: set[int] = set()
            for new_label, row in sorted(overlap.items(), key=lambda kv: -max(kv[1].values(), default=0)):
                for old_label, share in sorted(row.items(), key=lambda kv: -kv[1]):
                    if share >= self.min_overlap and old_label not in used:
                        prev = old.rooms[old_label - 1]
                        room = fresh.rooms[new_label - 1]
                        room.id, room.type, room.name = prev.id, prev.type, prev.name
                        room.type_confidence, room.evidence = prev.type_confidence, list(prev.evidence)
                        renamed[new_label] = room
                        used.add(old_label)
                        break
        for label, room in enumerate(fresh.rooms, start=1):
            if label not in renamed:
                while f"room_{self._next}" in {r.id for r in fresh.rooms if r is not room} | _ids(old):
                    self._next += 1
                room.id = f"room_{self._next}"
                self._next += 1
        self.current = fresh
        return fresh


def _ids(seg: Segmentation | None) -> set[str]:
    return {r.id for r in seg.rooms} if seg is not None else set()


def _overlaps(old: Segmentation, new: Segmentation) -> dict[int, dict[int, float]]:
    """New label → {old label: share of the new region's cells that had it}, on the new grid."""
    g_old, g_new = old.grid, new.grid
    h, w = new.labels.shape
    rows, cols = np.mgrid[0:h, 0:w]
    xs = g_new.origin.x + (cols + 0.5) * g_new.resolution
    ys = g_new.origin.y + (rows + 0.5) * g_new.resolution
    orow = np.floor((ys - g_old.origin.y) / g_old.resolution).astype(int)
    ocol = np.floor((xs - g_old.origin.x) / g_old.resolution).astype(int)
    oh, ow = old.labels.shape
    inside = (orow >= 0) & (orow < oh) & (ocol >= 0) & (ocol < ow)
    old_on_new = np.zeros_like(new.labels)
    old_on_new[inside] = old.labels[orow[inside], ocol[inside]]
    # every (new, old) pair counted in one pass, not one pass over the map per new room
    labelled = new.labels > 0
    width = int(old_on_new.max()) + 1
    pairs = np.bincount(new.labels[labelled].astype(np.int64) * width + old_on_new[labelled],
                        minlength=(int(new.labels.max()) + 1) * width).reshape(-1, width)
    result: dict[int, dict[int, float]] = {}
    for label in range(1, pairs.shape[0]):
        total = int(pairs[label].sum())
        if not total:
            continue
        result[label] = {int(o): float(c) / total for o, c in enumerate(pairs[label]) if o > 0 and c > 0}
    return result
