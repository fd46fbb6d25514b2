"""map.pgm + map.yaml in map_server's format: written, read back, and loaded as a simulator world."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from missiontree.mapping.mapfile import MapFileError, map_image, read_map, write_map
from missiontree.types import OccupancyGrid, Pose2D

SHARED_MAPS = Path(__file__).resolve().parents[2] / "config" / "worlds" / "maps"


def small_map() -> OccupancyGrid:
    """A 3 x 2 m room (5 cm cells) with walls, a free inside and an unknown strip on the right."""
    data = np.full((40, 60), 100, np.int8)
    data[1:39, 1:50] = 0
    data[:, 52:] = -1
    return OccupancyGrid(7.0, 0.05, Pose2D(-1.5, -2.0), data)


def test_written_files_follow_map_saver(tmp_path: Path) -> None:
    """P5 image with 254 free / 0 occupied / 205 unknown, top row = highest y; yaml with the saver's keys."""
    grid = small_map()
    pgm, meta = write_map(grid, tmp_path)
    assert (pgm.name, meta.name) == ("map.pgm", "map.yaml")
    raw = pgm.read_bytes()
    assert raw.startswith(b"P5\n")
    doc = yaml.safe_load(meta.read_text())
    assert doc == {"image": "map.pgm", "mode": "trinary", "resolution": 0.05, "origin": [-1.5, -2.0, 0.0],
                   "negate": 0, "occupied_thresh": 0.65, "free_thresh": 0.196}
    image = map_image(grid)
    assert image.shape == (40, 60)
    assert image[0, 0] == 0 and image[20, 20] == 254 and image[20, 55] == 205
    # row 0 of the grid (lowest y) is the image's bottom row
    grid.data[0, 10] = 0
    assert map_image(grid)[-1, 10] == 254


def test_read_back_gives_the_same_grid(tmp_path: Path) -> None:
    """read_map(write_map(grid)) has the same cells, resolution and origin."""
    grid = small_map()
    _, meta = write_map(grid, tmp_path, name="learned")
    back = read_map(meta)
    assert back.resolution == grid.resolution and back.origin == grid.origin
    np.testing.assert_array_equal(back.data, grid.data)


@pytest.mark.parametrize("name", ["maze.yaml", "tb3_sandbox.yaml"])
def test_real_slam_maps_round_trip(tmp_path: Path, name: str) -> None:
    """The real SLAM maps (TurtleBot 4 maze, Nav2 sandbox) read and round-trip unchanged."""
    grid = read_map(SHARED_MAPS / name)
    assert (grid.data == 0).any() and (grid.data == 100).any()
    _, meta = write_map(grid, tmp_path)
    np.testing.assert_array_equal(read_map(meta).data, grid.data)


def test_missing_or_broken_files_are_clear_errors(tmp_path: Path) -> None:
    """A missing image or key gives a MapFileError naming the file and what is missing."""
    (tmp_path / "a.yaml").write_text("image: nothere.pgm\nresolution: 0.05\norigin: [0, 0, 0]\n")
    with pytest.raises(MapFileError, match="does not exist"):
        read_map(tmp_path / "a.yaml")
    (tmp_path / "b.yaml").write_text("image: x.pgm\norigin: [0, 0, 0]\n")
    with pytest.raises(MapFileError, match="resolution"):
        read_map(tmp_path / "b.yaml")
    (tmp_path / "c.pgm").write_bytes(b"P5\n10 10\n255\n" + bytes(20))
    (tmp_path / "c.yaml").write_text("image: c.pgm\nresolution: 0.05\norigin: [0, 0, 0]\n")
    with pytest.raises(MapFileError, match="fewer"):
        read_map(tmp_path / "c.yaml")


def test_written_map_loads_back_as_a_simulator_world(tmp_path: Path) -> None:
    """A world file naming the written map.yaml loads: its grid is the map, its walls are the map's."""
    world_module = pytest.importorskip("missiontree.backends.sim.world")
    grid = small_map()
    write_map(grid, tmp_path)
    (tmp_path / "learned.yaml").write_text(
        "name: learned\nrobot:\n  profile: turtlebot4\n  start: {x: 0.0, y: -1.0, yaw: 0.0}\n"
        "map:\n  yaml: map.yaml\n")
    world = world_module.load_world(tmp_path / "learned.yaml")
    assert world.grid.resolution == grid.resolution
    assert (world.grid.origin.x, world.grid.origin.y) == (grid.origin.x, grid.origin.y)
    assert world.grid.data.shape == grid.data.shape
    np.testing.assert_array_equal(world.grid.data == 100, grid.data == 100)
    np.testing.assert_array_equal(world.grid.data == -1, grid.data == -1)
    assert len(world.wall_segments) > 0


def test_writers_of_one_map_at_once_never_mix_their_bytes(tmp_path: Path) -> None:
    """Two writers of the same file each write under a name of their own: the file is one of theirs whole."""
    import threading

    from missiontree.mapping import mapfile

    target = tmp_path / "map.pgm"
    payloads = [bytes([k]) * 2_000_000 for k in (1, 2)]
    errors: list[BaseException] = []

    def write(payload: bytes) -> None:
        try:
            mapfile._atomic_write(target, payload)
        except BaseException as error:  # noqa: BLE001 - collected for the assertion below
            errors.append(error)

    threads = [threading.Thread(target=write, args=(p,)) for p in payloads * 3]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert errors == []  # with one shared temporary name, a writer found its file renamed away
    assert target.read_bytes() in payloads
    assert [p.name for p in tmp_path.iterdir()] == ["map.pgm"]  # no temporary file left behind
