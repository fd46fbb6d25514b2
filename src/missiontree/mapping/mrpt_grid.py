"""MRPT occupancy-grid files (``.gridmap`` and ``.gridmap.gz``) read into an :class:`OccupancyGrid`.

MRPT (the Mobile Robot Programming Toolkit) saves a ``COccupancyGridMap2D`` as one serialized object,
optionally gzip-compressed. The layout, as MRPT's ``CArchive`` and ``COccupancyGridMap2D_io.cpp``
write it (little-endian throughout):

- object header: one byte ``0x80 | n`` then the ``n``-byte class name ``COccupancyGridMap2D``, then the
  serialization version as one byte (versions 0 to 6 are known). Streams from before MRPT 0.5.5 use
  the old header instead: the name length as a 32-bit integer (the first byte without ``0x80``), the
  name, and the version as a 32-bit integer, with no end flag;
- from version 2, the bits per cell (8 or 16; before, 8 is assumed);
- ``size_x``, ``size_y`` (uint32), ``x_min``, ``x_max``, ``y_min``, ``y_max``, ``resolution`` (float32);
- ``size_x * size_y`` cells, x fastest, the first row at ``y_min``: signed log-odds of the cell being
  *free* from version 3 (positive free, negative occupied, 0 unknown); before version 3, unsigned
  probabilities of being free (128 of 255 unknown);
- the map's insertion and likelihood options (not needed here, skipped), then the end flag ``0x88``.

:func:`read_gridmap` checks the file size before reading, the header and the grid's size before
reading the cells (at most :data:`MAX_GRIDMAP_CELLS`), and reads exactly the cells' bytes from the
stream, so a malformed or hostile file costs no more than its header says and ends in a
:class:`GridmapError` naming the file.
"""

from __future__ import annotations

import gzip
import math
import struct
import zlib
from pathlib import Path
from typing import IO

import numpy as np

from missiontree.types import OccupancyGrid, Pose2D

#: Largest gridmap file read from disk (compressed or not): MRPT's Malaga campus grid is 0.8 MiB gzipped.
MAX_GRIDMAP_BYTES = 64 * 2**20
#: Largest grid read (cells): the Malaga campus grid has 5.2 M; anything past this is refused unread.
MAX_GRIDMAP_CELLS = 32_000_000
#: Largest tail (options and end flag) read after the cells: MRPT's own files have about 500 bytes.
MAX_TAIL_BYTES = 64 * 1024
#: The class name MRPT writes in front of an occupancy grid.
CLASS_NAME = "COccupancyGridMap2D"
#: Serialization versions of ``COccupancyGridMap2D`` that MRPT's reader knows.
KNOWN_VERSIONS = range(0, 7)
#: MRPT's end-of-object flag (since MRPT 0.5.5).
END_FLAG = 0x88
_GZIP_MAGIC = b"\x1f\x8b"


class GridmapError(ValueError):
    """A gridmap file that cannot be read; the message names the file and what is wrong."""


def read_gridmap(path: str | Path, stamp: float = 0.0) -> OccupancyGrid:
    """Read an MRPT ``.gridmap`` or ``.gridmap.gz`` into an OccupancyGrid (-1 unknown, 0 free, 100 occupied).

    The grid's cell (0, 0) is MRPT's (``x_min``, ``y_min``) corner, so the origin is (x_min, y_min)
    and row 0 is the lowest y, as in ROS. Whether a file is gzipped is read from its first bytes.

    Args:
        path: The file.
        stamp: Stamp given to the grid.

    Raises:
        GridmapError: The file is missing, too large, not an MRPT occupancy grid, of an unknown
            version or cell size, inconsistent or cut short (the message names the file).
    """
    path = Path(path)
    try:
        size = path.stat().st_size
    except OSError as exc:
        raise GridmapError(f"{path}: cannot read the gridmap: {exc.strerror or exc}") from None
    if size > MAX_GRIDMAP_BYTES:
        raise GridmapError(f"{path}: expected a gridmap of at most {MAX_GRIDMAP_BYTES // 2**20} MiB, "
                           f"found {size / 2**20:.1f} MiB")
    try:
        with path.open("rb") as raw:
            gzipped = raw.read(2) == _GZIP_MAGIC
            raw.seek(0)
            if gzipped:
                with gzip.GzipFile(fileobj=raw, mode="rb") as stream:
                    return _read(stream, path, stamp)
            return _read(raw, path, stamp)
    except (OSError, EOFError, zlib.error) as exc:  # gzip.BadGzipFile is an OSError
        raise GridmapError(f"{path}: cannot read the gridmap: {exc}") from None


def _read(stream: IO[bytes] | gzip.GzipFile, path: Path, stamp: float) -> OccupancyGrid:
    version, old_format = _header(stream, path)
    bits = 8 if version < 2 else _exact(stream, 1, path, "the bits per cell")[0]
    if bits not in (8, 16):
        raise GridmapError(f"{path}: expected 8 or 16 bits per cell, found {bits}")
    nx, ny = (int(v) for v in _unpack(stream, "<II", path, "the grid size"))
    # float32 in the file: rounded to 0.1 mm (bounds) and 1 µm (resolution), 0.08 m reads as 0.08
    x_min, x_max, y_min, y_max = (round(float(v), 4) for v in _unpack(stream, "<ffff", path, "the bounds"))
    res = round(float(_unpack(stream, "<f", path, "the resolution")[0]), 6)
    if not all(math.isfinite(v) for v in (x_min, x_max, y_min, y_max, res)) or res <= 0:
        raise GridmapError(f"{path}: expected finite bounds and a resolution > 0, found "
                           f"x {x_min:g}..{x_max:g}, y {y_min:g}..{y_max:g}, resolution {res:g}")
    if nx == 0 or ny == 0 or nx * ny > MAX_GRIDMAP_CELLS:
        raise GridmapError(f"{path}: expected a grid of 1 to {MAX_GRIDMAP_CELLS:,} cells, found {nx} x {ny}")
    # MRPT sizes the grid from its bounds: they must agree with the cell counts (within a cell)
    if abs((x_max - x_min) / res - nx) > 1.01 or abs((y_max - y_min) / res - ny) > 1.01:
        raise GridmapError(f"{path}: grid of {nx} x {ny} cells of {res:g} m does not fit its bounds "
                           f"x {x_min:g}..{x_max:g}, y {y_min:g}..{y_max:g}")
    count = nx * ny
    cell_bytes = _exact(stream, count * bits // 8, path, f"{nx} x {ny} cells")
    if bits == 8:
        values = np.frombuffer(cell_bytes, np.int8 if version >= 3 else np.uint8)
    else:  # MRPT reads a 16-bit stream into 8-bit cells by its high byte
        values = np.frombuffer(cell_bytes, "<i2" if version >= 3 else "<u2") >> 8
    if version >= 3:
        free, occupied = values > 0, values < 0
    else:  # probability of being free, 0..255; 128 is MRPT's unknown 0.5
        free, occupied = values > 128, values < 127
    data = np.full(count, -1, np.int8)
    data[free] = 0
    data[occupied] = 100
    tail = stream.read(MAX_TAIL_BYTES + 1)
    if len(tail) > MAX_TAIL_BYTES:
        raise GridmapError(f"{path}: expected at most {MAX_TAIL_BYTES:,} bytes of options after the cells, "
                           "found more (not one occupancy grid?)")
    if not old_format and (not tail or tail[-1] != END_FLAG):
        raise GridmapError(f"{path}: the end flag 0x88 is missing after the grid (the file is cut short "
                           "or not one occupancy grid)")
    return OccupancyGrid(stamp, res, Pose2D(x_min, y_min, 0.0), data.reshape(ny, nx))


def _header(stream: IO[bytes] | gzip.GzipFile, path: Path) -> tuple[int, bool]:
    """The serialization version after MRPT's object header, and whether the header is the old one."""
    first = _exact(stream, 1, path, "the object header")[0]
    old_format = not first & 0x80
    if old_format:
        rest = _exact(stream, 3, path, "the object header")
        if rest != b"\0\0\0":
            raise GridmapError(f"{path}: not an MRPT gridmap (expected an object header, found bytes "
                               f"{bytes([first]) + rest!r})")
    length = first & 0x7F
    name = _exact(stream, length, path, "the class name")
    if name != CLASS_NAME.encode("ascii"):
        shown = name[:40].decode("ascii", "replace")
        raise GridmapError(f"{path}: expected an MRPT {CLASS_NAME}, found an object of class {shown!r}")
    version = (int(_unpack(stream, "<i", path, "the version")[0]) if old_format
               else _exact(stream, 1, path, "the version")[0])
    if version not in KNOWN_VERSIONS:
        raise GridmapError(f"{path}: {CLASS_NAME} serialization version {version} is unknown "
                           f"(known: {KNOWN_VERSIONS.start} to {KNOWN_VERSIONS.stop - 1})")
    return version, old_format


def _unpack(stream: IO[bytes] | gzip.GzipFile, fmt: str, path: Path, what: str) -> tuple[int | float, ...]:
    return struct.unpack(fmt, _exact(stream, struct.calcsize(fmt), path, what))


def _exact(stream: IO[bytes] | gzip.GzipFile, count: int, path: Path, what: str) -> bytes:
    data = stream.read(count)
    if len(data) != count:
        raise GridmapError(f"{path}: the file ends inside {what} "
                           f"(expected {count:,} bytes, found {len(data):,})")
    return data
