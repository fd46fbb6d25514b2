"""``missiontree map convert``: map_server files from MRPT gridmaps and rawlogs, and bad input as exit 2."""

from __future__ import annotations

import gzip
import struct
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.ndimage import binary_dilation

from missiontree.backends.sim.world import load_world
from missiontree.cli.main import main
from missiontree.mapping import mrpt_datasets
from missiontree.mapping.mapfile import read_map

LOOP_FILE = "2006-01ENE-21-SENA_Telecom Faculty_one_loop_only.rawlog"
LOOP = mrpt_datasets.find_dataset(LOOP_FILE) or Path("missing")
MALAGA = mrpt_datasets.find_dataset("2006-MalagaCampus.gridmap.gz") or Path("missing")
MISSING = mrpt_datasets.missing_reason(LOOP_FILE)


def small_gridmap(path: Path) -> Path:
    """A 4 x 3 MRPT grid (version 3, 8-bit log-odds): one occupied, one free, the rest unknown."""
    cells = np.zeros((3, 4), np.int8)
    cells[0, 0], cells[2, 3] = -100, 100
    name = b"COccupancyGridMap2D"
    data = bytes([0x80 | len(name)]) + name + bytes([3, 8])
    data += struct.pack("<IIfffff", 4, 3, -1.0, -0.6, 2.0, 2.3, 0.1) + cells.tobytes() + b"\0" * 8 + b"\x88"
    path.write_bytes(gzip.compress(data))
    return path


def test_convert_writes_a_map_server_pair_from_a_gridmap(tmp_path: Path,
                                                         capsys: pytest.CaptureFixture[str]) -> None:
    """A gridmap becomes map.yaml/map.pgm whose cells, resolution and origin read back unchanged."""
    src = small_gridmap(tmp_path / "tiny.gridmap.gz")
    assert main(["map", "convert", str(src), "--out", str(tmp_path / "out")]) == 0
    grid = read_map(tmp_path / "out" / "map.yaml")
    assert grid.resolution == pytest.approx(0.1)
    assert (grid.origin.x, grid.origin.y) == pytest.approx((-1.0, 2.0))
    assert grid.data[0, 0] == 100 and grid.data[2, 3] == 0 and grid.data[1, 1] == -1
    assert "4 x 3 cells" in capsys.readouterr().out


def test_unknown_kind_exits_2_listing_the_known_ones(tmp_path: Path,
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    """A file of no known kind exits 2 with the endings map convert reads."""
    src = tmp_path / "map.txt"
    src.write_text("hello")
    assert main(["map", "convert", str(src), "--out", str(tmp_path)]) == 2
    assert ".gridmap.gz, .rawlog" in capsys.readouterr().err


def test_damaged_gridmap_exits_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A gridmap cut short exits 2 naming the file, writing nothing."""
    src = tmp_path / "cut.gridmap"
    src.write_bytes(gzip.decompress(small_gridmap(tmp_path / "x.gridmap.gz").read_bytes())[:30])
    assert main(["map", "convert", str(src), "--out", str(tmp_path / "out")]) == 2
    assert "cut.gridmap" in capsys.readouterr().err and not (tmp_path / "out").exists()


@pytest.mark.realdata
@pytest.mark.skipif(not MALAGA.is_file(), reason=MISSING)
def test_convert_malaga_campus_keeps_its_size(tmp_path: Path) -> None:
    """MRPT's Malaga campus grid converts to a 1888 x 2738 map_server map at 8 cm."""
    assert main(["map", "convert", str(MALAGA), "--out", str(tmp_path)]) == 0
    grid = read_map(tmp_path / "map.yaml")
    assert grid.data.shape == (2738, 1888) and grid.resolution == pytest.approx(0.08)


@pytest.mark.realdata
@pytest.mark.skipif(not LOOP.is_file(), reason=MISSING)
def test_rawlog_map_loads_as_a_world(tmp_path: Path) -> None:
    """The faculty loop's map (raw odometry, no extra needed) converts and loads in a world file."""
    assert main(["map", "convert", str(LOOP), "--out", str(tmp_path), "--raw-odometry"]) == 0
    grid = read_map(tmp_path / "map.yaml")
    assert (grid.data == 100).sum() > 1000 and (grid.data == 0).sum() > 100_000
    world_file = tmp_path / "faculty.yaml"
    world_file.write_text("name: faculty\nrobot: {profile: turtlebot4, start: {x: 0.0, y: 0.0, yaw: 0.0}}\n"
                          "map: {yaml: map.yaml, height: 2.5}\n")
    world = load_world(world_file)
    assert world.name == "faculty"


@pytest.mark.realdata
@pytest.mark.skipif(not LOOP.is_file(), reason=MISSING)
def test_rawlog_without_the_extra_exits_2_naming_it(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    """Converting a rawlog with scan matching but no KISS-ICP exits 2 naming the realdata extra."""
    for name in ("kiss_icp", "kiss_icp.mapping", "kiss_icp.registration"):
        monkeypatch.setitem(sys.modules, name, None)  # None in sys.modules: the import fails
    assert main(["map", "convert", str(LOOP), "--out", str(tmp_path)]) == 2
    assert "missiontree[realdata]" in capsys.readouterr().err


BAG = Path(__file__).resolve().parents[1] / "data" / "ros2bag" / "sim_office.mcap"


@pytest.mark.realdata
def test_convert_a_ros2_bag_matches_the_map_sim_ros_learned(tmp_path: Path,
                                                            capsys: pytest.CaptureFixture[str]) -> None:
    """A bag's /scan at its /tf poses converts to a map with walls within 2 cells of the bag's own /map."""
    pytest.importorskip("mcap_ros2", reason="mcap-ros2-support (the realdata extra) is not installed")
    from missiontree.mapping.ros2bag import read_bag

    assert main(["map", "convert", str(BAG), "--out", str(tmp_path)]) == 0
    assert "119 of 119 scans at the poses of tf (map)" in capsys.readouterr().out
    grid, reference = read_map(tmp_path / "map.yaml"), read_bag(BAG).maps[-1]
    walls = binary_dilation(reference.data == 100, iterations=2)
    cells = [reference.world_to_cell(*grid.cell_to_world(r, c)) for r, c in np.argwhere(grid.data == 100)]
    inside = [walls[r, c] for r, c in cells if 0 <= r < walls.shape[0] and 0 <= c < walls.shape[1]]
    assert len(cells) > 300 and sum(inside) / len(cells) >= 0.9
    free = (grid.data == 0).sum() * grid.resolution ** 2
    assert free == pytest.approx((reference.data == 0).sum() * reference.resolution ** 2, rel=0.1)


@pytest.mark.realdata
def test_a_bag_without_scans_on_the_namespace_exits_2(tmp_path: Path,
                                                      capsys: pytest.CaptureFixture[str]) -> None:
    """A namespace the bag does not use finds no scans: exit 2 naming the topic looked for and the bag's."""
    pytest.importorskip("mcap_ros2", reason="mcap-ros2-support (the realdata extra) is not installed")
    assert main(["map", "convert", str(BAG), "--out", str(tmp_path / "out"), "--namespace", "/robot1"]) == 2
    err = capsys.readouterr().err
    assert "/robot1/scan" in err and "/scan" in err and not (tmp_path / "out").exists()
