"""MRPT's ``CArchive`` binary serialization, read: the primitives and object headers of its files.

MRPT (the Mobile Robot Programming Toolkit) writes every ``CSerializable`` object as a header, the
object's own fields in its ``serializeTo`` order, and an end flag (``libs/serialization``,
``CArchive.cpp``; little-endian throughout):

- header: one byte ``0x80 | n``, then the ``n``-byte class name (``CPose2D``; newer files spell it
  with its namespace, ``mrpt::poses::CPose2D``), then the serialization version as one byte. Streams
  from before MRPT 0.5.5 write the name length as a 32-bit integer instead (first byte without
  ``0x80``) and the version as a 32-bit integer, with no end flag;
- a ``bool`` is one byte, a ``std::string`` a ``uint32`` length and its bytes, a timestamp
  (``TTimeStamp``) a ``uint64`` count of 100 ns ticks since 1601-01-01 (Windows' FILETIME);
- end flag ``0x88`` after the fields.

No field carries its length, so an object of a class this module does not know cannot be skipped:
the reader stops there with an :class:`ArchiveError` naming the class and the byte offset.
:class:`ArchiveReader` reads from bytes already in memory (a file is read whole, at most
:data:`MAX_ARCHIVE_BYTES` after decompression) and checks every count against the bytes left
before allocating, so a malformed file costs no more than its size.
"""

from __future__ import annotations

import gzip
import math
import struct
import zlib
from pathlib import Path

import numpy as np

#: Largest archive read (after gunzip): MRPT's RGB-D sample is 5.9 MB, its laser loop 0.5 MB.
MAX_ARCHIVE_BYTES = 256 * 2**20
#: MRPT's end-of-object flag (since MRPT 0.5.5).
END_FLAG = 0x88
#: Seconds from 1601-01-01 (MRPT's and Windows' epoch) to 1970-01-01 (Unix's).
EPOCH_1601_TO_1970 = 11_644_473_600
_GZIP_MAGIC = b"\x1f\x8b"


class ArchiveError(ValueError):
    """An MRPT archive that cannot be read; the message names the file, the offset and what is wrong."""


def load_archive_bytes(path: str | Path) -> bytes:
    """The bytes of an MRPT archive file, gunzipped when it is gzipped (read from its first bytes).

    Raises:
        ArchiveError: The file is missing, unreadable or larger than :data:`MAX_ARCHIVE_BYTES`.
    """
    path = Path(path)
    try:
        with path.open("rb") as raw:
            if raw.read(2) != _GZIP_MAGIC:
                raw.seek(0)
                data = raw.read(MAX_ARCHIVE_BYTES + 1)
            else:
                raw.seek(0)
                with gzip.GzipFile(fileobj=raw, mode="rb") as stream:
                    data = stream.read(MAX_ARCHIVE_BYTES + 1)
    except (OSError, EOFError, zlib.error) as exc:  # gzip.BadGzipFile is an OSError
        raise ArchiveError(f"{path}: cannot read the MRPT archive: {exc}") from None
    if len(data) > MAX_ARCHIVE_BYTES:
        raise ArchiveError(f"{path}: expected an archive of at most {MAX_ARCHIVE_BYTES // 2**20} MiB "
                           "(uncompressed), found more")
    return data


def mrpt_time_to_unix(ticks: int) -> float:
    """Seconds since 1970 of an MRPT ``TTimeStamp`` (100 ns ticks since 1601); NaN for 0 (invalid)."""
    if ticks == 0:
        return math.nan
    return ticks / 1e7 - EPOCH_1601_TO_1970


class ArchiveReader:
    """A cursor over an MRPT archive in memory: primitives, arrays and object headers.

    Args:
        data: The archive's bytes (already gunzipped).
        source: Name of the file, used in error messages.
    """

    def __init__(self, data: bytes, source: str = "<archive>") -> None:
        self.data = memoryview(data)
        self.source = source
        self.pos = 0

    @property
    def remaining(self) -> int:
        """Bytes not read yet."""
        return len(self.data) - self.pos

    def at_end(self) -> bool:
        """Whether every byte has been read."""
        return self.pos >= len(self.data)

    def error(self, message: str) -> ArchiveError:
        """An ArchiveError naming the file and the current offset."""
        return ArchiveError(f"{self.source}: at byte {self.pos:,}: {message}")

    def take(self, count: int, what: str) -> memoryview:
        """The next ``count`` bytes; an error naming ``what`` when the archive ends first."""
        if count < 0 or count > self.remaining:
            raise self.error(f"the archive ends inside {what} (expected {count:,} bytes, "
                             f"found {self.remaining:,})")
        chunk = self.data[self.pos:self.pos + count]
        self.pos += count
        return chunk

    def unpack(self, fmt: str, what: str) -> tuple[int | float, ...]:
        """Values of the little-endian struct format ``fmt`` (without its ``<``)."""
        size = struct.calcsize("<" + fmt)
        return struct.unpack("<" + fmt, self.take(size, what))

    def u8(self, what: str) -> int:
        """One unsigned byte."""
        return int(self.take(1, what)[0])

    def boolean(self, what: str) -> bool:
        """A C++ ``bool`` (one byte)."""
        return self.u8(what) != 0

    def u32(self, what: str) -> int:
        """A ``uint32``."""
        return int(self.unpack("I", what)[0])

    def i32(self, what: str) -> int:
        """An ``int32``."""
        return int(self.unpack("i", what)[0])

    def u64(self, what: str) -> int:
        """A ``uint64``."""
        return int(self.unpack("Q", what)[0])

    def f32(self, what: str) -> float:
        """A ``float``."""
        return float(self.unpack("f", what)[0])

    def f64(self, what: str) -> float:
        """A ``double``."""
        return float(self.unpack("d", what)[0])

    def string(self, what: str, limit: int = 4096) -> str:
        """A ``std::string`` (uint32 length, then its bytes; read as UTF-8 with replacement)."""
        length = self.u32(f"{what}'s length")
        if length > limit:
            raise self.error(f"expected {what} of at most {limit} bytes, found a length of {length:,}")
        return bytes(self.take(length, what)).decode("utf-8", "replace")

    def array(self, dtype: str, count: int, what: str) -> np.ndarray:
        """``count`` values of the little-endian numpy ``dtype`` (a copy)."""
        item = np.dtype(dtype).newbyteorder("<")
        return np.frombuffer(self.take(count * item.itemsize, what), item).astype(item.newbyteorder("="))

    def header(self) -> tuple[str, int, bool]:
        """An object header: (class name without namespace, version, old format?)."""
        start = self.pos
        first = self.u8("an object header")
        old_format = not first & 0x80
        if old_format:
            if bytes(self.take(3, "an object header")) != b"\0\0\0":
                self.pos = start
                found = bytes(self.data[start:start + 4])
                raise self.error(f"expected an object header, found bytes {found!r}")
        length = first & 0x7F
        if length > 120:
            self.pos = start
            raise self.error(f"expected a class name of at most 120 bytes, found a length of {length}")
        name = bytes(self.take(length, "a class name")).decode("ascii", "replace")
        if name == "nullptr":
            return name, 0, old_format
        version = self.i32(f"{name}'s version") if old_format else self.u8(f"{name}'s version")
        return name.rsplit("::", 1)[-1], version, old_format

    def expect_header(self, *names: str) -> tuple[str, int, bool]:
        """An object header whose class is one of ``names``; an error naming what was found otherwise."""
        start = self.pos
        name, version, old_format = self.header()
        if name not in names:
            self.pos = start
            raise self.error(f"expected an object of class {' or '.join(names)}, found {name!r}")
        return name, version, old_format

    def end(self, name: str, old_format: bool) -> None:
        """The end flag after an object's fields (none in the old format)."""
        if old_format:
            return
        flag = self.u8(f"{name}'s end flag")
        if flag != END_FLAG:
            self.pos -= 1
            raise self.error(f"expected the end flag 0x88 after {name}, found 0x{flag:02x} (a field layout "
                             "this reader does not know, or a damaged file)")

    def unknown_version(self, name: str, version: int, known: str) -> ArchiveError:
        """The error for a serialization version this reader does not know."""
        return self.error(f"{name} serialization version {version} is unknown (known: {known})")

    # -- small MRPT objects every observation uses ---------------------------------------------------

    def matrix(self) -> np.ndarray:
        """A ``CMatrixD`` / ``CMatrixF`` object (rows, cols, then the values row by row)."""
        name, version, old = self.expect_header("CMatrixD", "CMatrixF", "CMatrix")
        if version != 0:
            raise self.unknown_version(name, version, "0")
        rows, cols = self.u32("the matrix rows"), self.u32("the matrix columns")
        if rows * cols > 4096:
            raise self.error(f"expected a small matrix (a pose or covariance), found {rows} x {cols}")
        values = self.array("f8" if name == "CMatrixD" else "f4", rows * cols, "the matrix values")
        self.end(name, old)
        return values.reshape(rows, cols).astype(np.float64)

    def pose2d(self) -> tuple[float, float, float]:
        """A ``CPose2D`` object: (x, y, phi)."""
        name, version, old = self.expect_header("CPose2D")
        if version == 0:
            x, y, phi = (float(v) for v in self.unpack("fff", "the CPose2D"))
        elif version == 1:
            x, y, phi = (float(v) for v in self.unpack("ddd", "the CPose2D"))
        else:
            raise self.unknown_version(name, version, "0, 1")
        self.end(name, old)
        return x, y, phi

    def pose3d(self) -> np.ndarray:
        """A ``CPose3D`` object as a 4 x 4 homogeneous matrix."""
        name, version, old = self.expect_header("CPose3D")
        pose = np.eye(4)
        if version in (0, 1):
            matrix = self.matrix()
            if matrix.shape != (4, 4):
                raise self.error(f"expected a 4 x 4 CPose3D matrix, found {matrix.shape}")
            pose = matrix
        elif version == 2:  # x y z qr qx qy qz
            x, y, z, qr, qx, qy, qz = (float(v) for v in self.unpack("7d", "the CPose3D"))
            pose[:3, :3] = _quaternion_matrix(qr, qx, qy, qz)
            pose[:3, 3] = (x, y, z)
        elif version == 3:  # x y z, then the rotation matrix row by row
            values = self.array("f8", 12, "the CPose3D")
            pose[:3, 3] = values[:3]
            pose[:3, :3] = values[3:].reshape(3, 3)
        else:
            raise self.unknown_version(name, version, "0 to 3")
        self.end(name, old)
        return pose


def _quaternion_matrix(w: float, x: float, y: float, z: float) -> np.ndarray:
    norm = math.sqrt(w * w + x * x + y * y + z * z) or 1.0
    w, x, y, z = w / norm, x / norm, y / norm, z / norm
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def yaw_of(pose: np.ndarray) -> float:
    """Yaw (rotation about z) of a 4 x 4 pose."""
    return math.atan2(float(pose[1, 0]), float(pose[0, 0]))
