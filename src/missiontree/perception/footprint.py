"""What several views tell about one object: its footprint's centre, whether it stands out, its size.

Helpers of :mod:`missiontree.semantics.fusion`, pure functions of frames, boxes and numbers:

- :func:`surface_cells` / :func:`outline_centre`: depth sees only an object's near face, so the
  centre of a large one (a sofa seen end-on places its near face a metre before its centre) comes
  from the outline of the surface points several views saw, fitted with the smallest rectangle;
- :func:`stands_out`: an object is bounded, its box's sides show a depth step to what is beside
  it; a stretch of wall the detector boxed continues flat past the box;
- :data:`SIZE_PRIORS` / :func:`plausible_size`: the least width and height an object of a class
  shows a camera (a tv's screen is at least 0.35 m wide, a closed umbrella 0.1 m);
- :data:`SIZE_LIMITS` / :func:`footprint_sides` / :func:`size_likelihood`: the largest an object of a
  class is, the footprint several views outline, and how well a class explains what was measured
  (a grey bin the detector calls a backpack is 0.35 m deep, deeper than any backpack).
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Sequence

import cv2
import numpy as np

from missiontree.perception.depth import surface_points
from missiontree.perception.projection import Projection
from missiontree.types import RGBDFrame

#: Physical size ranges of common indoor classes, metres: (least width, least height) an object
#: of the class shows a camera from any side it is usually seen from (a tv's screen is at least
#: 0.35 m wide, a closed umbrella is 0.1 m), from furniture catalogues and the COCO classes'
#: everyday sizes, kept generous. A candidate whose median measured width and height (box at its
#: depth) fall below a margin times these is not what the detector named (a thin umbrella called a
#: tv). Classes not listed are not checked.
SIZE_PRIORS: dict[str, tuple[float, float]] = {
    "chair": (0.3, 0.4),
    "sofa": (0.5, 0.4),
    "bed": (0.8, 0.3),
    "table": (0.3, 0.25),
    "dining table": (0.5, 0.4),
    "bottle": (0.03, 0.08),
    "cup": (0.03, 0.04),
    "backpack": (0.15, 0.2),
    "laptop": (0.2, 0.02),
    "umbrella": (0.03, 0.3),
    "potted plant": (0.1, 0.15),
    "tv": (0.35, 0.2),
    "refrigerator": (0.45, 0.5),
    "trash can": (0.15, 0.2),
    "bookshelf": (0.3, 0.5),
}


#: The largest a common indoor object of a class is, metres: (footprint's longer side, footprint's
#: shorter side, height), from furniture catalogues and everyday sizes, kept generous (a backpack is
#: 0.15-0.25 m deep: at most 0.3 here; a trash can up to 0.6 m across, a table 1.2 m deep). A
#: footprint is measured to about a surface cell (5 cm), so a limit is one cell above the
#: catalogues' largest: a real backpack measured 0.29 m deep, a grey bin 0.30-0.35 m. With
#: :data:`SIZE_PRIORS` (the
#: least sizes) they bound the sizes a class is plausible at (:func:`size_likelihood`). Classes not
#: listed are not checked.
SIZE_LIMITS: dict[str, tuple[float, float, float]] = {
    "chair": (0.9, 0.9, 1.3),
    "sofa": (3.2, 1.3, 1.2),
    "bed": (2.4, 2.2, 1.3),
    "table": (2.6, 1.3, 1.2),
    "dining table": (3.0, 1.5, 1.1),
    "bottle": (0.2, 0.2, 0.5),
    "cup": (0.2, 0.2, 0.25),
    "backpack": (0.5, 0.3, 0.7),
    "laptop": (0.5, 0.4, 0.4),
    "umbrella": (1.3, 1.3, 1.3),
    "potted plant": (1.2, 1.2, 2.2),
    "tv": (2.0, 0.5, 1.3),
    "refrigerator": (1.1, 1.0, 2.1),
    "trash can": (0.7, 0.7, 1.1),
    "bookshelf": (2.2, 0.6, 2.5),
}


def footprint_sides(
    cells: Counter[tuple[int, int]], centre: Sequence[float], reach: float, cell: float, views: int = 2
) -> tuple[float, float] | None:
    """(longer, shorter) side of the smallest rectangle round the surface cells near ``centre``.

    Cells seen in at least ``views`` views and within ``reach`` of ``centre`` count; the rectangle
    spans their centres, which measures a side to about a cell either way. None while fewer than 6
    such cells exist.
    One face seen gives a thin rectangle: the shorter side only grows once another face is seen,
    so it never overstates the object's depth.
    """
    keys = [key for key, n in cells.items() if n >= views]
    if len(keys) < 6:
        return None
    pts = (np.array(keys, dtype=float) + 0.5) * cell
    pts = pts[np.hypot(pts[:, 0] - centre[0], pts[:, 1] - centre[1]) <= reach]
    if len(pts) < 6:
        return None
    _, (w, h), _ = cv2.minAreaRect(pts.astype(np.float32))
    return float(max(w, h)), float(min(w, h))


def size_likelihood(label: str, shorter: float, height: float) -> float | None:
    """How likely a class is at a measured footprint's shorter side and height; None: not listed.

    Zero when the footprint's shorter side is wider than the class's largest (:data:`SIZE_LIMITS`),
    or the height is outside its least (:data:`SIZE_PRIORS`) and largest; else one over the volume
    of its range of sizes (longer side from its least width to its largest, shorter side up to its
    largest, height from its least to its largest): a uniform density over the sizes the class
    comes in, so a class of narrowly bounded size (a trash can) that fits explains a measurement
    better than one of almost any size (a table). The longer side is not checked: the surface
    cells of a neighbour seen behind an object lengthen it.
    """
    limits = SIZE_LIMITS.get(label)
    least = SIZE_PRIORS.get(label)
    if limits is None or least is None:
        return None
    if shorter > limits[1] or not least[1] <= height <= limits[2]:
        return 0.0
    volume = max(limits[0] - least[0], 0.05) * limits[1] * max(limits[2] - least[1], 0.05)
    return 1.0 / volume


def plausible_size(label: str, projections: Sequence[Projection], margin: float) -> bool:
    """Whether the median measured width and height reach ``margin`` times the class's least size."""
    prior = SIZE_PRIORS.get(label)
    if prior is None or margin <= 0 or not projections:
        return True
    width = float(np.median([q.size[0] for q in projections]))
    height = float(np.median([q.size[2] for q in projections]))
    return width >= margin * prior[0] and height >= margin * prior[1]


def stands_out(frame: RGBDFrame, box: tuple[float, float, float, float], band: int, step: float) -> bool:
    """Whether the box's object stands out of its surroundings in depth at a side the image does not cut.

    At each side, the median depth of a strip just inside the box (an eighth of its width) is
    compared with a strip ``band`` pixels wide just outside it, over the middle half of its rows;
    a difference above ``step`` metres (or no return beside it at all) means the object ends there.
    """
    depth = np.asarray(frame.depth)
    h, w = depth.shape[:2]
    x1, y1, x2, y2 = (int(round(v)) for v in box)
    top, bottom = max(0, y1 + (y2 - y1) // 4), min(h, y2 - (y2 - y1) // 4)
    if bottom <= top:
        return True
    inset = max(1, (x2 - x1) // 8)
    sides = (((x1 + 1, x1 + inset), (x1 - band, x1 - 1)), ((x2 - inset, x2 - 1), (x2 + 1, x2 + band)))
    for inside, outside in sides:
        if outside[0] < 0 or outside[1] >= w:
            continue  # cut by the image: no evidence at this side
        a = depth[top:bottom, max(0, inside[0]) : max(inside[0] + 1, inside[1])].astype(float)
        b = depth[top:bottom, outside[0] : outside[1] + 1].astype(float)
        a, b = a[np.isfinite(a) & (a > 0)], b[np.isfinite(b) & (b > 0)]
        if not a.size or not b.size:
            return True  # no return beside it: nothing there, it stands out
        if abs(float(np.median(b)) - float(np.median(a))) > step:
            return True
    return False


def surface_cells(
    cells: Counter[tuple[int, int]], frame: RGBDFrame, box: tuple[float, float, float, float], cell: float
) -> None:
    """Count, in ``cells``, the map cells of the surface the box shows (its nearest depth cluster).

    Each cell counts once a view; beyond 4000 cells only the 2000 most often seen are kept.
    """
    points = surface_points(frame, box)
    if not len(points):
        return
    keys = np.unique(np.floor(points / cell).astype(np.int64), axis=0)
    cells.update(map(tuple, keys.tolist()))
    if len(cells) > 4000:
        kept = dict(cells.most_common(2000))
        cells.clear()
        cells.update(kept)


def outline_centre(
    cells: Counter[tuple[int, int]],
    fused: Sequence[float],
    extent: float,
    cell: float,
    exclude: Sequence[tuple[float, float, float]] = (),
    holds_fused: float | None = None,
) -> tuple[float, float] | None:
    """The centre of the footprint the surface cells outline, None while they outline too little.

    Cells seen at least twice and within ``extent / 2 + 0.6`` m of the fused position are fitted
    with the smallest rectangle. Two faces seen (the rectangle has depth): its centre. One face (a
    thin rectangle): the point on the face's perpendicular bisector as far behind it as the fused
    position. A centre more than 1 m from the fused position means the cells hold something else
    too: None. So does, with ``holds_fused``, a rectangle that does not hold the fused position
    (grown by that margin): the fused position lies on the surface the boxes' centres showed, so
    the object's outline holds it; one that does not outlines a neighbour (a desk's cells taken
    from the bookshelf beside it moved its centre 0.7 m onto the bookshelf).

    Args:
        cells: Surface cells and the views that saw each (:func:`surface_cells`).
        fused: The fused position (x, y, ...).
        extent: The object's largest measured width, metres.
        cell: Cell size, metres.
        exclude: Discs (x, y, radius) whose cells are not counted: the surface of other objects
            the boxes held in front of or beside this one (a laptop on the floor before a table).
        holds_fused: Margin, metres, by which the rectangle must hold the fused position; None:
            not checked.
    """
    keys = [key for key, n in cells.items() if n >= 2]
    if len(keys) < 8:
        return None
    pts = (np.array(keys, dtype=float) + 0.5) * cell
    reach = 0.5 * extent + 0.6
    pts = pts[np.hypot(pts[:, 0] - fused[0], pts[:, 1] - fused[1]) <= reach]
    for x, y, radius in exclude:
        pts = pts[np.hypot(pts[:, 0] - x, pts[:, 1] - y) > radius]
    if len(pts) < 8:
        return None
    rect = cv2.minAreaRect(pts.astype(np.float32))
    (cx, cy), (w, h), angle = rect
    if holds_fused is not None:
        grown = cv2.boxPoints(((cx, cy), (w + 2 * holds_fused, h + 2 * holds_fused), angle))
        if cv2.pointPolygonTest(grown.astype(np.float32), (float(fused[0]), float(fused[1])), False) < 0:
            return None
    long_side, short_side = max(w, h), min(w, h)
    if short_side >= max(0.25, 0.3 * long_side):
        centre = (float(cx), float(cy))
    else:
        a = math.radians(angle if w >= h else angle + 90.0)
        normal = (-math.sin(a), math.cos(a))
        t = (fused[0] - cx) * normal[0] + (fused[1] - cy) * normal[1]
        centre = (float(cx + t * normal[0]), float(cy + t * normal[1]))
    if math.hypot(centre[0] - fused[0], centre[1] - fused[1]) > 1.0:
        return None
    return centre
