"""The viewer page as a file: self-contained, compact, and built from what the run recorded."""

from __future__ import annotations

import json
import re
from pathlib import Path

import cv2
import numpy as np

from missiontree.runlog.html import page_data, render_page, write_page
from missiontree.runlog.replay import open_run
from missiontree.testing_runs import synthesize_run


def test_the_page_needs_no_network(patrol_run: Path, tmp_path: Path):
    """No external script, style, image or font: everything is inline."""
    html = write_page(patrol_run, tmp_path / "report.html").read_text()
    assert not re.search(r"""<(script|link|img|iframe)[^>]+(src|href)\s*=\s*["']?(https?:)?//""", html)
    assert "@import" not in html and "url(http" not in html
    assert html.count("<script") == 2  # the data and the viewer, both inline


def test_data_cannot_close_the_script_element(tmp_path: Path):
    """Feedback text with '</script>' stays data."""
    synthesize_run(tmp_path, 20)
    replay = open_run(tmp_path)
    replay.changes[0] = type(replay.changes[0])(0, 0, 1, 0, "</script><b>x", "")
    html = render_page(page_data(replay, tmp_path))
    assert html.count("</script>") == 2


def test_an_hour_of_ticks_stays_under_ten_megabytes(tmp_path: Path):
    """36,000 ticks with a patrol's event rate make a page well under the 10 MB limit."""
    synthesize_run(tmp_path, 36_000)
    page = write_page(tmp_path, tmp_path / "report.html")
    assert page.stat().st_size <= 10_000_000
    assert page.stat().st_size < (tmp_path / "ticks.jsonl").stat().st_size


def test_a_learned_map_in_the_run_directory_is_preferred(patrol_run: Path, tmp_path: Path):
    """A map.pgm + map.yaml (map_server format) beside the log replaces the recorded map."""
    run = tmp_path / "run"
    run.mkdir()
    for name in ("ticks.jsonl", "runview.json"):
        (run / name).write_bytes((patrol_run / name).read_bytes())
    image = np.full((30, 50), 254, dtype=np.uint8)
    image[10, :] = 0
    cv2.imwrite(str(run / "map.pgm"), image)
    (run / "map.yaml").write_text(
        "image: map.pgm\nresolution: 0.1\norigin: [-1.0, -2.0, 0.0]\n"
        "negate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.25\n"
    )
    data = page_data(open_run(run), run)
    assert data["map"]["width"] == 50 and data["map"]["height"] == 30
    assert data["map"]["origin"] == [-1.0, -2.0] and "learned map" in data["map"]["source"]


def test_the_run_records_its_tree_map_and_trajectory(patrol_run: Path):
    """runview.json holds the declared tree, the robot's map and the simulator's trajectory."""
    runview = json.loads((patrol_run / "runview.json").read_text())
    assert runview["tree"]["name"] == "respond_or_patrol" and runview["tree"]["type"] == "Selector"
    assert runview["map"]["resolution"] > 0 and runview["map"]["png"]
    assert len(runview["poses"]) > 10 and all(len(p) == 3 for p in runview["poses"])


def test_live_data_picks_up_the_tree_recorded_after_the_first_lines(tmp_path: Path):
    """A server polled before runview.json exists restarts with the declared tree once it appears."""
    from missiontree.runlog.follow import LiveRun

    source = tmp_path / "source"
    synthesize_run(source, 50)
    live_dir = tmp_path / "live"
    live_dir.mkdir()
    lines = (source / "ticks.jsonl").read_text().splitlines(keepends=True)
    (live_dir / "ticks.jsonl").write_text("".join(lines[:5]))
    live = LiveRun(live_dir)
    first = live.data()
    assert all(node[2] == first["s"].index("?") for node in first["nodes"])  # types unknown so far
    (live_dir / "runview.json").write_bytes((source / "runview.json").read_bytes())
    with (live_dir / "ticks.jsonl").open("a") as stream:
        stream.write("".join(lines[5:]))
    live._built_at = -10.0  # past the rebuild throttle
    data = live.data()
    assert data["lines"] == len(lines) and len(data["times"]) == 50
    assert data["s"][data["nodes"][0][2]] == "Selector"


def _graph(run: Path) -> None:
    """A small scene graph: a kitchen with a cup and a fridge, a hall with a chair, one bad node."""
    nodes = [
        {"id": 0, "type": "building", "label": "Building"},
        {"id": "room_1", "type": "room", "label": "kitchen"},
        {"id": "room_2", "type": "room", "label": "hall"},
        {"id": "cup_1", "type": "object", "label": "cup", "coordinates": [1.0, 2.0, 0.8]},
        {"id": "refrigerator_1", "type": "object", "label": "refrigerator", "coordinates": [3.0, 2.0, 0.9]},
        {"id": "chair_1", "type": "object", "label": "chair", "coordinates": [8.0, -1.0, 0.4]},
        {"id": "ghost_1", "type": "object", "label": "ghost", "coordinates": ["NaN", None]},
    ]
    edges = [
        {"source_id": "room_1", "target_id": "cup_1", "relation": "contains"},
        {"source_id": "room_1", "target_id": "refrigerator_1", "relation": "contains"},
        {"source_id": "room_2", "target_id": "chair_1", "relation": "contains"},
        {"source_id": "cup_1", "target_id": "refrigerator_1", "relation": "near"},
    ]
    (run / "scene_graph.json").write_text(json.dumps({"nodes": nodes, "edges": edges}))


def test_the_scene_graph_becomes_a_map_layer_with_the_served_object(tmp_path: Path):
    """Objects keep their labels, rooms sit at their objects' centre, the served object is the target."""
    run = tmp_path / "run"
    synthesize_run(run, 50)
    _graph(run)
    summary = json.loads((run / "summary.json").read_text())
    summary["outcome"] = {"intent": {"commands": [{"status": "served", "object": "cup_1"}]}}
    (run / "summary.json").write_text(json.dumps(summary))
    scene = page_data(open_run(run), run)["scene"]
    assert sorted(o[3] for o in scene["objects"]) == ["chair_1", "cup_1", "refrigerator_1"]
    assert sorted(scene["rooms"]) == [[2.0, 2.0, "kitchen"], [8.0, -1.0, "hall"]]
    assert scene["target"] == [1.0, 2.0, "served: cup"]


def test_a_run_without_a_scene_graph_has_no_layer(tmp_path: Path):
    """A patrol-like run (no scene_graph.json, nothing found) draws no scene layer."""
    run = tmp_path / "run"
    synthesize_run(run, 50)
    assert page_data(open_run(run), run)["scene"] is None


def test_the_profile_reaches_the_page_with_numbers_checked(tmp_path: Path):
    """summary.json's profile becomes per-node [ticks, Hz, CPU] rows; a non-finite number becomes null."""
    run = tmp_path / "run"
    synthesize_run(run, 50)
    summary = json.loads((run / "summary.json").read_text())
    summary["profile"] = {"nodes": {"root/a": {"ticks": 50, "rate_hz": 10.0, "cpu_s": 0.25},
                                    "root/b": {"ticks": "many", "rate_hz": float("nan"), "cpu_s": 0.1}},
                          "run": {"cpu_s": 1.5, "rss_peak_mb": 300.0}, "models": {"vlm": {"calls": 3}}}
    (run / "summary.json").write_text(json.dumps(summary))
    view = page_data(open_run(run), run)["profile"]
    assert view["nodes"] == {"root/a": [50.0, 10.0, 0.25], "root/b": [None, None, 0.1]}
    assert view["run"]["cpu_s"] == 1.5 and view["run"]["wall_s"] is None
    assert view["models"] == {"vlm": [3.0, None, None]}
    del summary["profile"]
    (run / "summary.json").write_text(json.dumps(summary))
    assert page_data(open_run(run), run)["profile"] is None
