"""MRPT gridmap reader: synthetic files written here, and MRPT's own grids when mrpt-common is installed."""

from __future__ import annotations

import gzip
import struct
from pathlib import Path

import numpy as np
import pytest

from missiontree.mapping import mrpt_grid
from missiontree.mapping.mrpt_datasets import find_dataset, missing_reason
from missiontree.mapping.mrpt_grid import GridmapError, read_gridmap

DATASETS = (find_dataset("2006-MalagaCampus.gridmap.gz") or Path("/nonexistent/x")).parent
NEEDS_MRPT = pytest.mark.skipif(
    not (DATASETS / "2006-MalagaCampus.gridmap.gz").is_file(),
    reason=missing_reason("2006-MalagaCampus.gridmap.gz"),
)


def gridmap_bytes(cells: np.ndarray, *, res: float = 0.1, x_min: float = -1.0, y_min: float = -2.0,
                  version: int = 3, bits: int = 8, old_header: bool = False, end: bool = True,
                  name: bytes = b"COccupancyGridMap2D") -> bytes:
    """An MRPT COccupancyGridMap2D stream as MRPT writes it (``cells[row, col]``, row 0 at y_min)."""
    ny, nx = cells.shape
    if old_header:
        out = struct.pack("<I", len(name)) + name + struct.pack("<i", version)
    else:
        out = bytes([0x80 | len(name)]) + name + bytes([version])
    if version >= 2:
        out += bytes([bits])
    out += struct.pack("<IIfffff", nx, ny, x_min, x_min + nx * res, y_min, y_min + ny * res, res)
    if bits == 8:
        out += cells.astype(np.int8 if version >= 3 else np.uint8).tobytes()
    else:
        out += cells.astype("<i2" if version >= 3 else "<u2").tobytes()
    out += b"\x00" * 40  # stands in for the options MRPT writes after the cells
    return out + (b"\x88" if end and not old_header else b"")


def write(tmp_path: Path, payload: bytes, name: str = "map.gridmap") -> Path:
    path = tmp_path / name
    path.write_bytes(payload)
    return path


def sample() -> np.ndarray:
    """Three rows: free, occupied and unknown cells in known places."""
    return np.array([[100, 100, -100], [0, 5, 5], [-3, 0, 127]])


def test_reads_cells_resolution_and_origin(tmp_path: Path) -> None:
    """Positive cells read as free, negative as occupied, zero as unknown; row 0 is y_min."""
    grid = read_gridmap(write(tmp_path, gridmap_bytes(sample())))
    assert grid.data.tolist() == [[0, 0, 100], [-1, 0, 0], [100, -1, 0]]
    assert grid.resolution == pytest.approx(0.1)
    assert (grid.origin.x, grid.origin.y) == (-1.0, -2.0)
    assert grid.world_to_cell(-0.75, -1.95) == (0, 2)


def test_gzipped_file_reads_the_same(tmp_path: Path) -> None:
    """A .gridmap.gz (gzip found by its magic bytes) gives the same grid as the plain file."""
    payload = gridmap_bytes(sample())
    plain = read_gridmap(write(tmp_path, payload))
    packed = read_gridmap(write(tmp_path, gzip.compress(payload), "map.gridmap.gz"))
    assert np.array_equal(plain.data, packed.data)


def test_old_header_and_probability_cells(tmp_path: Path) -> None:
    """A pre-0.5.5 header (32-bit length and version) and version-1 probability cells are read."""
    cells = np.array([[255, 128, 0]])
    grid = read_gridmap(write(tmp_path, gridmap_bytes(cells, version=1, old_header=True)))
    assert grid.data.tolist() == [[0, -1, 100]]


def test_sixteen_bit_cells(tmp_path: Path) -> None:
    """16-bit log-odds cells are read by their high byte, as MRPT does."""
    grid = read_gridmap(write(tmp_path, gridmap_bytes(np.array([[3000, -3000, 0]]), bits=16)))
    assert grid.data.tolist() == [[0, 100, -1]]


@pytest.mark.parametrize(
    ("payload", "words"),
    [
        (gridmap_bytes(sample(), name=b"CSimplePointsMap"), "class 'CSimplePointsMap'"),
        (gridmap_bytes(sample(), version=9), "version 9 is unknown"),
        (gridmap_bytes(sample(), bits=12), "8 or 16 bits per cell"),
        (gridmap_bytes(sample(), end=False), "end flag"),
        (gridmap_bytes(sample())[:55], "ends inside 3 x 3 cells"),
        (b"\x13\x00\x00\x01", "not an MRPT gridmap"),
        (b"", "ends inside the object header"),
    ],
    ids=["other class", "unknown version", "odd cell size", "no end flag", "cut short", "no header", "empty"],
)
def test_malformed_files_are_refused_naming_the_file(tmp_path: Path, payload: bytes, words: str) -> None:
    """Each malformed file ends in a GridmapError that names the file and what is wrong."""
    path = write(tmp_path, payload, "bad.gridmap")
    with pytest.raises(GridmapError, match="bad.gridmap") as info:
        read_gridmap(path)
    assert words in str(info.value)


def test_bounds_that_do_not_fit_the_size_are_refused(tmp_path: Path) -> None:
    """A header whose bounds disagree with its cell counts is refused."""
    payload = bytearray(gridmap_bytes(sample()))
    payload[29:33] = struct.pack("<f", 50.0)  # x_max far past 3 cells of 0.1 m
    with pytest.raises(GridmapError, match="does not fit its bounds"):
        read_gridmap(write(tmp_path, bytes(payload)))


def test_huge_grid_is_refused_before_its_cells_are_read(tmp_path: Path) -> None:
    """A header claiming more cells than the limit is refused from the header alone."""
    head = gridmap_bytes(sample())[:22] + struct.pack("<IIfffff", 100_000, 100_000, 0, 10_000, 0, 10_000, 0.1)
    with pytest.raises(GridmapError, match="expected a grid of 1 to"):
        read_gridmap(write(tmp_path, head))


def test_file_over_the_size_limit_is_refused(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A file larger than MAX_GRIDMAP_BYTES is refused before it is opened."""
    monkeypatch.setattr(mrpt_grid, "MAX_GRIDMAP_BYTES", 64)
    with pytest.raises(GridmapError, match="at most"):
        read_gridmap(write(tmp_path, gridmap_bytes(np.zeros((10, 10)))))


def test_missing_file_is_named(tmp_path: Path) -> None:
    """A missing file ends in a GridmapError naming it."""
    with pytest.raises(GridmapError, match="nothere.gridmap"):
        read_gridmap(tmp_path / "nothere.gridmap")


@NEEDS_MRPT
def test_malaga_campus_grid() -> None:
    """MRPT's Malaga campus grid reads as 1888 x 2738 cells of 8 cm from (-10, -127.04), mostly unknown."""
    grid = read_gridmap(DATASETS / "2006-MalagaCampus.gridmap.gz")
    assert grid.data.shape == (2738, 1888)
    assert grid.resolution == pytest.approx(0.08)
    assert (grid.origin.x, grid.origin.y) == pytest.approx((-10.0, -127.04))
    free, occupied, unknown = ((grid.data == v).mean() for v in (0, 100, -1))
    assert 0.3 < free < 0.45 and 0.002 < occupied < 0.02 and unknown > 0.55


@NEEDS_MRPT
def test_uwb_demo_grid() -> None:
    """MRPT's UWB demo grid reads as 700 x 650 cells of 4 cm (28 x 26 m)."""
    grid = read_gridmap(DATASETS / "uwb_ro-localization_demo_map.gridmap.gz")
    assert grid.data.shape == (650, 700)
    assert grid.resolution == pytest.approx(0.04)
    assert (grid.data == 0).sum() > (grid.data == 100).sum() > 0
