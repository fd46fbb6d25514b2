"""The watershed that grows room cores into rooms, and the merges after it (for :mod:`.rooms`).

Pure array work on label images: cores found at a clearance radius are flooded level by level down
the clearance (so boundaries fall in doors), neighbours meeting in the open are joined, and regions
too small to be rooms join the neighbour they share most border with.
"""

from __future__ import annotations

import cv2
import numpy as np
from scipy import ndimage


def late_cores(
    markers: np.ndarray,
    small: np.ndarray,
    clearance: np.ndarray,
    radius: float,
    min_radius: float,
    step: float,
    core_cells: tuple[float, float],
) -> np.ndarray:
    """Cores for rooms whose middle was too cluttered to give one at the chosen radius.

    A small room full of furniture shows at the chosen radius only as a piece too small to be a
    core (``small``); without a core of its own it is flooded from its neighbour through the door
    and becomes part of it. Going down in radius from the chosen one, a piece that holds such a
    small piece, no core, and is core-sized (``core_cells``) becomes a core. Pieces without a small
    piece at the chosen radius (gaps between furniture, which show only at lower radii) do not.
    """
    markers = markers.copy()
    low, high = core_cells
    r = radius - step
    while r >= min_radius - 1e-9:
        count, comp = cv2.connectedComponents((clearance > r).astype(np.uint8), connectivity=8)
        sizes = np.bincount(comp.ravel(), minlength=count)
        cored = np.zeros(count, bool)
        cored[comp[markers > 0]] = True  # a mark per piece (no sort of millions of cells)
        seeded = np.zeros(count, bool)
        seeded[comp[small]] = True
        seeded[0] = False
        for piece in np.flatnonzero(seeded & ~cored & (sizes >= low) & (sizes <= high)):
            markers[comp == piece] = int(markers.max()) + 1
        r -= step
    return markers


def drop_small_cores(markers: np.ndarray, min_cells: float) -> np.ndarray:
    """Renumber the cores 1..n in label order, leaving out those under ``min_cells`` cells."""
    sizes = np.bincount(markers.ravel())
    keep = np.flatnonzero(sizes >= max(min_cells, 1))
    keep = keep[keep > 0]
    out = np.zeros_like(markers)
    for i, old in enumerate(keep, start=1):
        out[markers == old] = i
    return out.astype(np.int32)


def flood(markers: np.ndarray, clearance: np.ndarray, free: np.ndarray, step: float) -> np.ndarray:
    """Grow the cores over the free cells by a watershed on the clearance, so boundaries fall in doors.

    The free cells are flooded level by level, from the clearest down in ``step`` metres; at each
    level the labelled regions grow (breadth-first, see :func:`wave`) over the cells at least that
    clear. A door is the least clear place between two rooms: both rooms are filled before the
    water reaches it, and their boundary lies in it. (Growing by geodesic distance alone put the
    boundary wherever the two cores were equally far, often a metre into the room whose core lay
    farther from the door, where the floor is open, and the rooms were then merged.)
    """
    labels = markers.astype(np.int32).copy()
    labels[~free] = 0
    if labels.max() == 0:
        count, comp = cv2.connectedComponents(free.astype(np.uint8), connectivity=8)
        return comp.astype(np.int32)
    level = float(clearance[free].max())
    while level > 0.0:
        level = max(level - step, 0.0)
        wave(labels, free & (clearance >= level) & (labels == 0))
    return labels


def grow(markers: np.ndarray, free: np.ndarray) -> np.ndarray:
    """Grow the labelled regions over the free cells, each cell to the geodesically nearest region."""
    labels = markers.astype(np.int32).copy()
    labels[~free] = 0
    if labels.max() == 0:
        count, comp = cv2.connectedComponents(free.astype(np.uint8), connectivity=8)
        return comp.astype(np.int32)
    wave(labels, free & (labels == 0))
    return labels


def wave(labels: np.ndarray, open_cells: np.ndarray) -> None:
    """Label ``open_cells`` reached from the labelled cells, in place, one 4-connected step at a time.

    A breadth-first wave from every region at once; a cell reached by several regions in the same
    step takes the highest label (as a grey dilation would, step after step, but without
    redrawing the whole map at each of hundreds of steps on a real map). Open cells no region
    reaches (the outside of a building, a pocket) stay unlabelled.

    Works within the open cells' box grown by a cell (the wave never leaves the open cells, and
    its sources touch them): at the watershed's high levels a few cells, not the whole map.
    """
    rows = np.flatnonzero(open_cells.any(axis=1))
    if not rows.size:
        return
    cols = np.flatnonzero(open_cells.any(axis=0))
    h, w = labels.shape
    window = (slice(max(int(rows[0]) - 1, 0), min(int(rows[-1]) + 2, h)),
              slice(max(int(cols[0]) - 1, 0), min(int(cols[-1]) + 2, w)))
    if labels[window].size < labels.size:
        part = np.ascontiguousarray(labels[window])
        _wave_in(part, open_cells[window])
        labels[window] = part
    else:
        _wave_in(labels, open_cells)


def _wave_in(labels: np.ndarray, open_cells: np.ndarray) -> None:
    """:func:`wave` on a contiguous ``labels`` (written in place through a flat view)."""
    h, w = labels.shape
    flat = labels.reshape(-1)  # a view: writing flat writes labels
    todo = open_cells.reshape(-1).copy()
    cross = np.array([[0, 1, 0], [1, 1, 1], [0, 1, 0]], np.uint8)
    touching = cv2.dilate(open_cells.astype(np.uint8), cross).reshape(-1).astype(bool)
    front = np.flatnonzero((flat > 0) & touching)
    while front.size:
        row, col = np.divmod(front, w)
        label = flat[front]
        steps = (
            (row > 0, -w),
            (row < h - 1, w),
            (col > 0, -1),
            (col < w - 1, 1),
        )
        cells = np.concatenate([front[ok] + step for ok, step in steps])
        values = np.concatenate([label[ok] for ok, _ in steps])
        reach = todo[cells]
        cells, values = cells[reach], values[reach]
        if not cells.size:
            break
        order = np.lexsort((values, cells))  # by cell, its highest label last
        cells, values = cells[order], values[order]
        last = np.concatenate((cells[1:] != cells[:-1], [True]))
        front, label = cells[last], values[last]
        flat[front] = label
        todo[front] = False


def merge_open(labels: np.ndarray, clearance: np.ndarray, max_door_width: float) -> np.ndarray:
    """Join neighbours that meet in the open rather than in a door.

    A door or narrow passage has walls on both sides: along the border between two rooms no free
    cell is farther than half a door's width from an obstacle. Furniture in the middle of a room
    splits it into pieces that meet on open floor (far from any obstacle), or along several
    stretches (on both sides of a table).
    """
    labels = labels.copy()
    kernel = np.ones((3, 3), np.uint8)
    merged = True
    while merged:
        merged = False
        boxes = ndimage.find_objects(labels)
        for a in _present(labels):
            # the region's box grown by a cell holds its dilation: work there, not on the whole map
            window = padded(boxes[a - 1], labels.shape, 1)
            near = labels[window]
            grown = cv2.dilate((near == a).astype(np.uint8), kernel).astype(bool)
            for b in sorted(set(np.unique(near[grown]).tolist()) - {0, a}):
                border = grown & (near == b)
                count, comp, stats, _ = cv2.connectedComponentsWithStats(
                    border.astype(np.uint8), connectivity=8
                )
                stretches = [i for i in range(1, count) if stats[i][cv2.CC_STAT_AREA] >= 5]
                if not stretches:
                    continue
                open_floor = float(clearance[window][border].max()) > max_door_width / 2.0
                if len(stretches) > 1 or open_floor:
                    labels[labels == b] = a
                    merged = True
                    break
            if merged:
                break
    return labels


def merge_small(labels: np.ndarray, min_cells: float) -> np.ndarray:
    """Join regions under ``min_cells`` to the neighbour they share most border with; renumber."""
    labels = labels.copy()
    changed = True
    while changed:
        changed = False
        sizes = np.bincount(labels.ravel())
        boxes = ndimage.find_objects(labels)
        for label in np.argsort(sizes):
            if label == 0 or sizes[label] == 0 or sizes[label] >= min_cells:
                continue
            window = padded(boxes[label - 1], labels.shape, 2)  # holds the 5 x 5 ring
            near = labels[window]
            region = near == label
            ring = cv2.dilate(region.astype(np.uint8), np.ones((5, 5), np.uint8)).astype(bool) & ~region
            around = near[ring]
            around = around[(around > 0) & (around != label)]
            if around.size == 0:
                continue
            labels[labels == label] = int(np.bincount(around).argmax())
            changed = True
            break
    out = np.zeros_like(labels)
    for i, old in enumerate(_present(labels), start=1):
        out[labels == old] = i
    return out


def padded(box: tuple[slice, slice], shape: tuple[int, ...], pad: int) -> tuple[slice, slice]:
    """``box`` (from ``ndimage.find_objects``) grown by ``pad`` cells on each side, within ``shape``."""
    rows, cols = box
    return (
        slice(max(rows.start - pad, 0), min(rows.stop + pad, shape[0])),
        slice(max(cols.start - pad, 0), min(cols.stop + pad, shape[1])),
    )


def _present(labels: np.ndarray) -> list[int]:
    """The labels above 0 that occur in ``labels`` (non-negative), ascending: a count, not a sort."""
    return [int(v) for v in np.flatnonzero(np.bincount(labels.ravel())[1:]) + 1]
