"""A pinhole RGB-D camera rendered by casting one horizontal ray per image column.

Everything in the world is an upright prism, so a pixel's ray (column ``u``, row ``v``)
is the column's horizontal ray climbing or falling linearly: with ``a = (cx - u) / fx`` and
``b = (cy - v) / fy`` the point at depth ``t`` (metres along the level optical axis) is
``C + t * (forward + a * left)`` at height ``h + t * b``. Per column the ``k`` nearest prisms
are found once (:func:`raycast.k_hits`); per pixel the first prism whose front face, top or
bottom the ray meets wins, else the floor (``b < 0``) or the ceiling. Depth is ``t``, the
distance along the optical axis that a registered depth image holds.

The instance mask (which prism each pixel shows) is returned separately and stays with the
simulator's ground truth; :class:`~missiontree.types.RGBDFrame` carries only colour and depth.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from missiontree.backends.sim.raycast import HAVE_NUMBA, Primitives, column_hits
from missiontree.backends.sim.schema import CameraSpec
from missiontree.types import CameraIntrinsics, Pose2D

HITS_PER_COLUMN = 8
CEILING_RGB = (236, 236, 232)
_FACE_SHADE = 0.55, 0.45     # front faces: ambient + diffuse * |cos incidence|
_TOP_SHADE = 1.0
_BOTTOM_SHADE = 0.45
_TILE = 0.5                   # floor tiles (m), a faint checker for texture

if HAVE_NUMBA:
    import numba


@dataclass(frozen=True)
class Floor:
    """Floor colours per grid cell (rooms have their own floors) and the ceiling height."""

    rgb: np.ndarray          # (rows, cols, 3) float64
    origin_x: float
    origin_y: float
    resolution: float
    ceiling: float


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
        k = self.intrinsics
        spec = self.spec
        t_in, t_out, idx, shade = column_hits(cam.x, cam.y, cam.yaw, self._a, k.fx, k.cx, prims,
                                              HITS_PER_COLUMN, self.accelerate)
        c, s = math.cos(cam.yaw), math.sin(cam.yaw)
        args = (cam.x, cam.y, height, c - self._a * s, s + self._a * c, self._b, t_in, t_out, idx, shade,
                prims.z, prims.rgb, prims.inst, floor.rgb, floor.origin_x, floor.origin_y, floor.resolution,
                floor.ceiling, spec.depth_min, spec.depth_max, int(prims.inst.max(initial=1)) + 1)
        color, depth, inst, counts = (_fill_jit if self.accelerate else _fill_numpy)(*args)
        if spec.depth_noise > 0:
            depth = depth + self.rng.normal(0.0, 1.0, depth.shape).astype(np.float32) * (
                spec.depth_noise * depth * depth)
            depth = np.where((depth >= spec.depth_min) & (depth <= spec.depth_max), depth, np.nan).astype(
                np.float32)
        if spec.color_noise > 0:
            noisy = color + self.rng.normal(0.0, spec.color_noise, color.shape)
            color = np.clip(noisy, 0, 255).astype(np.uint8)
        return Rendering(color, depth, inst, counts)


def _fill_numpy(ox, oy, hc, dx, dy, b, t_in, t_out, idx, shade, pz, prgb, pinst,  # noqa: ANN001, ANN202
                floor_rgb, fox, foy, fres, ceiling, dmin, dmax, ninst):
    """Vectorised painter: floor and ceiling first, then the k hits from far to near."""
    h, w = len(b), len(dx)
    bb = np.broadcast_to(b[:, None], (h, w))
    with np.errstate(divide="ignore", invalid="ignore"):
        t_floor = np.where(bb < 0, -hc / bb, np.where(bb > 0, (ceiling - hc) / bb, np.inf))
    depth = t_floor.copy()
    px = ox + t_floor * dx[None, :]
    py = oy + t_floor * dy[None, :]
    rows = np.clip(np.nan_to_num((py - foy) / fres, nan=0.0, posinf=0.0, neginf=0.0).astype(np.int64), 0,
                   floor_rgb.shape[0] - 1)
    cols = np.clip(np.nan_to_num((px - fox) / fres, nan=0.0, posinf=0.0, neginf=0.0).astype(np.int64), 0,
                   floor_rgb.shape[1] - 1)
    tile = (np.floor(np.nan_to_num(px / _TILE, posinf=0.0, neginf=0.0))
            + np.floor(np.nan_to_num(py / _TILE, posinf=0.0, neginf=0.0))) % 2
    color = floor_rgb[rows, cols] * np.where(tile > 0, 0.94, 1.0)[..., None]
    color = np.where((bb > 0)[..., None], np.array(CEILING_RGB, float), color)
    inst = np.zeros((h, w), np.int64)
    for k in range(t_in.shape[1] - 1, -1, -1):
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


def _fill_loops(ox, oy, hc, dx, dy, b, t_in, t_out, idx, shade, pz, prgb, pinst,  # noqa: ANN001, ANN202
                floor_rgb, fox, foy, fres, ceiling, dmin, dmax, ninst):
    """Per-pixel loops (compiled by numba): the nearest prism face the ray meets, else floor/ceiling."""
    h, w = len(b), len(dx)
    color = np.empty((h, w, 3), np.uint8)
    depth = np.empty((h, w), np.float32)
    inst = np.zeros((h, w), np.int32)
    counts = np.zeros(ninst, np.int64)
    nrows, ncols = floor_rgb.shape[0], floor_rgb.shape[1]
    kmax = t_in.shape[1]
    for v in range(h):
        bv = b[v]
        # where this row's ray meets the floor (looking down) or the ceiling (looking up)
        t_plane = -hc / bv if bv < 0.0 else ((ceiling - hc) / bv if bv > 0.0 else np.inf)
        for u in range(w):
            t = -1.0
            f = 0.0
            p = -1
            for k in range(kmax):
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
                t = t_plane
                px = ox + t * dx[u]
                py = oy + t * dy[u]
                r = min(max(int((py - foy) / fres), 0), nrows - 1)
                c = min(max(int((px - fox) / fres), 0), ncols - 1)
                f = 0.94 if (math.floor(px / _TILE) + math.floor(py / _TILE)) % 2 else 1.0
                for ch in range(3):
                    color[v, u, ch] = min(255.0, floor_rgb[r, c, ch] * f)
            else:
                t = t_plane
                for ch in range(3):
                    color[v, u, ch] = CEILING_RGB[ch]
            depth[v, u] = t if dmin <= t <= dmax else np.nan
    return color, depth, inst, counts


_fill_jit = numba.njit(cache=True)(_fill_loops) if HAVE_NUMBA else _fill_loops
