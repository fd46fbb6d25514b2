"""Reading a Nav2 map image safely: the size is checked from the header before anything is decoded.

A map header can promise 100,000 x 100,000 pixels in a file of a few hundred bytes; decoding it
would allocate 10 GB. :func:`read_map_image` reads the width and height from the header of the
formats map_server maps come in (PGM, PNG, BMP), refuses images over :data:`MAX_MAP_CELLS`
pixels or files over :data:`MAX_MAP_BYTES`, and only then decodes with OpenCV. Other formats are
refused with a hint to convert them.
"""

from __future__ import annotations

import struct
from pathlib import Path

import cv2
import numpy as np

#: Largest map image (and world grid) accepted, in cells: a 100 m square at 5 cm with its margin
#: (2,020 x 2,020) and MRPT's Malaga campus grid (1,888 x 2,738) fit; a header promising more is
#: refused before anything is decoded.
MAX_MAP_CELLS = 6_000_000
#: Largest map image file accepted, in bytes.
MAX_MAP_BYTES = 32 * 1024 * 1024


class MapImageError(ValueError):
    """A map image that cannot be read; the message says why, ``hint`` how to fix it."""

    def __init__(self, message: str, hint: str = "") -> None:
        super().__init__(message)
        self.hint = hint


def image_size(path: Path) -> tuple[int, int]:
    """(width, height) from the file's header; PGM, PNG and BMP are understood.

    Raises:
        MapImageError: Another format, or a header that cannot be read.
    """
    with path.open("rb") as handle:
        head = handle.read(512)
    if head[:2] in (b"P5", b"P2"):
        return _pgm_size(head)
    if head[:8] == b"\x89PNG\r\n\x1a\n":
        if len(head) < 24 or head[12:16] != b"IHDR":
            raise MapImageError("expected a PNG header, found a truncated one")
        width, height = struct.unpack(">II", head[16:24])
        return int(width), int(height)
    if head[:2] == b"BM":
        if len(head) < 26:
            raise MapImageError("expected a BMP header, found a truncated one")
        width, height = struct.unpack("<ii", head[18:26])
        return abs(int(width)), abs(int(height))
    raise MapImageError("expected a PGM, PNG or BMP image, found another format",
                        "convert the map to PGM (what map_saver writes) or PNG")


def _pgm_size(head: bytes) -> tuple[int, int]:
    fields: list[int] = []
    tokens = []
    for line in head[2:].split(b"\n"):
        line = line.split(b"#", 1)[0]
        tokens += line.split()
        if len(tokens) >= 2:
            break
    try:
        fields = [int(t) for t in tokens[:2]]
    except ValueError:
        fields = []
    if len(fields) < 2:
        raise MapImageError("expected a PGM header with width and height, found none")
    return fields[0], fields[1]


def read_map_image(path: Path) -> np.ndarray:
    """The image as 8-bit grayscale, after checking its header's size and the file's size.

    Raises:
        MapImageError: Too large, another format, or not decodable.
    """
    size = path.stat().st_size
    if size > MAX_MAP_BYTES:
        raise MapImageError(f"expected a file of at most {MAX_MAP_BYTES:,} bytes, found {size:,} bytes",
                            "crop the map or lower its resolution")
    width, height = image_size(path)
    if width <= 0 or height <= 0:
        raise MapImageError(f"expected a positive width and height, found {width} x {height}")
    if width * height > MAX_MAP_CELLS:
        raise MapImageError(f"expected at most {MAX_MAP_CELLS:,} pixels, found {width:,} x {height:,}",
                            "crop the map or lower its resolution")
    image = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
    if image is None:
        raise MapImageError("expected a readable image, found one that does not decode",
                            "save the map again with map_saver")
    if image.shape != (height, width):
        raise MapImageError(f"expected {width} x {height} pixels as the header says, found "
                            f"{image.shape[1]} x {image.shape[0]}")
    return image
