"""Surface patterns the camera paints on objects' side faces: shelves, doors, a screen, legs.

Every object in the simulator is one upright prism, so without a pattern a white bookshelf and a
white refrigerator, or a black tv and a black table seen face-on, are the same slab of colour
and no detector could tell them apart. A pattern draws what a camera at 40 cm sees of the real
thing on the prism's side faces: a bookshelf's boards and books, a refrigerator's door gap and
handles, a tv's bezel and dark screen, the shadow under a table between its legs, a sofa's seams,
a bottle's cap and label. Only colour changes: depth, the instance mask, the lidar and the map
still see the whole prism.

An object's pattern is its world file's ``pattern`` or, when that is not given, the one its label
suggests (:data:`LABEL_PATTERNS`); anything else is drawn plain. The painting is one pass over
the pixels of patterned objects after the frame is rendered (:func:`paint`): a numba pixel loop
when numba is installed, else the vectorised numpy reference.
"""

from __future__ import annotations

import numpy as np

from missiontree.backends.sim.raycast import BOX, CYLINDER, HAVE_NUMBA, Primitives

if HAVE_NUMBA:
    import numba

PLAIN, SHELVES, FRIDGE, DOORS, SCREEN, LEGS, CHAIR, CUSHIONS, BOTTLE, UMBRELLA, PLANT, RIM = range(12)
#: Pattern names and their ids in :attr:`Primitives.pattern` (0 = plain).
PATTERNS: dict[str, int] = {
    "plain": PLAIN, "shelves": SHELVES, "fridge": FRIDGE, "doors": DOORS, "screen": SCREEN, "legs": LEGS,
    "chair": CHAIR, "cushions": CUSHIONS, "bottle": BOTTLE, "umbrella": UMBRELLA, "plant": PLANT, "rim": RIM,
}
#: The pattern a label gets when its object names none.
LABEL_PATTERNS: dict[str, str] = {
    "bookshelf": "shelves", "bookcase": "shelves", "shelf": "shelves", "shelves": "shelves",
    "refrigerator": "fridge", "fridge": "fridge",
    "wardrobe": "doors", "cabinet": "doors", "cupboard": "doors",
    "tv": "screen", "television": "screen", "monitor": "screen",
    "table": "legs", "dining table": "legs", "coffee table": "legs", "desk": "legs", "bench": "legs",
    "stool": "legs",
    "chair": "chair", "armchair": "chair", "office chair": "chair",
    "sofa": "cushions", "couch": "cushions",
    "bottle": "bottle", "umbrella": "umbrella", "potted plant": "plant", "plant": "plant",
    "cup": "rim", "mug": "rim", "trash can": "rim", "bin": "rim", "bucket": "rim",
}

_SCREEN = np.array([18.0, 22.0, 32.0])
_GLOW = np.array([10.0, 14.0, 26.0])       # added to the screen towards its top
_HANDLE = np.array([150.0, 150.0, 156.0])
_POT = np.array([165.0, 88.0, 58.0])
_LABEL = np.array([232.0, 228.0, 214.0])
_UMBRELLA_HANDLE = np.array([62.0, 42.0, 30.0])
_BOOKS = np.array([[150, 40, 40], [40, 70, 130], [200, 170, 70], [50, 110, 60], [220, 215, 200],
                   [110, 60, 110], [190, 110, 50], [60, 60, 60]], np.float64)
_SIDE_EPS = 1e-3   # a point this close to a prism's wall (m), and not on its top or bottom, is on a side


def pattern_for(label: str, pattern: str | None) -> int:
    """The pattern id an object gets: its own ``pattern``, else its label's, else plain."""
    name = pattern if pattern is not None else LABEL_PATTERNS.get(label.strip().lower(), "plain")
    return PATTERNS[name]


def paint(color: np.ndarray, depth: np.ndarray, instances: np.ndarray, origin: tuple[float, float, float],
          dx: np.ndarray, dy: np.ndarray, b: np.ndarray, prims: Primitives,
          accelerate: bool = True) -> np.ndarray:
    """Paint the patterned objects' side faces of a rendered frame (``color`` is changed in place).

    Args:
        color: (H, W, 3) uint8 frame as rendered.
        depth: (H, W) depth along the optical axis (NaN where unknown: those pixels stay as drawn).
        instances: (H, W) instance id per pixel.
        origin: Camera (x, y, height).
        dx: (W,) x of each column's ray direction per metre of depth; ``dy`` likewise.
        dy: (W,) y of the same.
        b: (H,) rise of each row's ray per metre of depth.
        prims: The primitives the frame was rendered from.
        accelerate: Use the numba loops when numba is installed (same result as numpy, to a unit of
            colour).

    Returns:
        ``color``.
    """
    if prims.pattern is None or not (prims.pattern > 0).any():
        return color
    rows = np.flatnonzero(prims.pattern > 0)
    lut = np.full(max(int(instances.max(initial=0)), int(prims.inst.max(initial=0))) + 1, -1, np.int64)
    lut[prims.inst[rows]] = rows
    if accelerate and HAVE_NUMBA:
        _paint_jit(color, depth, instances, origin[0], origin[1], origin[2], np.ascontiguousarray(dx),
                   np.ascontiguousarray(dy), np.ascontiguousarray(b), lut, prims.kind, prims.geom, prims.z,
                   prims.rgb, prims.pattern, _BOOKS)
        return color
    return _paint_numpy(color, depth, lut[instances], origin, dx, dy, b, prims)


def _paint_numpy(color: np.ndarray, depth: np.ndarray, row: np.ndarray, origin: tuple[float, float, float],
                 dx: np.ndarray, dy: np.ndarray, b: np.ndarray, prims: Primitives) -> np.ndarray:
    """:func:`paint`'s numpy reference; ``row`` is each pixel's primitive (-1: none patterned)."""
    vs, us = np.nonzero((row >= 0) & np.isfinite(depth))
    if len(vs) == 0:
        return color
    p = row[vs, us]
    t = depth[vs, us].astype(np.float64)
    ox, oy, hc = origin
    x, y, z = ox + t * dx[us], oy + t * dy[us], hc + t * b[vs]
    z0, z1 = prims.z[p, 0], prims.z[p, 1]
    height, zr = z1 - z0, z - z0
    s, width, cos, long, side = _side_faces(prims, p, x, y, dx[us], dy[us])
    side &= (zr > 1e-4) & (zr < height - 1e-4)
    if not side.any():
        return color
    keep = np.flatnonzero(side)
    base = prims.rgb[p[keep]]
    assert prims.pattern is not None  # paint() returned early without patterns
    out = _pattern_rgb(prims.pattern[p[keep]], base, s[keep], width[keep], zr[keep], height[keep], long[keep])
    shade = (0.55 + 0.45 * cos[keep])[:, None]
    color[vs[keep], us[keep]] = np.clip(out * shade, 0, 255).astype(np.uint8)
    return color


def _side_faces(prims: Primitives, p: np.ndarray, x: np.ndarray, y: np.ndarray, ddx: np.ndarray,
                ddy: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Where points (x, y) of primitives ``p`` lie on their side faces, seen along rays (ddx, ddy).

    Returns (s along the face, the face's width, cosine of the view to its normal, long face, on
    a side face).
    """
    g = prims.geom[p]
    dlen = np.hypot(ddx, ddy)
    s = np.zeros_like(x)
    width = np.ones_like(x)
    cos = np.ones_like(x)
    long = np.ones(len(x), bool)
    side = np.zeros(len(x), bool)
    box = prims.kind[p] == BOX
    if box.any():
        c, sn, hx, hy = g[box, 2], g[box, 3], g[box, 4], g[box, 5]
        rx, ry = x[box] - g[box, 0], y[box] - g[box, 1]
        qx, qy = c * rx + sn * ry, -sn * rx + c * ry
        gap_x, gap_y = np.abs(np.abs(qx) - hx), np.abs(np.abs(qy) - hy)
        on_x = gap_x <= gap_y                      # the face at local x = +-hx (spanned by y)
        s[box] = np.where(on_x, np.where(qx > 0, hy - qy, qy + hy), np.where(qy > 0, qx + hx, hx - qx))
        width[box] = np.where(on_x, 2 * hy, 2 * hx)
        long[box] = np.where(on_x, hy >= hx - 1e-9, hx >= hy - 1e-9)
        lx, ly = c * ddx[box] + sn * ddy[box], -sn * ddx[box] + c * ddy[box]
        cos[box] = np.where(on_x, np.abs(lx), np.abs(ly)) / dlen[box]
        side[box] = np.minimum(gap_x, gap_y) < _SIDE_EPS
    cyl = prims.kind[p] == CYLINDER
    if cyl.any():
        rx, ry, r = x[cyl] - g[cyl, 0], y[cyl] - g[cyl, 1], g[cyl, 2]
        dist = np.hypot(rx, ry)
        s[cyl] = r * np.mod(np.arctan2(ry, rx), 2 * np.pi)
        width[cyl] = 2 * np.pi * r
        cos[cyl] = np.abs(rx * ddx[cyl] + ry * ddy[cyl]) / (np.maximum(dist, 1e-9) * dlen[cyl])
        side[cyl] = np.abs(dist - r) < _SIDE_EPS
    return s, width, cos, long, side


def _hash(a, c):  # noqa: ANN001, ANN202 - arrays (numpy reference) or floats (numba loop)
    """A repeatable pseudo-random number in [0, 1) per pair of whole numbers ``a``, ``c``."""
    return (np.sin(a * 12.9898 + c * (12.9898 + 65.233)) * 43758.5453) % 1.0


class _Shading:
    """Colours (N, 3) and brightness factors (N,) of side-face points, as the patterns paint them."""

    def __init__(self, base: np.ndarray) -> None:
        self.out = base.copy()
        self.m = np.ones(len(base))

    def mult(self, mask: np.ndarray, factor: float | np.ndarray) -> None:
        """Darken (or lighten) the points of ``mask`` by ``factor``."""
        self.m[mask] = (factor[mask] if isinstance(factor, np.ndarray) else factor)

    def over(self, mask: np.ndarray, rgb: np.ndarray) -> None:
        """Paint the points of ``mask`` in ``rgb`` (one colour, or one a point), unshaded."""
        self.out[mask] = rgb[mask] if rgb.ndim == 2 else rgb
        self.m[mask] = 1.0


# Each painter below: (shading, points of its pattern, s along the face, face width w, z above the
# bottom, height h, long face, distance to the face's nearer edge).
_Arrays = np.ndarray


def _shelves(sh: _Shading, q: _Arrays, s: _Arrays, w: _Arrays, z: _Arrays, h: _Arrays, long: _Arrays,
             edge: _Arrays) -> None:
    """Shelves: a frame, boards every ~36 cm, books in the compartments (long faces only)."""
    q = q & long
    if not q.any():
        return
    frame = 0.035
    n = np.maximum(2, np.round((h - 2 * frame) / 0.36))
    pitch = (h - 2 * frame) / n
    level = np.floor((z - frame) / pitch)
    inner_z = z - frame - level * pitch             # height within the compartment
    board = inner_z < 0.025
    inside = q & (edge > frame) & (z > frame) & (z < h - frame) & ~board
    sh.mult(inside, 0.42)
    book = np.floor((s - frame) / 0.045).astype(np.int64)
    chance = _hash(book.astype(np.float64), level)
    tall = 0.6 + 0.3 * _hash(book + 7.0, level)
    books = inside & (chance > 0.18) & (inner_z < tall * pitch) & (np.mod(s - frame, 0.045) > 0.004)
    sh.over(books, _BOOKS[(chance * 1000).astype(np.int64) % len(_BOOKS)] * (0.7 + 0.3 * tall[:, None]))


def _fridge(sh: _Shading, q: _Arrays, s: _Arrays, w: _Arrays, z: _Arrays, h: _Arrays, long: _Arrays,
            edge: _Arrays) -> None:
    """Refrigerator: a freezer door gap and two handles."""
    split = 0.68 * h
    sh.mult(q & (np.abs(z - split) < 0.008), 0.5)
    bar = q & (s > w - 0.085) & (s < w - 0.055)
    sh.over(bar & (z > split + 0.05) & (z < split + 0.05 + np.minimum(0.25, 0.5 * (h - split))), _HANDLE)
    sh.over(bar & (z < split - 0.06) & (z > split - 0.06 - np.minimum(0.45, 0.5 * split)), _HANDLE)
    sh.mult(q & (z < 0.05), 0.55)


def _doors(sh: _Shading, q: _Arrays, s: _Arrays, w: _Arrays, z: _Arrays, h: _Arrays, long: _Arrays,
           edge: _Arrays) -> None:
    """Wardrobe, cabinet: two doors, two knobs, a plinth."""
    ql = q & long
    sh.mult(ql & (np.abs(s - w / 2) < 0.006), 0.5)
    sh.mult(ql & (np.abs(np.abs(s - w / 2) - 0.06) < 0.015) & (np.abs(z - 0.5 * h) < 0.015), 0.45)
    sh.mult(q & (z < 0.06), 0.55)


def _screen(sh: _Shading, q: _Arrays, s: _Arrays, w: _Arrays, z: _Arrays, h: _Arrays, long: _Arrays,
            edge: _Arrays) -> None:
    """Tv, monitor: a bezel round a dark screen, brighter towards its top (long faces only)."""
    q = q & long
    if not q.any():
        return
    bezel = np.minimum(0.035, 0.1 * w)
    screen = q & (edge > bezel) & (z > bezel) & (z < h - bezel)
    glow = (z / np.maximum(h, 1e-6))[:, None] * _GLOW
    sh.over(screen, _SCREEN + glow)


def _legs(sh: _Shading, q: _Arrays, s: _Arrays, w: _Arrays, z: _Arrays, h: _Arrays, long: _Arrays,
          edge: _Arrays) -> None:
    """Table, desk, bench: a top, legs at the ends, shadow between them under the top."""
    top = np.minimum(0.05, 0.15 * h)
    under = q & (z < h - top) & (edge > 0.05)
    sh.mult(under, 0.3)
    sh.mult(under & (z > h - top - 0.06) & long, 0.75)   # the apron below the top


def _chair(sh: _Shading, q: _Arrays, s: _Arrays, w: _Arrays, z: _Arrays, h: _Arrays, long: _Arrays,
           edge: _Arrays) -> None:
    """Chair: legs under a seat, a gap, a backrest."""
    seat = 0.45 * h
    sh.mult(q & (z < seat - 0.04) & (edge > 0.045), 0.3)
    sh.mult(q & (z > seat) & (z < seat + 0.1) & (edge > 0.04), 0.45)
    sh.mult(q & (z >= seat + 0.1) & (edge > 0.04), 0.85)


def _cushions(sh: _Shading, q: _Arrays, s: _Arrays, w: _Arrays, z: _Arrays, h: _Arrays, long: _Arrays,
              edge: _Arrays) -> None:
    """Sofa: a dark plinth, the seat's front, a seam, back cushions between the armrests."""
    arm = np.minimum(0.2, 0.12 * w)
    seat = 0.45 * h
    sh.mult(q & (z < 0.06), 0.35)
    sh.mult(q & long & (z >= 0.06) & (z < seat), 0.85)
    sh.mult(q & long & (np.abs(z - seat) < 0.012), 0.5)
    n = np.maximum(1, np.round((w - 2 * arm) / 0.6))
    cushion = np.mod(s - arm, (w - 2 * arm) / n)
    seams = (np.minimum(cushion, (w - 2 * arm) / n - cushion) < 0.01) | (np.abs(edge - arm) < 0.01)
    sh.mult(q & long & (z > seat) & (edge >= arm - 0.01) & seams, 0.55)


def _bottle(sh: _Shading, q: _Arrays, s: _Arrays, w: _Arrays, z: _Arrays, h: _Arrays, long: _Arrays,
            edge: _Arrays) -> None:
    """Bottle: a dark cap, a lighter neck, a paper label."""
    sh.mult(q & (z > 0.92 * h), 0.45)
    sh.mult(q & (z > 0.72 * h) & (z <= 0.92 * h), 0.8)
    sh.over(q & (z > 0.3 * h) & (z < 0.58 * h), _LABEL)


def _umbrella(sh: _Shading, q: _Arrays, s: _Arrays, w: _Arrays, z: _Arrays, h: _Arrays, long: _Arrays,
              edge: _Arrays) -> None:
    """Umbrella, furled: a wooden handle, a metal tip, panel seams, a strap."""
    sh.mult(q & (np.mod(s, w / 8) < 0.006), 0.6)
    sh.mult(q & (np.abs(z - 0.5 * h) < 0.02), 0.7)
    sh.over(q & (z < 0.12 * h), _UMBRELLA_HANDLE)
    sh.over(q & (z > 0.95 * h), _HANDLE)


def _plant(sh: _Shading, q: _Arrays, s: _Arrays, w: _Arrays, z: _Arrays, h: _Arrays, long: _Arrays,
           edge: _Arrays) -> None:
    """Potted plant: a terracotta pot, leaves of varying light."""
    leaves = q & (z >= 0.38 * h)
    sh.mult(leaves, 0.7 + 0.55 * _hash(np.floor(s / 0.05), np.floor(z / 0.05)))
    sh.over(q & (z < 0.38 * h), _POT)


def _rim(sh: _Shading, q: _Arrays, s: _Arrays, w: _Arrays, z: _Arrays, h: _Arrays, long: _Arrays,
         edge: _Arrays) -> None:
    """Cup, bin: a rim."""
    sh.mult(q & (z > h - np.minimum(0.02, 0.12 * h)), 0.7)


#: The numpy painters by pattern id, in the order they paint.
_PAINTERS = {SHELVES: _shelves, FRIDGE: _fridge, DOORS: _doors, SCREEN: _screen, LEGS: _legs, CHAIR: _chair,
             CUSHIONS: _cushions, BOTTLE: _bottle, UMBRELLA: _umbrella, PLANT: _plant, RIM: _rim}


def _pattern_rgb(pattern: np.ndarray, base: np.ndarray, s: np.ndarray, w: np.ndarray, z: np.ndarray,
                 h: np.ndarray, long: np.ndarray) -> np.ndarray:
    """Unshaded colour (N, 3) of side-face points at ``s`` along faces ``w`` wide, ``z`` above the bottom."""
    shading = _Shading(base)
    edge = np.minimum(s, w - s)
    for pattern_id, painter in _PAINTERS.items():
        q = pattern == pattern_id
        if q.any():
            painter(shading, q, s, w, z, h, long, edge)
    return shading.out * shading.m[:, None]


# -- numba ---------------------------------------------------------------------------------------
# The same painting pixel by pixel, compiled by numba when it is installed (extra `accel`); the
# numpy version above is the reference (tests/backends/sim/test_sim_patterns.py keeps them equal).


def _pixel_rgb(pattern, base, s, w, z, h, long, books):  # noqa: ANN001, ANN202
    """Unshaded colour of one side-face point; see :func:`_pattern_rgb`."""
    if pattern <= SCREEN:
        r, g, bl, m = _pixel_cabinets(pattern, base[0], base[1], base[2], s, w, z, h, long, books)
    elif pattern <= CUSHIONS:
        r, g, bl, m = _pixel_seats(pattern, base[0], base[1], base[2], s, w, z, h, long)
    else:
        r, g, bl, m = _pixel_small(pattern, base[0], base[1], base[2], s, w, z, h)
    return r * m, g * m, bl * m


def _pixel_cabinets(pattern, r, g, bl, s, w, z, h, long, books):  # noqa: ANN001, ANN202, C901, PLR0912, PLR0913
    """Colour (r, g, bl) and brightness factor of a point of shelves, a fridge, doors or a screen."""
    m = 1.0
    edge = min(s, w - s)
    if pattern == SHELVES and long:
        frame = 0.035
        n = max(2.0, np.round((h - 2 * frame) / 0.36))
        pitch = (h - 2 * frame) / n
        level = np.floor((z - frame) / pitch)
        inner_z = z - frame - level * pitch
        if edge > frame and frame < z < h - frame and not inner_z < 0.025:
            m = 0.42
            book = np.floor((s - frame) / 0.045)
            chance = _hash_one(book, level)
            tall = 0.6 + 0.3 * _hash_one(book + 7, level)
            if chance > 0.18 and inner_z < tall * pitch and (s - frame) % 0.045 > 0.004:
                k = int(chance * 1000) % len(books)
                r, g, bl = books[k, 0] * (0.7 + 0.3 * tall), books[k, 1] * (0.7 + 0.3 * tall), books[k, 2] * (
                    0.7 + 0.3 * tall)
                m = 1.0
    elif pattern == FRIDGE:
        split = 0.68 * h
        if abs(z - split) < 0.008:
            m = 0.5
        if w - 0.085 < s < w - 0.055 and (
                split + 0.05 < z < split + 0.05 + min(0.25, 0.5 * (h - split))
                or split - 0.06 - min(0.45, 0.5 * split) < z < split - 0.06):
            r, g, bl, m = _HANDLE[0], _HANDLE[1], _HANDLE[2], 1.0
        if z < 0.05:
            m = 0.55
    elif pattern == DOORS:
        if long and abs(s - w / 2) < 0.006:
            m = 0.5
        if long and abs(abs(s - w / 2) - 0.06) < 0.015 and abs(z - 0.5 * h) < 0.015:
            m = 0.45
        if z < 0.06:
            m = 0.55
    elif pattern == SCREEN and long:
        bezel = min(0.035, 0.1 * w)
        if edge > bezel and bezel < z < h - bezel:
            f = z / max(h, 1e-6)
            r, g, bl, m = _SCREEN[0] + _GLOW[0] * f, _SCREEN[1] + _GLOW[1] * f, _SCREEN[2] + _GLOW[2] * f, 1.0
    return r, g, bl, m


def _pixel_seats(pattern, r, g, bl, s, w, z, h, long):  # noqa: ANN001, ANN202, C901, PLR0912, PLR0913
    """Colour (r, g, bl) and brightness factor of a point of a table's legs, a chair or a sofa."""
    m = 1.0
    edge = min(s, w - s)
    if pattern == LEGS:
        top = min(0.05, 0.15 * h)
        if z < h - top and edge > 0.05:
            m = 0.75 if z > h - top - 0.06 and long else 0.3
    elif pattern == CHAIR:
        seat = 0.45 * h
        if z < seat - 0.04 and edge > 0.045:
            m = 0.3
        if seat < z < seat + 0.1 and edge > 0.04:
            m = 0.45
        if z >= seat + 0.1 and edge > 0.04:
            m = 0.85
    elif pattern == CUSHIONS:
        arm = min(0.2, 0.12 * w)
        seat = 0.45 * h
        if z < 0.06:
            m = 0.35
        if long and 0.06 <= z < seat:
            m = 0.85
        if long and abs(z - seat) < 0.012:
            m = 0.5
        n = max(1.0, np.round((w - 2 * arm) / 0.6))
        width = (w - 2 * arm) / n
        cushion = (s - arm) % width
        seam = min(cushion, width - cushion) < 0.01 or abs(edge - arm) < 0.01
        if long and z > seat and edge >= arm - 0.01 and seam:
            m = 0.55
    return r, g, bl, m


def _pixel_small(pattern, r, g, bl, s, w, z, h):  # noqa: ANN001, ANN202, PLR0913
    """Colour (r, g, bl) and brightness factor of a point of a small object's pattern (bottle to rim)."""
    m = 1.0
    if pattern == BOTTLE:
        if z > 0.92 * h:
            m = 0.45
        if 0.72 * h < z <= 0.92 * h:
            m = 0.8
        if 0.3 * h < z < 0.58 * h:
            r, g, bl, m = _LABEL[0], _LABEL[1], _LABEL[2], 1.0
    elif pattern == UMBRELLA:
        if s % (w / 8) < 0.006:
            m = 0.6
        if abs(z - 0.5 * h) < 0.02:
            m = 0.7
        if z < 0.12 * h:
            r, g, bl, m = _UMBRELLA_HANDLE[0], _UMBRELLA_HANDLE[1], _UMBRELLA_HANDLE[2], 1.0
        if z > 0.95 * h:
            r, g, bl, m = _HANDLE[0], _HANDLE[1], _HANDLE[2], 1.0
    elif pattern == PLANT:
        if z >= 0.38 * h:
            m = 0.7 + 0.55 * _hash_one(np.floor(s / 0.05), np.floor(z / 0.05))
        else:
            r, g, bl, m = _POT[0], _POT[1], _POT[2], 1.0
    elif pattern == RIM:
        if z > h - min(0.02, 0.12 * h):
            m = 0.7
    return r, g, bl, m


def _paint_loops(color, depth, inst, ox, oy, hc, dx, dy, b, lut, kind, geom, pz, prgb, pattern,  # noqa: ANN001, ANN202
                 books):
    """Pixel loops of :func:`paint` (compiled by numba)."""
    rows, cols = depth.shape
    for v in range(rows):
        for u in range(cols):
            i = inst[v, u]
            if i < 0 or i >= len(lut) or lut[i] < 0:
                continue
            t = depth[v, u]
            if not np.isfinite(t):
                continue
            p = lut[i]
            t = np.float64(t)
            x, y, zr = ox + t * dx[u] - geom[p, 0], oy + t * dy[u] - geom[p, 1], hc + t * b[v] - pz[p, 0]
            height = pz[p, 1] - pz[p, 0]
            if not (zr > 1e-4 and zr < height - 1e-4):
                continue
            dlen = np.sqrt(dx[u] * dx[u] + dy[u] * dy[u])
            if kind[p] == BOX:
                c, sn, hx, hy = geom[p, 2], geom[p, 3], geom[p, 4], geom[p, 5]
                qx, qy = c * x + sn * y, -sn * x + c * y
                gap_x, gap_y = abs(abs(qx) - hx), abs(abs(qy) - hy)
                if min(gap_x, gap_y) >= _SIDE_EPS:
                    continue
                if gap_x <= gap_y:
                    s = hy - qy if qx > 0 else qy + hy
                    w, long = 2 * hy, hy >= hx - 1e-9
                    cos = abs(c * dx[u] + sn * dy[u]) / dlen
                else:
                    s = qx + hx if qy > 0 else hx - qx
                    w, long = 2 * hx, hx >= hy - 1e-9
                    cos = abs(-sn * dx[u] + c * dy[u]) / dlen
            elif kind[p] == CYLINDER:
                r = geom[p, 2]
                dist = np.sqrt(x * x + y * y)
                if abs(dist - r) >= _SIDE_EPS:
                    continue
                s = r * (np.arctan2(y, x) % (2 * np.pi))
                w, long = 2 * np.pi * r, True
                cos = abs(x * dx[u] + y * dy[u]) / (max(dist, 1e-9) * dlen)
            else:
                continue
            pr, pg, pb = _pixel_rgb(pattern[p], prgb[p], s, w, zr, height, long, books)
            shade = 0.55 + 0.45 * cos
            color[v, u, 0] = min(255.0, max(0.0, pr * shade))
            color[v, u, 1] = min(255.0, max(0.0, pg * shade))
            color[v, u, 2] = min(255.0, max(0.0, pb * shade))


if HAVE_NUMBA:
    _hash_one = numba.njit(cache=True)(_hash)
    _pixel_cabinets = numba.njit(cache=True, inline="always")(_pixel_cabinets)
    _pixel_seats = numba.njit(cache=True, inline="always")(_pixel_seats)
    _pixel_small = numba.njit(cache=True, inline="always")(_pixel_small)
    _pixel_rgb = numba.njit(cache=True)(_pixel_rgb)
    _paint_jit = numba.njit(cache=True, nogil=True)(_paint_loops)
else:  # pragma: no cover - exercised only without numba
    _hash_one = _hash
    _paint_jit = _paint_loops
