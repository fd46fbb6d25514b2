"""The scene-graph diagnosis names one cause per missed object, in the order the pipeline loses it."""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
from scene_graph_diagnosis import miss_cause  # noqa: E402


def test_an_object_no_frame_showed_is_never_shown() -> None:
    """No frame with its pixels and no box: never shown."""
    assert miss_cause(0, [], [], [], []) == "never shown"


def test_an_object_boxed_only_as_another_class_is_confused() -> None:
    """Boxed as a backpack only (no box of its own label placed it): confused."""
    assert miss_cause(40, [("backpack", 30)], [], [], []) == "confused"


def test_an_object_boxed_only_from_beyond_the_range_is_beyond_range() -> None:
    """Every right box from 7 m or more: beyond the 6 m range."""
    assert miss_cause(20, [("bookshelf", 15)], [7.4, 8.1], [], []) == "beyond range"


def test_merged_comes_before_mislocated() -> None:
    """An instance of it joined into another, which stands near: merged, not mislocated."""
    changes = ["added plant_3", "removed plant_3 (the same potted plant as plant_1 (one box holds both))"]
    assert miss_cause(60, [("potted plant", 55)], [2.8], changes, ["plant_1@0.57"]) == "merged"
    assert miss_cause(60, [("potted plant", 55)], [2.8], [], ["plant_1@0.57"]) == "mislocated"


def test_a_boxed_object_with_no_instance_near_is_under_min_frames() -> None:
    """Boxed in range, nothing of its label near, nothing merged: a candidate that never passed."""
    assert miss_cause(7, [("potted plant", 7)], [3.4], [], []) == "under min_frames"
