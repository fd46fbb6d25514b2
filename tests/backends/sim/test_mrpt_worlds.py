"""Worlds on MRPT's grids: the datasets folder, the crop rule, the world source and its errors."""

from __future__ import annotations

import gzip
import struct
from pathlib import Path

import cv2
import numpy as np
import pytest

from missiontree.backends.sim import mrpt_worlds
from missiontree.backends.sim.mapimage import MAX_MAP_CELLS
from missiontree.backends.sim.mrpt_worlds import MAPS, crop_window, datasets_dir, world_grid
from missiontree.backends.sim.world import load_world
from missiontree.errors import WorldFileError
from missiontree.mapping.clearance import clearance_metres
from missiontree.mapping.planner import plan
from missiontree.types import OccupancyGrid, Pose2D

NEEDS_MRPT = pytest.mark.skipif(
    not mrpt_worlds.mrpt_available(),
    reason="MRPT's datasets are not installed: apt-get install -y mrpt-common (or make setup-mrpt)",
)


def gridmap(cells: np.ndarray, res: float) -> bytes:
    """A gzipped MRPT gridmap (version 3, 8-bit log-odds; row 0 at y_min)."""
    ny, nx = cells.shape
    name = b"COccupancyGridMap2D"
    head = bytes([0x80 | len(name)]) + name + bytes([3, 8])
    head += struct.pack("<IIfffff", nx, ny, 0.0, nx * res, 0.0, ny * res, res)
    return gzip.compress(head + cells.astype(np.int8).tobytes() + b"\x00" * 8 + b"\x88")


@pytest.fixture
def fake_datasets(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A datasets folder with a small two-room building as the uwb map, and a cache folder."""
    res = 0.05
    cells = np.zeros((160, 200), np.int8)  # 10 x 8 m, unknown
    cells[20:140, 20:180] = -100  # walls round ...
    cells[22:138, 22:178] = 100  # ... free floor
    cells[22:138, 98:102] = -100  # a wall between two rooms, with a 1 m door
    cells[70:90, 98:102] = 100
    folder = tmp_path / "datasets"
    folder.mkdir()
    (folder / MAPS["uwb"]).write_bytes(gridmap(cells, res))
    monkeypatch.setenv(mrpt_worlds.DATASETS_ENV, str(folder))
    monkeypatch.setenv(mrpt_worlds.CACHE_ENV, str(tmp_path / "cache"))
    return folder


def test_missing_datasets_name_the_apt_package(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Without the datasets, the folder lookup and the world source both name mrpt-common."""
    monkeypatch.setenv(mrpt_worlds.DATASETS_ENV, str(tmp_path))
    with pytest.raises(FileNotFoundError, match="apt-get install -y mrpt-common"):
        datasets_dir()
    assert not mrpt_worlds.mrpt_available()
    with pytest.raises(WorldFileError, match="mrpt-common"):
        load_world("mrpt:uwb")


def test_unknown_map_or_bad_seed_is_refused() -> None:
    """A name outside MAPS or a seed that is no whole number is refused with the accepted form."""
    for name in ("mrpt:nowhere", "mrpt:uwb:x1"):
        with pytest.raises(WorldFileError, match=r"mrpt:<map>\[:<seed>\]"):
            load_world(name)


def test_small_map_is_kept_whole() -> None:
    """A map that fits the crop square is not cropped."""
    grid = OccupancyGrid(0.0, 0.1, Pose2D(0, 0, 0), np.zeros((300, 200), np.int8))
    assert crop_window(grid) == (0, 0, 300, 200)


def test_crop_holds_the_largest_drivable_floor() -> None:
    """On a 100 x 100 m map the 40 m crop is where the largest drivable floor is, not a smaller piece."""
    data = np.full((200, 200), -1, np.int8)  # 0.5 m cells
    data[120:190, 10:60] = 0  # 35 x 25 m of floor: the largest piece
    data[10:40, 150:190] = 0  # 15 x 20 m: a smaller one
    r0, c0, h, w = crop_window(OccupancyGrid(0.0, 0.5, Pose2D(0, 0, 0), data))
    assert (h, w) == (80, 80)
    assert r0 <= 120 and r0 + h >= 190 and c0 <= 10 and c0 + w >= 60


def test_world_grid_walls_its_edge(fake_datasets: Path) -> None:
    """No free cell lies on the world grid's outer edge."""
    data = world_grid("uwb").data
    edge = np.concatenate([data[0], data[-1], data[:, 0], data[:, -1]])
    assert not (edge == 0).any()


def test_free_floor_never_touches_unknown_cells(fake_datasets: Path, tmp_path: Path) -> None:
    """Where the scans end (free beside unknown, as at a gap in a wall) the world grid has a wall."""
    cells = np.zeros((60, 60), np.int8)  # unknown all round
    cells[10:50, 10:50] = 100  # free floor, no wall at all
    (fake_datasets / MAPS["uwb"]).write_bytes(gridmap(cells, 0.05))
    data = world_grid("uwb").data
    free = data == 0
    grown = np.zeros_like(free)
    grown[1:-1, 1:-1] = free[:-2, 1:-1] | free[2:, 1:-1] | free[1:-1, :-2] | free[1:-1, 2:]
    assert free.sum() > 0 and not (grown & (data == -1)).any()


def test_synthetic_gridmap_loads_as_a_world(fake_datasets: Path) -> None:
    """mrpt:uwb:<seed> on a small synthetic gridmap loads with a start on its floor and objects placed."""
    world = load_world("mrpt:uwb:3")
    row, col = world.grid.world_to_cell(world.start.x, world.start.y)
    assert world.grid.data[row, col] == 0
    assert world.objects
    assert load_world("mrpt:uwb:3").start == world.start  # the same seed, the same world


@NEEDS_MRPT
def test_malaga_crop_is_a_40_m_square_within_the_loader_limit() -> None:
    """The Malaga campus grid is cropped to 40 x 40 m, within the loader's cell limit, and loads."""
    grid = world_grid("malaga")
    assert grid.data.shape == (500, 500) and grid.data.size <= MAX_MAP_CELLS
    assert (grid.data == 0).mean() > 0.5
    world = load_world("mrpt:malaga")
    assert world.objects and world.rooms


@NEEDS_MRPT
def test_uwb_loads_whole() -> None:
    """The UWB demo grid (28 x 26 m) loads whole as a world with objects."""
    assert world_grid("uwb").data.shape == (650, 700)
    assert load_world("mrpt:uwb").objects


def test_map_yaml_writes_only_the_pair_and_keeps_identical_files(fake_datasets: Path, tmp_path: Path) -> None:
    """The cache holds the yaml and image only, and a second call leaves the same bytes untouched."""
    first = mrpt_worlds.map_yaml("uwb")
    stamp = first.stat().st_mtime_ns
    assert mrpt_worlds.map_yaml("uwb") == first
    assert sorted(p.name for p in (tmp_path / "cache").iterdir()) == ["mrpt_uwb.pgm", "mrpt_uwb.yaml"]
    assert first.stat().st_mtime_ns == stamp


def test_full_name_keeps_a_map_the_crop_cuts(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """On a 60 x 50 m map `malaga` is cut to the 40 m square; `malaga-full` keeps every cell."""
    folder = tmp_path / "datasets"
    folder.mkdir()
    cells = np.full((1000, 1200), 100, np.int8)  # 0.05 m cells: 60 x 50 m of free floor
    cells[:, 600] = -100  # a wall down the middle
    (folder / MAPS["malaga"]).write_bytes(gridmap(cells, 0.05))
    monkeypatch.setenv(mrpt_worlds.DATASETS_ENV, str(folder))
    assert world_grid("malaga").data.shape == (800, 800)
    assert world_grid("malaga-full").data.shape == (1000, 1200)


@NEEDS_MRPT
def test_whole_malaga_campus_is_the_world_grid_within_the_loader_limit() -> None:
    """mrpt:malaga-full's grid is the whole 1,888 x 2,738-cell campus at 8 cm, within MAX_MAP_CELLS."""
    grid = world_grid("malaga-full")
    assert grid.data.shape == (2738, 1888) and grid.resolution == pytest.approx(0.08)
    assert grid.data.size <= MAX_MAP_CELLS


@NEEDS_MRPT
def test_planner_crosses_the_malaga_campus() -> None:
    """Between far corners of the campus's largest drivable floor the planner finds a path on free cells."""
    grid = world_grid("malaga-full")
    drivable = (clearance_metres((grid.data == 0).astype(np.uint8), grid.resolution) > 0.4).astype(np.uint8)
    _, labels = cv2.connectedComponents(drivable, connectivity=8)
    sizes = np.bincount(labels.ravel())
    sizes[0] = 0
    cells = np.argwhere(labels == sizes.argmax())
    ends = [cells[np.argmin(cells.sum(1))], cells[np.argmax(cells.sum(1))]]
    start, goal = ((grid.origin.x + (c + 0.5) * grid.resolution, grid.origin.y + (r + 0.5) * grid.resolution)
                   for r, c in ends)
    straight = float(np.hypot(goal[0] - start[0], goal[1] - start[1]))
    assert straight > 150.0
    path = plan(grid, start, goal, footprint_radius=0.17, allow_unknown=False)
    assert path is not None
    assert straight <= path.length < 2 * straight
    rows = ((path.points[:, 1] - grid.origin.y) / grid.resolution).astype(int)
    cols = ((path.points[:, 0] - grid.origin.x) / grid.resolution).astype(int)
    assert (grid.data[rows, cols] == 0).all()
