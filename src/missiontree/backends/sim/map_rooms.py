"""Rooms for a world on a real map: its free space segmented at doors, open floors cut into zones, typed.

:func:`rooms_from_map` is what :func:`missiontree.backends.sim.placement.place_objects` gives a world
without rooms. Each room and zone is worked on in its bounding box (a real map holds millions of
cells and a hundred rooms); the segmentation of a map is kept for the process.
"""

from __future__ import annotations

import copy
import hashlib
import math
from typing import Any

import cv2
import numpy as np

from missiontree.backends.sim.world import World
from missiontree.mapping.occupancy import BLOCKED_FROM
from missiontree.types import OccupancyGrid

#: Room types handed to rooms that have none (rooms found on a real map), after the largest.
SEGMENTED_TYPES = ["kitchen", "office", "bedroom", "bathroom", "storage", "living room", "hall"]


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
    _, comp = cv2.connectedComponents(((data >= 0) & (data < BLOCKED_FROM)).astype(np.uint8), connectivity=4)
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
        from scipy import ndimage  # imported on use, as the segmentation: only when a map is segmented

        from missiontree.semantics.rooms import segment_rooms

        seg = segment_rooms(grid, inside=inside)
        res = grid.resolution
        # each room in its bounding box with a margin (no map-sized mask per room or zone)
        masks: list[tuple[np.ndarray, tuple[int, int]]] = []
        for n, bbox in enumerate(ndimage.find_objects(seg.labels), start=1):
            if bbox is None:
                continue
            r0, c0 = max(bbox[0].start - _MARGIN, 0), max(bbox[1].start - _MARGIN, 0)
            region = seg.labels[r0 : bbox[0].stop + _MARGIN, c0 : bbox[1].stop + _MARGIN] == n
            area = float(region.sum()) * res * res
            parts = _zones(region, res) if area > 2 * ZONE_AREA else [(region, (0, 0))]
            masks += [(m, (r0 + dr, c0 + dc)) for m, (dr, dc) in parts]
        masks.sort(key=lambda m: -int(m[0].sum()))
        found = []
        for mask, corner in masks:
            poly = _outline(mask, grid, corner)
            if poly is not None:
                found.append((poly, float(mask.sum()) * res * res))
        if len(_PIECES) > 32:
            _PIECES.clear()
        _PIECES[key] = found
    return copy.deepcopy(_PIECES[key])


#: Open floors (a segmented room over twice this, m²) are cut into zones of about this area.
ZONE_AREA = 60.0
#: Cells kept round a room's bounding box: its outline's closing (5 x 5) sees what it would on the map.
_MARGIN = 6


def _zones(region: np.ndarray, res: float) -> list[tuple[np.ndarray, tuple[int, int]]]:
    """``region`` cut into zones of about :data:`ZONE_AREA`: cells to the nearest of seeds on a grid.

    Each zone is a mask of its bounding box with :data:`_MARGIN` and that box's corner (row,
    column) in ``region``.
    """
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
    from scipy import ndimage  # imported on use: a mission on a shipped world never needs it

    _, (ir, ic) = ndimage.distance_transform_edt(~seeds, return_indices=True)
    owner = ir * region.shape[1] + ic
    # zone k + 1 per cell, zones in the order of their seeds' keys; each cut out in its own box
    keys, index = np.unique(owner[region], return_inverse=True)
    labels = np.zeros(region.shape, np.int32)
    labels[region] = index.ravel() + 1
    zones = []
    for k, bbox in enumerate(ndimage.find_objects(labels, max_label=len(keys)), start=1):
        if bbox is None:
            continue
        r0, c0 = max(bbox[0].start - _MARGIN, 0), max(bbox[1].start - _MARGIN, 0)
        zone = labels[r0 : bbox[0].stop + _MARGIN, c0 : bbox[1].stop + _MARGIN] == k
        if float(zone.sum()) * res * res >= 3.0:
            zones.append((zone, (r0, c0)))
    return zones


def _outline(mask: np.ndarray, grid: OccupancyGrid, corner: tuple[int, int] = (0, 0)
             ) -> list[list[float]] | None:
    """The outline of a mask's largest piece as a polygon simplified to 10 cm (None if too small).

    ``mask`` covers the grid's cells from ``corner`` (row, column) on.
    """
    res = grid.resolution
    closed = cv2.morphologyEx(mask.astype(np.uint8), cv2.MORPH_CLOSE, np.ones((5, 5), np.uint8))
    contours, _ = cv2.findContours(closed, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE,
                                   offset=(corner[1], corner[0]))
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
