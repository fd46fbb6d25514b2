"""Exact 2D ray casting against vertical prisms: the one geometry kernel the lidar and camera share.

The world is a set of *primitives*, each an upright prism standing between heights ``z0`` and
``z1``: a wall segment (kind 0), an oriented box (kind 1) or an upright cylinder (kind 2). A
ray ``o + t * d`` (``d`` need not be unit length, so ``t`` is in units of ``|d|``) enters a
primitive at ``t_in`` and leaves it at ``t_out`` (equal for a segment). The lidar takes the
nearest entry per beam; the camera takes the ``k`` nearest per image column and decides per
pixel which face the ray meets (see :mod:`missiontree.backends.sim.camera`).

Two implementations with the same results: vectorised numpy, always available, and numba
loops, used when numba is installed (the ``accel`` extra) and not switched off. Intersections
are analytic, so ranges are exact up to float rounding.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

SEGMENT, BOX, CYLINDER = 0, 1, 2
_EPS = 1e-9

try:  # numba is an optional accelerator (extra `accel`); numpy is the fallback.
    import numba

    HAVE_NUMBA = True
except ImportError:  # pragma: no cover - exercised only without numba
    numba = None
    HAVE_NUMBA = False


#: One prism as a row: (kind, geometry, z0, z1, rgb, instance id), optionally a pattern id after them.
Row = tuple[int, tuple[float, ...], float, float, tuple[int, int, int], int] | tuple[
    int, tuple[float, ...], float, float, tuple[int, int, int], int, int]


@dataclass(frozen=True)
class Primitives:
    """A table of prisms, one row each.

    Attributes:
        kind: (P,) int64 SEGMENT, BOX or CYLINDER.
        geom: (P, 6) float64; segment: x1, y1, x2, y2; box: cx, cy, cos(yaw), sin(yaw), half x,
            half y; cylinder: cx, cy, radius.
        z: (P, 2) float64 bottom and top height.
        rgb: (P, 3) float64 colour 0-255.
        inst: (P,) int64 instance id (ground truth).
        pattern: (P,) int64 surface pattern the camera paints on side faces
            (:mod:`missiontree.backends.sim.patterns`), or None when every prism is plain.
    """

    kind: np.ndarray
    geom: np.ndarray
    z: np.ndarray
    rgb: np.ndarray
    inst: np.ndarray
    pattern: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.kind)

    @staticmethod
    def empty() -> Primitives:
        """A table with no rows."""
        return Primitives(np.zeros(0, np.int64), np.zeros((0, 6)), np.zeros((0, 2)), np.zeros((0, 3)),
                          np.zeros(0, np.int64))

    @staticmethod
    def build(rows: list[Row]) -> Primitives:
        """Make a table from rows ``(kind, geom, z0, z1, rgb, inst[, pattern])``."""
        if not rows:
            return Primitives.empty()
        pad = (0.0,) * 6
        table = np.array([(r[0], *(tuple(r[1]) + pad)[:6], r[2], r[3], *r[4], r[5],
                           r[6] if len(r) > 6 else 0) for r in rows], np.float64)  # type: ignore[misc]
        pattern = table[:, 13].astype(np.int64)
        return Primitives(table[:, 0].astype(np.int64), table[:, 1:7].copy(), table[:, 7:9].copy(),
                          table[:, 9:12].copy(), table[:, 12].astype(np.int64),
                          pattern if pattern.any() else None)

    def concat(self, other: Primitives) -> Primitives:
        """Rows of both tables."""
        if len(other) == 0:
            return self
        if len(self) == 0:
            return other
        pattern = None
        if self.pattern is not None or other.pattern is not None:
            pattern = np.concatenate([self.patterns(), other.patterns()])
        return Primitives(*(np.concatenate([a, b]) for a, b in zip(  # type: ignore[call-arg]  # 5 + pattern
            (self.kind, self.geom, self.z, self.rgb, self.inst),
            (other.kind, other.geom, other.z, other.rgb, other.inst), strict=True)), pattern)

    def patterns(self) -> np.ndarray:
        """(P,) pattern id per row, zeros when the table has none."""
        return self.pattern if self.pattern is not None else np.zeros(len(self.kind), np.int64)

    def select(self, mask: np.ndarray) -> Primitives:
        """The rows where ``mask`` is true."""
        return Primitives(self.kind[mask], self.geom[mask], self.z[mask], self.rgb[mask], self.inst[mask],
                          None if self.pattern is None else self.pattern[mask])

    def crossing(self, height: float) -> Primitives:
        """The rows whose height range contains ``height`` (what a planar sensor there sees)."""
        return self.select((self.z[:, 0] <= height) & (self.z[:, 1] >= height))


# -- numpy ---------------------------------------------------------------------------------------


def _hits_numpy(ox: float, oy: float, dx: np.ndarray, dy: np.ndarray,
                prims: Primitives) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Entry, exit and |cos incidence| of every ray against every primitive: three (R, P) arrays."""
    n_rays, n_prims = len(dx), len(prims)
    t_in = np.full((n_rays, n_prims), np.inf)
    t_out = np.full((n_rays, n_prims), np.inf)
    shade = np.ones((n_rays, n_prims))
    dlen = np.hypot(dx, dy)[:, None]
    for kind, hits in ((SEGMENT, _segment_hits), (BOX, _box_hits), (CYLINDER, _cylinder_hits)):
        idx = np.flatnonzero(prims.kind == kind)
        if len(idx):
            t_in[:, idx], t_out[:, idx], shade[:, idx] = hits(ox, oy, dx[:, None], dy[:, None], dlen,
                                                              prims.geom[idx])
    return t_in, t_out, shade


Hits = tuple[np.ndarray, np.ndarray, np.ndarray]


def _segment_hits(ox: float, oy: float, dxc: np.ndarray, dyc: np.ndarray, dlen: np.ndarray,
                  g: np.ndarray) -> Hits:
    """Entry, exit (the same) and |cos incidence| of (R, 1) rays against wall segments ``g`` (P, 4)."""
    x1, y1, x2, y2 = (g[:, j][None, :] for j in range(4))
    ex, ey = x2 - x1, y2 - y1
    wx, wy = x1 - ox, y1 - oy
    denom = dxc * ey - dyc * ex
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (wx * ey - wy * ex) / denom
        s = (wx * dyc - wy * dxc) / denom
        ok = (np.abs(denom) > _EPS) & (t > _EPS) & (s >= 0.0) & (s <= 1.0)
        t = np.where(ok, t, np.inf)
        cos = np.abs(denom) / (dlen * np.hypot(ex, ey))
    return t, t, cos


def _box_hits(ox: float, oy: float, dxc: np.ndarray, dyc: np.ndarray, dlen: np.ndarray,
              g: np.ndarray) -> Hits:
    """Entry, exit and |cos incidence| of (R, 1) rays against oriented boxes ``g`` (P, 6): slab test."""
    cx, cy, c, s_, hx, hy = (g[:, j][None, :] for j in range(6))
    qx = c * (ox - cx) + s_ * (oy - cy)
    qy = -s_ * (ox - cx) + c * (oy - cy)
    lx = c * dxc + s_ * dyc
    ly = -s_ * dxc + c * dyc
    with np.errstate(divide="ignore", invalid="ignore"):
        ax1, ax2 = (-hx - qx) / lx, (hx - qx) / lx
        ay1, ay2 = (-hy - qy) / ly, (hy - qy) / ly
    # a ray parallel to a slab is inside it everywhere or nowhere
    par_x, par_y = np.abs(lx) < _EPS, np.abs(ly) < _EPS
    in_x, in_y = np.abs(qx) <= hx, np.abs(qy) <= hy
    xmin = np.where(par_x, np.where(in_x, -np.inf, np.inf), np.minimum(ax1, ax2))
    xmax = np.where(par_x, np.where(in_x, np.inf, -np.inf), np.maximum(ax1, ax2))
    ymin = np.where(par_y, np.where(in_y, -np.inf, np.inf), np.minimum(ay1, ay2))
    ymax = np.where(par_y, np.where(in_y, np.inf, -np.inf), np.maximum(ay1, ay2))
    tmin, tmax = np.maximum(xmin, ymin), np.minimum(xmax, ymax)
    ok = (tmax >= tmin) & (tmin > _EPS)
    return (np.where(ok, tmin, np.inf), np.where(ok, tmax, np.inf),
            np.where(xmin >= ymin, np.abs(lx), np.abs(ly)) / dlen)


def _cylinder_hits(ox: float, oy: float, dxc: np.ndarray, dyc: np.ndarray, dlen: np.ndarray,
                   g: np.ndarray) -> Hits:
    """Entry, exit and |cos incidence| of (R, 1) rays against upright cylinders ``g`` (P, 3)."""
    cx, cy, r = (g[:, j][None, :] for j in range(3))
    fx, fy = ox - cx, oy - cy
    a = dxc * dxc + dyc * dyc
    b = 2.0 * (dxc * fx + dyc * fy)
    cc = fx * fx + fy * fy - r * r
    disc = b * b - 4.0 * a * cc
    root = np.sqrt(np.maximum(disc, 0.0))
    t1 = (-b - root) / (2.0 * a)
    t2 = (-b + root) / (2.0 * a)
    ok = (disc >= 0.0) & (t1 > _EPS)
    hx_ = fx + t1 * dxc
    hy_ = fy + t1 * dyc
    return (np.where(ok, t1, np.inf), np.where(ok, t2, np.inf),
            np.abs(hx_ * dxc + hy_ * dyc) / (np.maximum(r, _EPS) * dlen))


def first_hit_numpy(ox: float, oy: float, dx: np.ndarray, dy: np.ndarray, prims: Primitives) -> np.ndarray:
    """Ray parameter of the nearest entry per ray (inf when nothing is hit)."""
    if len(prims) == 0:
        return np.full(len(dx), np.inf)
    t_in, _, _ = _hits_numpy(ox, oy, dx, dy, prims)
    return t_in.min(axis=1)


def k_hits_numpy(ox: float, oy: float, dx: np.ndarray, dy: np.ndarray, prims: Primitives,
                 k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The ``k`` nearest entries per ray, nearest first: t_in, t_out, primitive index, shade (R, k)."""
    n = len(dx)
    if len(prims) == 0:
        return (np.full((n, k), np.inf), np.full((n, k), np.inf), np.full((n, k), -1, np.int64),
                np.ones((n, k)))
    t_in, t_out, shade = _hits_numpy(ox, oy, dx, dy, prims)
    if t_in.shape[1] < k:
        pad = k - t_in.shape[1]
        t_in = np.pad(t_in, ((0, 0), (0, pad)), constant_values=np.inf)
        t_out = np.pad(t_out, ((0, 0), (0, pad)), constant_values=np.inf)
        shade = np.pad(shade, ((0, 0), (0, pad)), constant_values=1.0)
    part = np.argpartition(t_in, k - 1, axis=1)[:, :k] if t_in.shape[1] > k else np.tile(
        np.arange(k), (n, 1))
    order = np.take_along_axis(t_in, part, axis=1).argsort(axis=1, kind="stable")
    idx = np.take_along_axis(part, order, axis=1)
    tin = np.take_along_axis(t_in, idx, axis=1)
    hit = np.isfinite(tin)
    tout = np.where(hit, np.take_along_axis(t_out, idx, axis=1), np.inf)
    shd = np.where(hit, np.take_along_axis(shade, idx, axis=1), 1.0)
    return tin, tout, np.where(hit, idx, -1), shd


# -- numba ---------------------------------------------------------------------------------------


def _hit_one(ox, oy, dx, dy, kind, g):  # noqa: ANN001, ANN202 - numba kernel, typed by numba
    """(t_in, t_out, shade) of one ray against one primitive; t_in = inf when missed."""
    dlen = np.sqrt(dx * dx + dy * dy)
    if kind == 0:
        ex, ey = g[2] - g[0], g[3] - g[1]
        wx, wy = g[0] - ox, g[1] - oy
        denom = dx * ey - dy * ex
        if abs(denom) <= _EPS:
            return np.inf, np.inf, 1.0
        t = (wx * ey - wy * ex) / denom
        s = (wx * dy - wy * dx) / denom
        if t > _EPS and 0.0 <= s <= 1.0:
            return t, t, abs(denom) / (dlen * np.sqrt(ex * ex + ey * ey))
        return np.inf, np.inf, 1.0
    if kind == 1:
        c, s_ = g[2], g[3]
        qx = c * (ox - g[0]) + s_ * (oy - g[1])
        qy = -s_ * (ox - g[0]) + c * (oy - g[1])
        lx = c * dx + s_ * dy
        ly = -s_ * dx + c * dy
        xmin, xmax = _slab(qx, lx, g[4])
        ymin, ymax = _slab(qy, ly, g[5])
        tmin, tmax = max(xmin, ymin), min(xmax, ymax)
        if tmax >= tmin and tmin > _EPS:
            shade = abs(lx) / dlen if xmin >= ymin else abs(ly) / dlen
            return tmin, tmax, shade
        return np.inf, np.inf, 1.0
    fx, fy, r = ox - g[0], oy - g[1], g[2]
    a = dx * dx + dy * dy
    b = 2.0 * (dx * fx + dy * fy)
    cc = fx * fx + fy * fy - r * r
    disc = b * b - 4.0 * a * cc
    if disc < 0.0:
        return np.inf, np.inf, 1.0
    root = np.sqrt(disc)
    t1 = (-b - root) / (2.0 * a)
    if t1 <= _EPS:
        return np.inf, np.inf, 1.0
    t2 = (-b + root) / (2.0 * a)
    hx_, hy_ = fx + t1 * dx, fy + t1 * dy
    return t1, t2, abs(hx_ * dx + hy_ * dy) / (max(r, _EPS) * dlen)


def _slab(q, d, h):  # noqa: ANN001, ANN202 - numba kernel, typed by numba
    """Ray parameters (enter, leave) of the slab |x| <= h for a ray at ``q`` moving ``d`` along x.

    A ray parallel to the slab is inside it everywhere (-inf, inf) or nowhere (inf, -inf).
    """
    if abs(d) < _EPS:
        return (-np.inf, np.inf) if abs(q) <= h else (np.inf, -np.inf)
    a1, a2 = (-h - q) / d, (h - q) / d
    return min(a1, a2), max(a1, a2)


def _bound(kind, g):  # noqa: ANN001, ANN202
    """Bounding circle (cx, cy, r) of one primitive."""
    if kind == 0:
        half = 0.5 * np.sqrt((g[2] - g[0]) ** 2 + (g[3] - g[1]) ** 2)
        return 0.5 * (g[0] + g[2]), 0.5 * (g[1] + g[3]), half
    if kind == 1:
        return g[0], g[1], np.sqrt(g[4] * g[4] + g[5] * g[5])
    return g[0], g[1], g[2]


def _fan_loops(ox, oy, angle0, inc, n, kind, geom):  # noqa: ANN001, ANN202
    """Nearest entry per ray of a full fan, visiting only the rays each primitive's bound subtends."""
    out = np.full(n, np.inf)
    two_pi = 2.0 * np.pi
    angles = angle0 + inc * np.arange(n)
    cos_a, sin_a = np.cos(angles), np.sin(angles)
    for p in range(len(kind)):
        bx, by, br = _bound(kind[p], geom[p])
        d = np.sqrt((bx - ox) ** 2 + (by - oy) ** 2)
        if d <= br + 1e-9:
            start, count = 0, n
        else:
            hw = np.arcsin(min(1.0, br / d))
            rel = (np.arctan2(by - oy, bx - ox) - hw - angle0) % two_pi
            start = int(np.floor(rel / inc))
            count = min(n, int(np.ceil(2.0 * hw / inc)) + 2)
        for j in range(count):
            i = (start + j) % n
            t, _, _ = _hit_one(ox, oy, cos_a[i], sin_a[i], kind[p], geom[p])
            if t < out[i]:
                out[i] = t
    return out


def _columns_loops(ox, oy, yaw, a, fx, cx, kind, geom, k):  # noqa: ANN001, ANN202
    """The k nearest entries per camera column, visiting only the columns each bound subtends."""
    n = len(a)
    tin = np.full((n, k), np.inf)
    tout = np.full((n, k), np.inf)
    idx = np.full((n, k), -1, np.int64)
    shade = np.ones((n, k))
    c, s = np.cos(yaw), np.sin(yaw)
    half = np.pi / 2.0 - 1e-6
    for p in range(len(kind)):
        bx, by, br = _bound(kind[p], geom[p])
        d = np.sqrt((bx - ox) ** 2 + (by - oy) ** 2)
        if d <= br + 1e-9:
            u0, u1 = 0, n - 1
        else:
            hw = np.arcsin(min(1.0, br / d))
            rel = (np.arctan2(by - oy, bx - ox) - yaw + np.pi) % (2.0 * np.pi) - np.pi
            lo, hi = rel - hw, rel + hw
            if hi < -half or lo > half:
                continue
            lo, hi = max(lo, -half), min(hi, half)
            u0 = max(0, int(np.floor(cx - fx * np.tan(hi))) - 1)
            u1 = min(n - 1, int(np.ceil(cx - fx * np.tan(lo))) + 1)
        for u in range(u0, u1 + 1):
            dx = c - a[u] * s
            dy = s + a[u] * c
            t1, t2, sh = _hit_one(ox, oy, dx, dy, kind[p], geom[p])
            if t1 >= tin[u, k - 1]:
                continue
            j = k - 1
            while j > 0 and tin[u, j - 1] > t1:
                tin[u, j] = tin[u, j - 1]
                tout[u, j] = tout[u, j - 1]
                idx[u, j] = idx[u, j - 1]
                shade[u, j] = shade[u, j - 1]
                j -= 1
            tin[u, j], tout[u, j], idx[u, j], shade[u, j] = t1, t2, p, sh
    return tin, tout, idx, shade


if HAVE_NUMBA:
    # Rebinding the module globals first makes the loop kernels call the compiled helpers; the
    # kernels release the GIL so the camera can render on a worker thread while physics steps.
    _slab = numba.njit(cache=True, nogil=True)(_slab)
    _hit_one = numba.njit(cache=True, nogil=True)(_hit_one)
    _bound = numba.njit(cache=True, nogil=True)(_bound)
    _fan_jit = numba.njit(cache=True, nogil=True)(_fan_loops)
    _columns_jit = numba.njit(cache=True, nogil=True)(_columns_loops)


def fan_first_hit(ox: float, oy: float, angle0: float, increment: float, n: int, kind: np.ndarray,
                  geom: np.ndarray, accelerate: bool = True) -> np.ndarray:
    """Range of the nearest entry for ``n`` unit rays at world angles ``angle0 + i * increment``.

    ``kind`` and ``geom`` are the columns of a :class:`Primitives` table (heights do not matter
    to a planar fan). Uses the culled numba kernel when numba is present and ``accelerate``;
    numpy otherwise.
    """
    if len(kind) == 0:
        return np.full(n, np.inf)
    if accelerate and HAVE_NUMBA:
        return _fan_jit(float(ox), float(oy), float(angle0), float(increment), int(n), kind, geom)
    a = angle0 + increment * np.arange(n)
    m = len(kind)
    prims = Primitives(kind, geom, np.zeros((m, 2)), np.zeros((m, 3)), np.zeros(m, np.int64))
    return first_hit_numpy(ox, oy, np.cos(a), np.sin(a), prims)


def column_hits(ox: float, oy: float, yaw: float, a: np.ndarray, fx: float, cx: float, prims: Primitives,
                k: int, accelerate: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The ``k`` nearest entries per camera column (t_in, t_out, index, shade), each (W, k).

    Column ``u`` casts along ``forward + a[u] * left`` of heading ``yaw``, so ``t`` is depth
    along the optical axis. Culled numba kernel or numpy, as :func:`fan_first_hit`.
    """
    if accelerate and HAVE_NUMBA:
        return _columns_jit(float(ox), float(oy), float(yaw), np.ascontiguousarray(a, np.float64), float(fx),
                            float(cx), prims.kind, prims.geom, int(k))
    c, s = np.cos(yaw), np.sin(yaw)
    return k_hits_numpy(ox, oy, c - a * s, s + a * c, prims, k)
