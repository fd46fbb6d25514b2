"""Small objects of one class close together stay apart in the fusion (``small_radius``)."""

from __future__ import annotations

from missiontree.perception.projection import Projection
from missiontree.semantics.fusion import FusionParams, InstanceFusion
from missiontree.semantics.semantic_map import SemanticMap
from missiontree.types import Detection, Pose2D


def _bottle(x: float, stamp: float, width: float = 0.08) -> Projection:
    det = Detection("bottle", 0.9, (150.0, 100.0, 160.0, 130.0))
    size = (width, width, 0.25)
    return Projection("bottle", 0.9, det.box, (x, 0.0, 0.1), 2.0, 2.0, size, stamp, Pose2D(0, 0), det)


def test_a_bottle_beside_a_known_bottle_does_not_refine_it() -> None:
    """A bottle 0.45 m from a known bottle is not that one with small_radius 0.3; with it off, it is."""
    for radius, expected in ((0.3, None), (None, "known")):
        fusion = InstanceFusion(SemanticMap(), FusionParams(small_radius=radius))
        known = fusion.map.add("bottle", (1.0, 0.0, 0.1), 0.0, size=(0.08, 0.08, 0.25), observations=10)
        found = fusion._associate(_bottle(1.45, 1.0), set())
        assert (found.id if found else None) == (known.id if expected else None)


def test_a_wide_projection_keeps_the_usual_radius() -> None:
    """A 0.5 m wide box 0.45 m from a small instance still refines it (the rule is for small boxes)."""
    fusion = InstanceFusion(SemanticMap(), FusionParams(small_radius=0.3))
    known = fusion.map.add("bottle", (1.0, 0.0, 0.1), 0.0, size=(0.08, 0.08, 0.25), observations=10)
    found = fusion._associate(_bottle(1.45, 1.0, width=0.5), set())
    assert found is not None and found.id == known.id
