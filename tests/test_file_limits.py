"""Bounded reads: a file over its limit is refused before it is read whole, FIFOs included."""

from __future__ import annotations

import os
import threading
from pathlib import Path

import pytest

from missiontree import file_limits
from missiontree.errors import ConfigError
from missiontree.file_limits import FileTooLargeError, read_bounded
from missiontree.runlog import replay
from missiontree.semantics import rooms, scene_graph
from missiontree.semantics.scene_graph import SceneGraph, SceneGraphError


def test_a_file_within_its_limit_is_read_whole(tmp_path: Path) -> None:
    """Exactly ``limit`` bytes are read back unchanged."""
    path = tmp_path / "f.bin"
    path.write_bytes(b"x" * 100)
    assert read_bounded(path, 100, "test file") == b"x" * 100


def test_a_file_over_its_limit_is_refused_naming_it(tmp_path: Path) -> None:
    """One byte over: the error names the file, what it is, its size and the limit."""
    path = tmp_path / "big.json"
    path.write_bytes(b"x" * 101)
    expected = r"big\.json: the test file is 101 bytes, over the limit of 100"
    with pytest.raises(FileTooLargeError, match=expected):
        read_bounded(path, 100, "test file")


def test_a_fifo_that_never_ends_is_bounded(tmp_path: Path) -> None:
    """A FIFO has no size to check first; the read still stops at the limit."""
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)

    def write() -> None:
        with open(fifo, "wb") as out:
            try:
                out.write(b"y" * 10_000)
            except BrokenPipeError:
                pass

    writer = threading.Thread(target=write, daemon=True)
    writer.start()
    with pytest.raises(FileTooLargeError, match="over the limit of 1,000 bytes"):
        read_bounded(fifo, 1000, "pipe")
    writer.join(timeout=5)


def test_an_oversized_scene_graph_file_is_a_clear_error(tmp_path: Path,
                                                        monkeypatch: pytest.MonkeyPatch) -> None:
    """A scene graph over its limit is refused as a SceneGraphError naming the file, not read."""
    monkeypatch.setattr(scene_graph, "MAX_SCENE_GRAPH_BYTES", 64)
    path = tmp_path / "scene_graph.json"
    path.write_text('{"nodes": [], "edges": []}' + " " * 100, encoding="utf-8")
    with pytest.raises(SceneGraphError, match=r"scene_graph\.json: the scene graph file is \d+ bytes"):
        SceneGraph.load(path)


def test_a_scene_graph_file_that_is_not_utf8_names_the_file(tmp_path: Path) -> None:
    """Undecodable bytes are reported with the file's name and what it should be."""
    path = tmp_path / "graph.json"
    path.write_bytes(b'{"nodes": ["\xff"]}')
    with pytest.raises(SceneGraphError, match=r"graph\.json: not UTF-8 text"):
        SceneGraph.load(path)


def test_an_oversized_room_polygon_file_is_a_config_error(tmp_path: Path,
                                                          monkeypatch: pytest.MonkeyPatch) -> None:
    """Room polygons over their limit: a ConfigError naming the file."""
    monkeypatch.setattr(rooms, "MAX_ROOMS_BYTES", 10)
    path = tmp_path / "rooms.yaml"
    path.write_text("rooms: []\n" + "#" * 50, encoding="utf-8")
    with pytest.raises(ConfigError, match=r"rooms\.yaml: the room polygon file"):
        rooms.load_room_polygons(path)


def test_an_oversized_run_view_is_a_config_error(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A runview.json over its limit is refused with the file named, not parsed."""
    monkeypatch.setattr(replay, "MAX_RUNVIEW_BYTES", 10)
    (tmp_path / replay.RUNVIEW_FILE).write_text('{"tree": {}, "pad": "' + "z" * 50 + '"}', encoding="utf-8")
    with pytest.raises(ConfigError, match="run view file"):
        replay.read_runview(tmp_path)


def test_the_limits_are_documented_constants() -> None:
    """Every limit is a positive byte count in one module, where the docs point."""
    names = [n for n in dir(file_limits) if n.startswith("MAX_") and n.endswith("_BYTES")]
    assert len(names) >= 8
    assert all(getattr(file_limits, n) > 0 for n in names)


def test_an_oversized_map_image_is_refused_naming_the_map(tmp_path: Path,
                                                          monkeypatch: pytest.MonkeyPatch) -> None:
    """A map_server image over its limit: a MapFileError naming the yaml, before the image is read."""
    from missiontree.mapping import mapfile

    monkeypatch.setattr(mapfile, "MAX_MAP_IMAGE_BYTES", 100)
    (tmp_path / "map.pgm").write_bytes(b"P5\n20 20\n255\n" + bytes(400))
    text = "image: map.pgm\nresolution: 0.05\norigin: [0, 0, 0]\n"
    (tmp_path / "map.yaml").write_text(text, encoding="utf-8")
    with pytest.raises(mapfile.MapFileError, match=r"map\.yaml: cannot read the map image: .*over the limit"):
        mapfile.read_map(tmp_path / "map.yaml")
