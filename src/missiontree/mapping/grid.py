"""A log-odds occupancy grid built from 2D laser scans, in Nav2's map conventions.

Each scan is integrated at the pose the robot had *when the scan was taken* (look the pose up
in the robot's sensor history with :meth:`LogOddsGrid.update_from`, or pass it to
:meth:`LogOddsGrid.integrate`). Every beam marks the cells it crosses as free and the cell of
its end point as occupied; cells behind the end point are left alone (unknown stays unknown).
The end point of a return is taken ``hit_depth`` beyond the measured range before its cell is
found: a return comes from an obstacle's surface, and with range noise of about a centimetre half
the returns from a surface lying on a cell's edge would otherwise fall into the free cell in front
of it, which then reads occupied (a wall drawn a cell into the room, a doorway a cell narrower).
A beam with no return (``inf``) marks free space up to the sensor's range (or ``max_range``);
NaN readings are skipped. Within one scan a cell is updated at most once, and a cell hit by
some beam is not also freed by another beam of the same scan (so a wall seen at a grazing angle
stays a wall).

Conventions are those of nav_msgs/OccupancyGrid and map_server: ``resolution`` metres a cell,
``origin`` the map position of cell (0, 0)'s corner (row 0 is the lowest y), values -1
(unknown), 0 (free), 100 (occupied) in :meth:`LogOddsGrid.to_occupancy`, with map_server's
trinary thresholds: a cell is occupied when its probability exceeds ``occupied_thresh`` (0.65),
free below ``free_thresh`` (0.25), unknown in between.

The grid **grows** when a scan reaches outside it: it is padded (in whole ``grow_step``
metres, keeping cells aligned with the original origin) so that every beam fits. The origin of
the grid then moves to the new lower-left corner; callers that keep cell indices must re-read
``origin``/``shape`` after :meth:`integrate`. Pass ``grow=False`` to clip beams at the border.

Ray traversal is exact (every cell a beam passes through, as Amanatides and Woo's DDA): a numba
kernel when numba is installed (the ``accel`` extra), a vectorised numpy version with the same
result otherwise. One 360-beam scan into a 20 x 20 m grid at 5 cm costs well under 1 ms with
numba (see ``benchmarks/exploration.py``).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from missiontree.mapping.occupancy import (  # noqa: F401 - the grid's cell values, kept importable here
    FREE,
    FREE_BELOW,
    FREE_THRESH,
    OCCUPIED,
    OCCUPIED_FROM,
    OCCUPIED_THRESH,
    UNKNOWN,
)
from missiontree.types import LaserScan, OccupancyGrid, Pose2D

try:  # numba is an optional accelerator (extra `accel`); numpy is the fallback.
    import numba

    HAVE_NUMBA = True
except ImportError:  # pragma: no cover - exercised only without numba
    numba = None
    HAVE_NUMBA = False


def logit(p: float) -> float:
    """Log-odds of probability ``p``."""
    return math.log(p / (1.0 - p))


# -- ray traversal -----------------------------------------------------------------------------


def _scan_kernel(logodds, free_mark, hit_mark, scan_id, sx, sy, ex, ey, hit,  # noqa: ANN001, ANN201
                 l_free, l_occ, l_min, l_max):
    """Integrate one scan (numba-compiled when available; the loop reference otherwise).

    ``(sx, sy)`` is the sensor and ``(ex[i], ey[i])`` the end of beam ``i``, both in cell units
    (x along columns, y along rows, 0 at the grid's corner); ``hit[i]`` tells whether the end is
    an obstacle. Returns the number of cells updated.
    """
    # occupied ends first, so that no beam of this scan frees a cell another beam hit
    _mark_hits(hit_mark, scan_id, ex, ey, hit)
    updated = 0
    for i in range(len(ex)):
        updated += _free_beam(logodds, free_mark, hit_mark, scan_id, sx, sy, ex[i], ey[i], hit[i],
                              l_free, l_min)
    return updated + _apply_hits(logodds, hit_mark, scan_id, ex, ey, hit, l_occ, l_max)


def _mark_hits(hit_mark, scan_id, ex, ey, hit):  # noqa: ANN001, ANN202
    """Mark the cells where beams of this scan (``scan_id``) ended on an obstacle."""
    rows, cols = hit_mark.shape
    for i in range(len(ex)):
        if hit[i]:
            c = int(np.floor(ex[i]))
            r = int(np.floor(ey[i]))
            if 0 <= r < rows and 0 <= c < cols:
                hit_mark[r, c] = scan_id


def _free_beam(logodds, free_mark, hit_mark, scan_id, sx, sy, ex, ey, hit,  # noqa: ANN001, ANN202
               l_free, l_min):
    """Free the cells one beam crosses (its end cell too when it has no return); cells updated.

    A cell is freed once a scan and never when a beam of the scan ended on it.
    """
    rows, cols = logodds.shape
    dx = ex - sx
    dy = ey - sy
    c = int(np.floor(sx))
    r = int(np.floor(sy))
    c_end = int(np.floor(ex))
    r_end = int(np.floor(ey))
    step_c = 1 if dx > 0 else -1
    step_r = 1 if dy > 0 else -1
    # ray parameter t in [0, 1] at the next column / row boundary, computed from the boundary
    # itself (not accumulated) so the numpy version finds exactly the same cells
    t_max_x = ((c + 1.0 if dx > 0 else float(c)) - sx) / dx if dx != 0.0 else np.inf
    t_max_y = ((r + 1.0 if dy > 0 else float(r)) - sy) / dy if dy != 0.0 else np.inf
    updated = 0
    while True:
        if r == r_end and c == c_end:
            break
        if 0 <= r < rows and 0 <= c < cols:
            if hit_mark[r, c] != scan_id and free_mark[r, c] != scan_id:
                free_mark[r, c] = scan_id
                v = logodds[r, c] + l_free
                logodds[r, c] = v if v > l_min else l_min
                updated += 1
        t_next = t_max_x if t_max_x < t_max_y else t_max_y
        if t_next >= 1.0:
            break
        if t_max_x <= t_next:  # both at once through a corner: the cells beside it are not crossed
            c += step_c
            t_max_x = ((c + 1.0 if dx > 0 else float(c)) - sx) / dx
        if t_max_y <= t_next:
            r += step_r
            t_max_y = ((r + 1.0 if dy > 0 else float(r)) - sy) / dy
    # the end cell of a beam without a return is free too
    if not hit and 0 <= r_end < rows and 0 <= c_end < cols:
        if hit_mark[r_end, c_end] != scan_id and free_mark[r_end, c_end] != scan_id:
            free_mark[r_end, c_end] = scan_id
            v = logodds[r_end, c_end] + l_free
            logodds[r_end, c_end] = v if v > l_min else l_min
            updated += 1
    return updated


def _apply_hits(logodds, hit_mark, scan_id, ex, ey, hit, l_occ, l_max):  # noqa: ANN001, ANN202
    """Raise each marked end cell once however many beams ended there; cells updated."""
    rows, cols = logodds.shape
    updated = 0
    for i in range(len(ex)):
        if hit[i]:
            c = int(np.floor(ex[i]))
            r = int(np.floor(ey[i]))
            if 0 <= r < rows and 0 <= c < cols and hit_mark[r, c] == scan_id:
                hit_mark[r, c] = -scan_id  # applied once however many beams ended here
                v = logodds[r, c] + l_occ
                logodds[r, c] = v if v < l_max else l_max
                updated += 1
    return updated


if HAVE_NUMBA:  # the kernel's parts compiled too: called once a scan or once a beam
    _mark_hits = numba.njit(cache=True, nogil=True)(_mark_hits)
    _free_beam = numba.njit(cache=True, nogil=True)(_free_beam)
    _apply_hits = numba.njit(cache=True, nogil=True)(_apply_hits)


if HAVE_NUMBA:
    _scan_jit = numba.njit(cache=True, nogil=True)(_scan_kernel)


def _beam_cells_numpy(sx: float, sy: float, ex: np.ndarray, ey: np.ndarray,
                      shape: tuple[int, int], include_end: np.ndarray) -> np.ndarray:
    """Flat indices of the in-grid cells every beam passes through (the DDA's cells, vectorised).

    A beam's cells are those holding the midpoints between consecutive grid-line crossings; the
    end cell is included where ``include_end`` is true.
    """
    rows, cols = shape
    dx, dy = ex - sx, ey - sy
    c0, r0 = math.floor(sx), math.floor(sy)
    ce, re = np.floor(ex).astype(np.int64), np.floor(ey).astype(np.int64)
    nx = int(np.abs(ce - c0).max(initial=0))
    ny = int(np.abs(re - r0).max(initial=0))
    k_x = np.arange(1, nx + 1, dtype=np.float64)[None, :]
    k_y = np.arange(1, ny + 1, dtype=np.float64)[None, :]
    with np.errstate(divide="ignore", invalid="ignore"):
        # column boundaries crossed: x = c0 + k (dx > 0) or c0 + 1 - k (dx < 0)
        bx = np.where(dx[:, None] > 0, c0 + k_x, c0 + 1 - k_x)
        tx = (bx - sx) / dx[:, None]
        by = np.where(dy[:, None] > 0, r0 + k_y, r0 + 1 - k_y)
        ty = (by - sy) / dy[:, None]
    tx = np.where((tx > 0) & (tx < 1) & np.isfinite(tx), tx, np.inf)
    ty = np.where((ty > 0) & (ty < 1) & np.isfinite(ty), ty, np.inf)
    ts = np.concatenate([np.zeros((len(ex), 1)), tx, ty], axis=1)
    ts.sort(axis=1)
    a, b = ts[:, :-1], ts[:, 1:]
    valid = np.isfinite(b) & (b > a)
    mid = np.where(valid, 0.5 * (a + b), 0.0)
    mx = np.floor(sx + mid * dx[:, None]).astype(np.int64)
    my = np.floor(sy + mid * dy[:, None]).astype(np.int64)
    first_c = np.full((len(ex), 1), c0, np.int64)
    first_r = np.full((len(ex), 1), r0, np.int64)
    cc = np.concatenate([first_c, mx], axis=1)
    rr = np.concatenate([first_r, my], axis=1)
    ok = np.concatenate([np.ones((len(ex), 1), bool), valid], axis=1)
    # the cell holding the start of each segment is crossed; the beam's end cell is treated apart
    ok &= ~((cc == ce[:, None]) & (rr == re[:, None]))
    cells_c = np.concatenate([cc[ok], ce[include_end]])
    cells_r = np.concatenate([rr[ok], re[include_end]])
    inside = (cells_r >= 0) & (cells_r < rows) & (cells_c >= 0) & (cells_c < cols)
    return cells_r[inside] * cols + cells_c[inside]


def _scan_numpy(logodds: np.ndarray, sx: float, sy: float, ex: np.ndarray, ey: np.ndarray,
                hit: np.ndarray, l_free: float, l_occ: float, l_min: float, l_max: float) -> int:
    """The numpy version of :func:`_scan_kernel` (same cells, same updates)."""
    rows, cols = logodds.shape
    flat = logodds.reshape(-1)
    hc, hr = np.floor(ex[hit]).astype(np.int64), np.floor(ey[hit]).astype(np.int64)
    inside = (hr >= 0) & (hr < rows) & (hc >= 0) & (hc < cols)
    hit_cells = np.unique(hr[inside] * cols + hc[inside])
    free_cells = np.unique(_beam_cells_numpy(sx, sy, ex, ey, logodds.shape, ~hit))
    free_cells = free_cells[~np.isin(free_cells, hit_cells, assume_unique=True)]
    flat[free_cells] = np.maximum(flat[free_cells] + l_free, l_min)
    flat[hit_cells] = np.minimum(flat[hit_cells] + l_occ, l_max)
    return int(len(free_cells) + len(hit_cells))


# -- the grid ----------------------------------------------------------------------------------


class LogOddsGrid:
    """An occupancy grid of log-odds, updated scan by scan.

    Args:
        resolution: Cell size in metres (Nav2 ``resolution``).
        width_m: Initial width (x extent) in metres.
        height_m: Initial height (y extent) in metres.
        origin: Map position of the lower-left corner of cell (0, 0) (Nav2 ``origin``; yaw must be 0).
        l_occ: Log-odds added to a cell a beam ends in (default: p = 0.7, one hit makes it occupied).
        l_free: Log-odds added to a cell a beam passes through (default: p = 0.35, two passes make it free).
        l_min: Lower clamp (so an obstacle that appears is picked up within a few scans).
        l_max: Upper clamp (so an obstacle that leaves is cleared within a few scans).
        occupied_thresh: Probability above which a cell reads as occupied (map_server's 0.65).
        free_thresh: Probability below which a cell reads as free (map_server's 0.25).
        max_range: Beams are used up to this range (m); a return beyond it marks free space up
            to it and no obstacle. None: the scan's ``range_max``.
        hit_depth: A return's end point is taken this far (m) beyond its range, at most 0.45 of a
            cell, so that range noise does not put a surface's hit into the free cell before it.
        sensor_offset: (x, y) of the lidar in the robot base frame (LaserScan carries only the
            mount yaw).
        grow: Enlarge the grid when a scan reaches outside it (else beams are clipped).
        grow_step: Growth granularity in metres.
        accelerate: Use the numba kernel when numba is installed.
    """

    def __init__(self, resolution: float = 0.05, width_m: float = 20.0, height_m: float = 20.0,
                 origin: Pose2D | None = None, *, l_occ: float = 0.85, l_free: float = -0.6,
                 l_min: float = -2.0, l_max: float = 3.5, occupied_thresh: float = OCCUPIED_THRESH,
                 free_thresh: float = FREE_THRESH, max_range: float | None = None,
                 hit_depth: float = 0.02, sensor_offset: tuple[float, float] = (0.0, 0.0), grow: bool = True,
                 grow_step: float = 2.0, accelerate: bool = True) -> None:
        if resolution <= 0:
            raise ValueError(f"resolution must be > 0 m, found {resolution}")
        if width_m <= 0 or height_m <= 0:
            raise ValueError(f"grid size must be > 0 m, found {width_m} x {height_m}")
        if not 0.0 < free_thresh < occupied_thresh < 1.0:
            raise ValueError(f"expected 0 < free_thresh < occupied_thresh < 1, found {free_thresh} and "
                             f"{occupied_thresh}")
        if not 0.0 <= hit_depth < math.inf:
            raise ValueError(f"hit_depth must be >= 0 m, found {hit_depth}")
        if l_occ <= 0 or l_free >= 0:
            raise ValueError(f"expected l_occ > 0 and l_free < 0, found {l_occ} and {l_free}")
        origin = origin if origin is not None else Pose2D(-width_m / 2.0, -height_m / 2.0)
        if abs(origin.yaw) > 1e-9:
            raise ValueError(f"a rotated grid origin is not supported (yaw {origin.yaw}); use yaw 0")
        self.resolution = float(resolution)
        self.origin = Pose2D(float(origin.x), float(origin.y), 0.0)
        rows = int(math.ceil(height_m / resolution - 1e-9))
        cols = int(math.ceil(width_m / resolution - 1e-9))
        self.logodds = np.zeros((rows, cols), np.float32)
        self._free_mark = np.zeros((rows, cols), np.int32)
        self._hit_mark = np.zeros((rows, cols), np.int32)
        self.l_occ, self.l_free = float(l_occ), float(l_free)
        self.l_min, self.l_max = float(l_min), float(l_max)
        self.occupied_thresh, self.free_thresh = occupied_thresh, free_thresh
        self._l_occupied = logit(occupied_thresh)
        self._l_free_below = logit(free_thresh)
        self.max_range = max_range
        self.hit_depth = min(float(hit_depth), 0.45 * self.resolution)
        self.sensor_offset = (float(sensor_offset[0]), float(sensor_offset[1]))
        self.grow = grow
        self.grow_step = float(grow_step)
        self.accelerate = accelerate and HAVE_NUMBA
        self.scans = 0
        self.last_stamp: float | None = None

    # -- geometry ----------------------------------------------------------------------------------

    @property
    def shape(self) -> tuple[int, int]:
        """(rows, cols) of the grid."""
        return self.logodds.shape  # type: ignore[return-value]

    def world_to_cell(self, x: float, y: float) -> tuple[int, int]:
        """(row, col) of the cell holding map point (x, y); may be outside the grid."""
        return (int(math.floor((y - self.origin.y) / self.resolution)),
                int(math.floor((x - self.origin.x) / self.resolution)))

    def cell_to_world(self, row: int, col: int) -> tuple[float, float]:
        """Map coordinates of the centre of cell (row, col)."""
        return (self.origin.x + (col + 0.5) * self.resolution, self.origin.y + (row + 0.5) * self.resolution)

    # -- updates -----------------------------------------------------------------------------------

    def integrate(self, scan: LaserScan, pose: Pose2D) -> None:
        """Add one scan taken with the robot base at ``pose`` (the pose at ``scan.stamp``)."""
        sx_m, sy_m = pose.transform(*self.sensor_offset)
        ranges = np.asarray(scan.ranges, np.float64)
        angles = pose.yaw + scan.mount_yaw + scan.angle_min + scan.angle_increment * np.arange(len(ranges))
        reach = min(scan.range_max, self.max_range) if self.max_range is not None else scan.range_max
        valid = ~np.isnan(ranges) & (ranges >= scan.range_min)
        hit = valid & np.isfinite(ranges) & (ranges <= reach)
        length = np.where(hit, ranges + self.hit_depth, reach)[valid]
        angles, hit = angles[valid], hit[valid]
        ex_m = sx_m + length * np.cos(angles)
        ey_m = sy_m + length * np.sin(angles)
        if self.grow and len(ex_m):
            self._fit(min(float(ex_m.min()), sx_m), min(float(ey_m.min()), sy_m),
                      max(float(ex_m.max()), sx_m), max(float(ey_m.max()), sy_m))
        res = self.resolution
        sx, sy = (sx_m - self.origin.x) / res, (sy_m - self.origin.y) / res
        ex, ey = (ex_m - self.origin.x) / res, (ey_m - self.origin.y) / res
        if not self.grow:
            ex, ey, hit = self._clip(sx, sy, ex, ey, hit)
        self.scans += 1
        self.last_stamp = scan.stamp
        if self.accelerate:
            if self.scans >= 2**31 - 1:  # the marks compare scan ids; start again long before they wrap
                self._free_mark[:] = 0
                self._hit_mark[:] = 0
                self.scans = 1
            _scan_jit(self.logodds, self._free_mark, self._hit_mark, np.int32(self.scans), float(sx),
                      float(sy), np.ascontiguousarray(ex), np.ascontiguousarray(ey),
                      np.ascontiguousarray(hit), np.float32(self.l_free), np.float32(self.l_occ),
                      np.float32(self.l_min), np.float32(self.l_max))
        else:
            _scan_numpy(self.logodds, sx, sy, ex, ey, hit, self.l_free, self.l_occ, self.l_min, self.l_max)

    def update_from(self, scan: LaserScan | None, pose_at: Callable[[float], Pose2D | None]) -> bool:
        """Integrate ``scan`` at the pose the robot had at its stamp (e.g. ``robot.pose_at``).

        Returns True when it was integrated; False when there is no scan, it is not newer than
        the last one integrated, or the pose history does not cover its stamp.
        """
        if scan is None or (self.last_stamp is not None and scan.stamp <= self.last_stamp):
            return False
        pose = pose_at(scan.stamp)
        if pose is None:
            return False
        self.integrate(scan, pose)
        return True

    def _clip(self, sx: float, sy: float, ex: np.ndarray, ey: np.ndarray,
              hit: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Shorten beams that leave the grid to its border (their end is then no obstacle)."""
        rows, cols = self.shape
        eps = 1e-6
        t = np.ones_like(ex)
        with np.errstate(divide="ignore", invalid="ignore"):
            for lo, hi, s, e in ((0.0, cols - eps, sx, ex), (0.0, rows - eps, sy, ey)):
                d = e - s
                t = np.where(e > hi, np.minimum(t, (hi - s) / d), t)
                t = np.where(e < lo, np.minimum(t, (lo - s) / d), t)
        t = np.clip(t, 0.0, 1.0)
        cut = t < 1.0
        return sx + t * (ex - sx), sy + t * (ey - sy), hit & ~cut

    def _fit(self, xmin: float, ymin: float, xmax: float, ymax: float) -> None:
        """Pad the grid (in whole ``grow_step``) so the box [xmin, xmax] x [ymin, ymax] is inside."""
        res = self.resolution
        rows, cols = self.shape
        step = max(1, int(round(self.grow_step / res)))
        c_lo, r_lo = math.floor((xmin - self.origin.x) / res), math.floor((ymin - self.origin.y) / res)
        c_hi, r_hi = math.floor((xmax - self.origin.x) / res), math.floor((ymax - self.origin.y) / res)
        left = -(-max(0, -c_lo) // step) * step if c_lo < 0 else 0
        bottom = -(-max(0, -r_lo) // step) * step if r_lo < 0 else 0
        right = -(-max(0, c_hi - cols + 1) // step) * step if c_hi >= cols else 0
        top = -(-max(0, r_hi - rows + 1) // step) * step if r_hi >= rows else 0
        if not (left or bottom or right or top):
            return
        pad = ((bottom, top), (left, right))
        self.logodds = np.pad(self.logodds, pad)
        self._free_mark = np.pad(self._free_mark, pad)
        self._hit_mark = np.pad(self._hit_mark, pad)
        self.origin = Pose2D(self.origin.x - left * res, self.origin.y - bottom * res, 0.0)

    # -- reading -----------------------------------------------------------------------------------

    def probabilities(self) -> np.ndarray:
        """Probability of occupancy per cell (0.5 where nothing was seen)."""
        return 1.0 / (1.0 + np.exp(-self.logodds.astype(np.float64)))

    def trinary(self) -> np.ndarray:
        """int8 cells: 100 occupied, 0 free, -1 unknown (map_server's trinary thresholds)."""
        data = np.full(self.shape, UNKNOWN, np.int8)
        data[self.logodds < self._l_free_below] = FREE
        data[self.logodds > self._l_occupied] = OCCUPIED
        return data

    def to_occupancy(self, stamp: float | None = None) -> OccupancyGrid:
        """The map as an OccupancyGrid (a copy), stamped ``stamp`` (default: the last scan's)."""
        when = stamp if stamp is not None else (self.last_stamp or 0.0)
        return OccupancyGrid(float(when), self.resolution, self.origin, self.trinary())

    def known_area(self) -> float:
        """Area (m^2) of the cells that read free or occupied."""
        return float(np.count_nonzero(self.trinary() != UNKNOWN)) * self.resolution**2


# -- reading any OccupancyGrid (trinary or scaled 0..100) ------------------------------------------

# the thresholds that read any grid: missiontree.mapping.occupancy (FREE_BELOW, OCCUPIED_FROM)


def free_mask(grid: OccupancyGrid) -> np.ndarray:
    """Bool mask of the cells known to be free."""
    return (grid.data >= 0) & (grid.data < FREE_BELOW)


def occupied_mask(grid: OccupancyGrid) -> np.ndarray:
    """Bool mask of the cells known to be occupied."""
    return grid.data >= OCCUPIED_FROM


def unknown_mask(grid: OccupancyGrid) -> np.ndarray:
    """Bool mask of the cells neither known free nor known occupied."""
    return ~(free_mask(grid) | occupied_mask(grid))
