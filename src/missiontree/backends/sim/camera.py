"""A pinhole RGB-D camera rendered by casting one horizontal ray per image column.

Everything in the world is an upright prism, so a pixel's ray (column ``u``, row ``v``)
is the column's horizontal ray climbing or falling linearly: with ``a = (cx - u) / fx`` and
``b = (cy - v) / fy`` the point at depth ``t`` (metres along the level optical axis) is
``C + t * (forward + a * left)`` at height ``h + t * b``. Per column the ``k`` nearest prisms
are found once (:func:`raycast.k_hits`); per pixel the first prism whose front face, top or
bottom the ray meets wins, else the floor (``b < 0``) or the ceiling. Depth is ``t``, the
distance along the optical axis that a registered depth image holds. Objects' side faces then
get their surface patterns (:mod:`missiontree.backends.sim.patterns`).

The instance mask (which prism each pixel shows) is returned separately and stays with the
simulator's ground truth; :class:`~missiontree.types.RGBDFrame` carries only colour and depth.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from missiontree.backends.sim.patterns import paint
from missiontree.backends.sim.raycast import HAVE_NUMBA, Primitives, column_hits
from missiontree.backends.sim.schema import CameraSpec
from missiontree.types import CameraIntrinsics, Pose2D

HITS_PER_COLUMN = 8
CEILING_RGB = (236, 236, 232)
_FACE_SHADE = 0.55, 0.45     # front faces: ambient + diffuse * |cos incidence|
_TOP_SHADE = 1.0
_BOTTOM_SHADE = 0.45
_TILE = 0.5                   # floor tiles (m), a faint checker for texture
_BAND = 256                   # rows of the floor texture baked at a time

if HAVE_NUMBA:
    import numba


@dataclass(frozen=True)
class Floor:
    """The floor's texture (room colours with a faint tile checker, per grid cell) and the ceiling height."""

    texture: np.ndarray      # (rows, cols, 3) uint8
    origin_x: float
    origin_y: float
    resolution: float
    ceiling: float

    @staticmethod
    def build(rgb: np.ndarray, origin_x: float, origin_y: float, resolution: float, ceiling: float) -> Floor:
        """Bake the tile checker into the per-cell floor colours.

        Done in bands of rows: the float64 temporaries of the whole image (about 250 MB for a 100 m
        world at 5 cm) are never held at once; each cell's arithmetic is the same.
        """
        rows, cols = rgb.shape[:2]
        xs = origin_x + (np.arange(cols) + 0.5) * resolution
        ys = origin_y + (np.arange(rows) + 0.5) * resolution
        texture = np.empty((rows, cols, 3), np.uint8)
        for top in range(0, rows, _BAND):
            band = slice(top, min(top + _BAND, rows))
            parity = (np.floor(ys[band] / _TILE)[:, None] + np.floor(xs / _TILE)[None, :]) % 2
            shaded = rgb[band] * np.where(parity > 0, 0.94, 1.0)[..., None]
            texture[band] = np.clip(shaded, 0, 255).astype(np.uint8)
        return Floor(texture, origin_x, origin_y, resolution, ceiling)


@dataclass(frozen=True)
class Rendering:
    """One rendered frame before it becomes an RGBDFrame."""

    color: np.ndarray        # (H, W, 3) uint8
    depth: np.ndarray        # (H, W) float32, NaN where unknown
    instances: np.ndarray    # (H, W) int32 instance id per pixel (0 = floor / ceiling)
    counts: np.ndarray       # pixels per instance id


def intrinsics_for(spec: CameraSpec) -> CameraIntrinsics:
    """Square-pixel intrinsics with the given horizontal field of view, centred principal point."""
    fx = (spec.width / 2.0) / math.tan(math.radians(spec.hfov_deg) / 2.0)
    return CameraIntrinsics(spec.width, spec.height, fx, fx, spec.width / 2.0 - 0.5, spec.height / 2.0 - 0.5)


class Camera:
    """Renders colour, depth and instance images from the camera's true pose."""

    def __init__(self, spec: CameraSpec, rng: np.random.Generator, accelerate: bool = True) -> None:
        self.spec = spec
        self.rng = rng
        self.accelerate = accelerate and HAVE_NUMBA
        self.intrinsics = intrinsics_for(spec)
        k = self.intrinsics
        self._a = (k.cx - np.arange(spec.width)) / k.fx
        self._b = (k.cy - np.arange(spec.height)) / k.fy

    def render(self, cam: Pose2D, height: float, prims: Primitives, floor: Floor) -> Rendering:
        """Render from camera pose ``cam`` (optical axis along its yaw) at ``height`` above the floor."""
        return self.add_noise(self.render_exact(cam, height, prims, floor))

    def render_exact(self, cam: Pose2D, height: float, prims: Primitives, floor: Floor,
                     patterns: bool = True) -> Rendering:
        """The noise-free image; pure (no random draws), so it may run on a worker thread.

        Without ``patterns`` the objects' surface patterns are left unpainted: the instance mask and
        depth are final, the colour is not until :meth:`paint_patterns` (for the ground truth of a
        frame nobody reads).
        """
        k = self.intrinsics
        spec = self.spec
        t_in, t_out, idx, shade = column_hits(cam.x, cam.y, cam.yaw, self._a, k.fx, k.cx, prims,
                                              HITS_PER_COLUMN, self.accelerate)
        c, s = math.cos(cam.yaw), math.sin(cam.yaw)
        args = (cam.x, cam.y, height, c - self._a * s, s + self._a * c, self._b, t_in, t_out, idx, shade,
                prims.z, prims.rgb, prims.inst, floor.texture, floor.origin_x, floor.origin_y,
                floor.resolution, floor.ceiling, spec.depth_min, spec.depth_max,
                int(prims.inst.max(initial=1)) + 1, k.fy, k.cy)
        color, depth, inst, counts = (_fill_jit if self.accelerate else _fill_numpy)(*args)
        image = Rendering(color, depth, inst, counts)
        if patterns:
            self.paint_patterns(image, cam, height, prims)
        return image

    def paint_patterns(self, image: Rendering, cam: Pose2D, height: float, prims: Primitives) -> None:
        """Paint the surface patterns into a frame rendered without them (its colour changes in place)."""
        c, s = math.cos(cam.yaw), math.sin(cam.yaw)
        paint(image.color, image.depth, image.instances, (cam.x, cam.y, height), c - self._a * s,
              s + self._a * c, self._b, prims, self.accelerate)

    def add_noise(self, image: Rendering) -> Rendering:
        """Depth and colour noise as configured, drawn from the camera's generator (in frame order)."""
        spec = self.spec
        color, depth = image.color, image.depth
        if spec.depth_noise > 0:
            depth = depth + self.rng.normal(0.0, 1.0, depth.shape).astype(np.float32) * (
                spec.depth_noise * depth * depth)
            depth = np.where((depth >= spec.depth_min) & (depth <= spec.depth_max), depth, np.nan).astype(
                np.float32)
        if spec.color_noise > 0:
            noisy = color + self.rng.normal(0.0, spec.color_noise, color.shape)
            color = np.clip(noisy, 0, 255).astype(np.uint8)
        return Rendering(color, depth, image.instances, image.counts)

    def skip_noise(self) -> None:
        """Draw (and drop) a frame's noise as :meth:`add_noise` would: later frames get the same noise."""
        spec = self.spec
        if spec.depth_noise > 0:
            self.rng.normal(0.0, 1.0, (spec.height, spec.width))
        if spec.color_noise > 0:
            self.rng.normal(0.0, spec.color_noise, (spec.height, spec.width, 3))


def _fill_numpy(ox, oy, hc, dx, dy, b, t_in, t_out, idx, shade, pz, prgb, pinst,  # noqa: ANN001, ANN202
                floor_rgb, fox, foy, fres, ceiling, dmin, dmax, ninst, fy, cy):
    """Vectorised painter: floor and ceiling first, then the k hits from far to near."""
    h, w = len(b), len(dx)
    bb = np.broadcast_to(b[:, None], (h, w))
    with np.errstate(divide="ignore", invalid="ignore"):
        t_floor = np.where(bb < 0, -hc / bb, np.where(bb > 0, (ceiling - hc) / bb, np.inf))
    depth = t_floor.copy()
    px = ox + t_floor * dx[None, :]
    py = oy + t_floor * dy[None, :]
    inv = 1.0 / fres
    rows = np.nan_to_num((py - foy) * inv, nan=0.0, posinf=0.0, neginf=0.0).astype(np.int64)
    cols = np.nan_to_num((px - fox) * inv, nan=0.0, posinf=0.0, neginf=0.0).astype(np.int64)
    rows = np.clip(rows, 0, floor_rgb.shape[0] - 1)
    cols = np.clip(cols, 0, floor_rgb.shape[1] - 1)
    color = floor_rgb[rows, cols].astype(np.float64)
    color = np.where((bb > 0)[..., None], np.array(CEILING_RGB, float), color)
    inst = np.zeros((h, w), np.int64)
    used = int((idx >= 0).sum(axis=1).max(initial=0))   # layers any column has
    for k in range(used - 1, -1, -1):
        p = idx[:, k]
        valid = p >= 0
        if not valid.any():
            continue
        pp = np.maximum(p, 0)
        z0, z1 = pz[pp, 0][None, :], pz[pp, 1][None, :]
        tin, tout = t_in[:, k][None, :], t_out[:, k][None, :]
        zin = hc + tin * bb
        front = valid[None, :] & (zin >= z0) & (zin <= z1)
        with np.errstate(divide="ignore", invalid="ignore"):
            t_top = (z1 - hc) / bb
            t_bot = (z0 - hc) / bb
        top = valid[None, :] & ~front & (bb < 0) & (zin > z1) & (t_top <= tout)
        bottom = valid[None, :] & ~front & (bb > 0) & (zin < z0) & (t_bot <= tout)
        rgb = prgb[pp][None, :, :]
        face = (_FACE_SHADE[0] + _FACE_SHADE[1] * shade[:, k])[None, :, None]
        depth = np.where(front, tin, np.where(top, t_top, np.where(bottom, t_bot, depth)))
        color = np.where(front[..., None], rgb * face, color)
        color = np.where(top[..., None], rgb * _TOP_SHADE, color)
        color = np.where(bottom[..., None], rgb * _BOTTOM_SHADE, color)
        inst = np.where(front | top | bottom, pinst[pp][None, :], inst)
    depth = np.where((depth >= dmin) & (depth <= dmax), depth, np.nan).astype(np.float32)
    counts = np.bincount(inst.ravel(), minlength=ninst)
    return np.clip(color, 0, 255).astype(np.uint8), depth, inst.astype(np.int32), counts


def _front_runs(h, cy, fy, hc, idx, t_in, shade, pz, prgb, pinst, ceiling, dmin, dmax,  # noqa: ANN001, ANN202
                counts):
    """Per column, the run of rows its nearest prism's front face covers, with its colour, depth and id.

    Returns (first row, last row, colour, depth, instance) per column; an empty run has first row
    ``h``. The run's pixels are added to ``counts``.
    """
    w = idx.shape[0]
    va_ = np.full(w, h, np.int64)
    vb_ = np.full(w, -1, np.int64)
    c0 = np.zeros((w, 3), np.uint8)
    d0 = np.zeros(w, np.float32)
    i0 = np.zeros(w, np.int32)
    for u in range(w):
        q0 = idx[u, 0]
        if q0 >= 0:
            tin0 = t_in[u, 0]
            top = min(pz[q0, 1], ceiling)
            va = max(0, int(math.ceil(cy - fy * (top - hc) / tin0)) + 1)
            vb = min(h - 1, int(math.floor(cy - fy * (pz[q0, 0] - hc) / tin0)) - 1)
            if va <= vb:
                f0 = _FACE_SHADE[0] + _FACE_SHADE[1] * shade[u, 0]
                for ch in range(3):
                    c0[u, ch] = min(255.0, prgb[q0, ch] * f0)
                d0[u] = tin0 if dmin <= tin0 <= dmax else np.nan
                i0[u] = pinst[q0]
                va_[u] = va
                vb_[u] = vb
                counts[i0[u]] += vb - va + 1
    return va_, vb_, c0, d0, i0


def _fill_loops(ox, oy, hc, dx, dy, b, t_in, t_out, idx, shade, pz, prgb, pinst,  # noqa: ANN001, ANN202
                floor_rgb, fox, foy, fres, ceiling, dmin, dmax, ninst, fy, cy):
    """Pixel loops (compiled by numba): the nearest prism face each pixel's ray meets, else floor/ceiling.

    The rows a column's nearest prism covers with its front face are one run of constant colour
    and depth (found first, per column: :func:`_front_runs`); each row is then filled by
    :func:`_fill_row`.
    """
    h, w = len(b), len(dx)
    color = np.empty((h, w, 3), np.uint8)
    depth = np.empty((h, w), np.float32)
    inst = np.zeros((h, w), np.int32)
    counts = np.zeros(ninst, np.int64)
    runs = _front_runs(h, cy, fy, hc, idx, t_in, shade, pz, prgb, pinst, ceiling, dmin, dmax, counts)
    out = (color, depth, inst, counts)
    hits = (idx, t_in, t_out, shade, pz, prgb, pinst)
    ray = (ox, oy, hc, dx, dy, ceiling, dmin, dmax)
    floor = (floor_rgb, fox, foy, 1.0 / fres)
    for v in range(h):
        _fill_row(v, b[v], out, runs, hits, ray, floor)
    return color, depth, inst, counts


def _fill_row(v, bv, out, runs, hits, ray, floor):  # noqa: ANN001, ANN202
    """Fill row ``v`` (ray slope ``bv``); a column's front-face run is written without testing.

    The other pixels test the column's hits inline: as a compiled helper it made a frame about four
    times slower (measured on the combined world); a call per row costs nothing next to it.
    """
    color, depth, inst, counts = out
    va, vb, c0, d0, i0 = runs
    idx, t_in, t_out, shade, pz, prgb, pinst = hits
    ox, oy, hc, dx, dy, ceiling, dmin, dmax = ray
    floor_rgb, fox, foy, inv_res = floor
    nrows, ncols = floor_rgb.shape[0], floor_rgb.shape[1]
    t_plane = -hc / bv if bv < 0.0 else ((ceiling - hc) / bv if bv > 0.0 else np.inf)
    for u in range(len(dx)):
        if va[u] <= v <= vb[u]:
            for ch in range(3):
                color[v, u, ch] = c0[u, ch]
            depth[v, u] = d0[u]
            inst[v, u] = i0[u]
            continue
        t = -1.0  # the first prism face (front, top or bottom) the ray meets, else floor/ceiling
        f, p = 0.0, -1
        for k in range(idx.shape[1]):
            q = idx[u, k]
            tin = t_in[u, k]
            if q < 0 or tin > t_plane:  # hits are sorted: the floor or ceiling comes first
                break
            z0, z1 = pz[q, 0], pz[q, 1]
            zin = hc + tin * bv
            if z0 <= zin <= z1:
                t = tin
                f = _FACE_SHADE[0] + _FACE_SHADE[1] * shade[u, k]
            elif bv < 0.0 and zin > z1:
                tt = (z1 - hc) / bv
                if tt <= t_out[u, k]:
                    t = tt
                    f = _TOP_SHADE
            elif bv > 0.0 and zin < z0:
                tb = (z0 - hc) / bv
                if tb <= t_out[u, k]:
                    t = tb
                    f = _BOTTOM_SHADE
            if t >= 0.0:
                p = q
                break
        if p >= 0:
            for ch in range(3):
                color[v, u, ch] = min(255.0, prgb[p, ch] * f)
            inst[v, u] = pinst[p]
            counts[pinst[p]] += 1
        elif bv < 0.0:
            r = min(max(int((oy + t_plane * dy[u] - foy) * inv_res), 0), nrows - 1)
            c = min(max(int((ox + t_plane * dx[u] - fox) * inv_res), 0), ncols - 1)
            for ch in range(3):
                color[v, u, ch] = floor_rgb[r, c, ch]
        else:
            for ch in range(3):
                color[v, u, ch] = CEILING_RGB[ch]
        t = t if p >= 0 else t_plane
        depth[v, u] = t if dmin <= t <= dmax else np.nan


if HAVE_NUMBA:  # called once a frame or row: a compiled call costs nothing next to the pixel loops
    _front_runs = numba.njit(cache=True, nogil=True)(_front_runs)
    _fill_row = numba.njit(cache=True, nogil=True)(_fill_row)
_fill_jit = numba.njit(cache=True, nogil=True)(_fill_loops) if HAVE_NUMBA else _fill_loops
