"""Files written whole: the bytes, readable permissions, the folder made, nothing left beside them."""

from __future__ import annotations

import stat
from pathlib import Path

from missiontree.files import write_whole
from missiontree.paths import REPO_ROOT
from missiontree.semantics.scene_graph import SceneGraph


def test_a_file_written_whole_is_readable_like_the_runs_other_files(tmp_path: Path) -> None:
    """The file has the bytes and mode 0644 (not the temporary file's 0600), in a folder made for it."""
    target = write_whole(tmp_path / "new" / "map.yaml", b"image: map.pgm\n")
    assert target.read_bytes() == b"image: map.pgm\n"
    assert stat.S_IMODE(target.stat().st_mode) == 0o644
    assert [p.name for p in target.parent.iterdir()] == ["map.yaml"]


def test_a_saved_scene_graph_is_readable_like_the_runs_other_files(tmp_path: Path) -> None:
    """scene_graph.json was written 0600 by its own temporary file; it is 0644 as the rest."""
    graph = SceneGraph.load(REPO_ROOT / "config" / "scene_graphs" / "office.json")
    path = graph.save(tmp_path / "scene_graph.json")
    assert stat.S_IMODE(path.stat().st_mode) == 0o644
    assert SceneGraph.load(path).to_json() == graph.to_json()
