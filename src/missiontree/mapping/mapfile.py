"""Map files in Nav2 map_server's format: ``map.pgm`` + ``map.yaml``, written and read.

:func:`write_map` writes what ``ros2 run nav2_map_server map_saver_cli`` writes in trinary mode:
a binary PGM (P5) with free cells 254, occupied 0 and unknown 205, the top image row being the
map's highest y, and a YAML with ``image``, ``mode: trinary``, ``resolution``, ``origin``,
``negate: 0``, ``occupied_thresh: 0.65`` and ``free_thresh: 0.196`` (map_saver's value, under
which the unknown grey 205 reads back as unknown, not free). Nav2's map_server loads the pair,
and so does missiontree's world loader (a world file with ``map: {yaml: map.yaml}``).

:func:`read_map` reads such a pair back into an OccupancyGrid with map_server's rules for the
``trinary``, ``scale`` and ``raw`` modes and ``negate`` (PGM and, through OpenCV, PNG images).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import yaml

from missiontree.errors import ProblemsError
from missiontree.file_limits import MAX_MAP_IMAGE_BYTES, read_bounded
from missiontree.files import write_whole
from missiontree.mapping.grid import FREE_BELOW, OCCUPIED_FROM
from missiontree.types import OccupancyGrid, Pose2D
from missiontree.yamlio import load_yaml

FREE_PIXEL, OCCUPIED_PIXEL, UNKNOWN_PIXEL = 254, 0, 205
SAVER_OCCUPIED_THRESH = 0.65
SAVER_FREE_THRESH = 0.196


class MapFileError(ValueError):
    """A map yaml or image that cannot be read; the message says which file and what is wrong."""


def map_image(grid: OccupancyGrid) -> np.ndarray:
    """The trinary map_saver image of ``grid`` (uint8, top row = highest y)."""
    image = np.full(grid.data.shape, UNKNOWN_PIXEL, np.uint8)
    data = grid.data
    image[(data >= 0) & (data < FREE_BELOW)] = FREE_PIXEL
    image[data >= OCCUPIED_FROM] = OCCUPIED_PIXEL
    return np.ascontiguousarray(np.flipud(image))


def write_map(grid: OccupancyGrid, directory: str | Path, name: str = "map") -> tuple[Path, Path]:
    """Write ``<directory>/<name>.pgm`` and ``<directory>/<name>.yaml`` (map_server trinary format).

    Returns:
        (pgm path, yaml path).
    """
    if abs(grid.origin.yaw) > 1e-9:
        raise ValueError(f"map_server maps are axis-aligned here; origin yaw {grid.origin.yaw} is not 0")
    out = Path(directory)
    out.mkdir(parents=True, exist_ok=True)
    pgm, meta = out / f"{name}.pgm", out / f"{name}.yaml"
    image = map_image(grid)
    h, w = image.shape
    header = f"P5\n# CREATOR: missiontree {grid.resolution:.3f} m/pix\n{w} {h}\n255\n".encode("ascii")
    _atomic_write(pgm, header + image.tobytes())
    doc = {
        "image": pgm.name,
        "mode": "trinary",
        "resolution": float(grid.resolution),
        "origin": [float(grid.origin.x), float(grid.origin.y), 0.0],
        "negate": 0,
        "occupied_thresh": SAVER_OCCUPIED_THRESH,
        "free_thresh": SAVER_FREE_THRESH,
    }
    _atomic_write(meta, yaml.safe_dump(doc, sort_keys=False, default_flow_style=None).encode("utf-8"))
    return pgm, meta


def read_map(yaml_path: str | Path, stamp: float = 0.0) -> OccupancyGrid:
    """Read a map_server map (yaml + image) into an OccupancyGrid (-1 / 0 ... 100).

    Raises:
        MapFileError: The yaml or image is missing or malformed (names the file and the key).
    """
    path = Path(yaml_path)
    try:
        doc = load_yaml(path).data
    except ProblemsError as exc:
        raise MapFileError(f"{path}: cannot read the map yaml: {exc.problems[0].message}") from None
    if not isinstance(doc, dict):
        raise MapFileError(f"{path}: expected a mapping with image, resolution and origin, found "
                           f"{type(doc).__name__}")
    for key in ("image", "resolution", "origin"):
        if key not in doc:
            raise MapFileError(f"{path}: missing key `{key}` (map_server needs image, resolution and origin)")
    try:
        resolution = float(doc["resolution"])
        origin = [float(v) for v in doc["origin"]]
        negate = int(doc.get("negate", 0))
        occ_t = float(doc.get("occupied_thresh", SAVER_OCCUPIED_THRESH))
        free_t = float(doc.get("free_thresh", 0.25))
    except (TypeError, ValueError) as exc:
        raise MapFileError(f"{path}: a numeric key is not a number: {exc}") from None
    if not resolution > 0 or len(origin) != 3 or not all(math.isfinite(v) for v in origin):
        raise MapFileError(f"{path}: expected resolution > 0 and origin [x, y, yaw], found "
                           f"{doc['resolution']!r} and {doc['origin']!r}")
    mode = str(doc.get("mode", "trinary"))
    if mode not in ("trinary", "scale", "raw"):
        raise MapFileError(f"{path}: mode must be trinary, scale or raw, found {mode!r}")
    image = _read_image(path.parent / str(doc["image"]), path)
    if mode == "raw":
        cells = np.where(image <= 100, image, -1).astype(np.int8)
    else:
        occ = image.astype(np.float64) / 255.0
        occ = occ if negate else 1.0 - occ
        cells = np.full(image.shape, -1, np.int8)
        cells[occ < free_t] = 0
        if mode == "scale":
            between = (occ >= free_t) & (occ <= occ_t)
            scaled = 99.0 * (occ - free_t) / max(occ_t - free_t, 1e-9)
            cells[between] = scaled[between].astype(np.int8)
        cells[occ > occ_t] = 100
    return OccupancyGrid(stamp, resolution, Pose2D(origin[0], origin[1], origin[2]), np.flipud(cells).copy())


def _read_image(image_path: Path, yaml_path: Path) -> np.ndarray:
    if not image_path.is_file():
        raise MapFileError(f"{yaml_path}: map image {image_path} does not exist")
    try:
        data = read_bounded(image_path, MAX_MAP_IMAGE_BYTES, "map image")
    except OSError as exc:
        raise MapFileError(f"{yaml_path}: cannot read the map image: {exc}") from None
    if data[:2] == b"P5":
        return _parse_pgm(data, image_path)
    import cv2

    image = cv2.imread(str(image_path), cv2.IMREAD_GRAYSCALE)
    if image is None:
        raise MapFileError(f"{yaml_path}: {image_path} is not an image OpenCV can read")
    return image


def _parse_pgm(data: bytes, where: Path) -> np.ndarray:
    """A binary 8-bit PGM (comments allowed in the header)."""
    fields: list[bytes] = []
    i = 2
    while len(fields) < 3:
        while i < len(data) and data[i:i + 1].isspace():
            i += 1
        if data[i:i + 1] == b"#":
            while i < len(data) and data[i:i + 1] not in (b"\n", b"\r"):
                i += 1
            continue
        j = i
        while j < len(data) and not data[j:j + 1].isspace():
            j += 1
        if j == i:
            raise MapFileError(f"{where}: truncated PGM header")
        fields.append(data[i:j])
        i = j
    try:
        w, h, maxval = (int(f) for f in fields)
    except ValueError:
        raise MapFileError(f"{where}: malformed PGM header {fields!r}") from None
    if maxval > 255:
        raise MapFileError(f"{where}: 16-bit PGM is not supported (maxval {maxval})")
    i += 1  # the single whitespace after maxval
    pixels = np.frombuffer(data, np.uint8, count=w * h, offset=i) if len(data) - i >= w * h else None
    if pixels is None:
        raise MapFileError(f"{where}: PGM holds fewer than {w} x {h} pixels")
    return pixels.reshape(h, w)


def _atomic_write(path: Path, payload: bytes) -> None:
    """Replace ``path`` whole (:func:`missiontree.files.write_whole`: a writer's own temporary name)."""
    write_whole(path, payload)
