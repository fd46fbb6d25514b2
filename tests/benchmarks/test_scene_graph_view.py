"""The scene-graph benchmark's in-view recall: misses split into objects never in view and objects lost."""

from __future__ import annotations

import sys
from pathlib import Path
from types import SimpleNamespace

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
from scene_graph_view import PoseTrack, frames_in_view, recall_in_view  # noqa: E402


def sighting(pixels: int) -> SimpleNamespace:
    return SimpleNamespace(pixels=pixels)


def test_only_frames_close_and_large_enough_count() -> None:
    """An object counts as in view in a frame with enough pixels and within range of the true pose."""
    track = PoseTrack()
    track.record(0.0, 0.0, 0.0)
    track.record(1.0, 10.0, 0.0)
    visibility = [
        (0.0, {"near": sighting(500), "far": sighting(500), "tiny": sighting(20)}),
        (1.0, {"far": sighting(500)}),
    ]
    truths = [SimpleNamespace(id=n, pose=SimpleNamespace(x=x, y=0.0))
              for n, x in (("near", 2.0), ("far", 12.0), ("tiny", 1.0))]
    counts = frames_in_view(visibility, track, truths, max_range=6.0)
    assert counts == {"near": 1, "far": 1}


def test_recall_in_view_leaves_out_objects_never_shown() -> None:
    """Recall in view divides the matched objects shown by the objects shown, not by all objects."""
    truths = [SimpleNamespace(id=n) for n in ("a", "b", "c", "d")]
    scored = {"truths": truths, "pairs": [(0, 0), (1, 2)]}  # a and c matched; d never shown
    counts = {"a": 3, "b": 5, "c": 1}
    assert recall_in_view(scored, counts) == (2, 3)
    assert recall_in_view(scored, counts, least=3) == (1, 2)
