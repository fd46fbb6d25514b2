"""Joining instances that are one object (semantics/merge.py), on hand-made instances."""

from __future__ import annotations

from missiontree.semantics.fusion import FusionParams, InstanceFusion
from missiontree.semantics.semantic_map import Instance, SemanticMap


def _with_mass(fusion: InstanceFusion, label: str, xy: tuple[float, float], z: float, size: tuple[float, ...],
               observations: int, mass: dict[str, float]) -> Instance:
    inst = fusion.map.add(label, (xy[0], xy[1], z), 0.0, size=size, colour="white", observations=observations)
    fusion.track(inst.id).evidence.update(mass)
    return inst


def test_two_small_instances_of_two_labels_whose_footprints_overlap_are_one_object() -> None:
    """A 9 cm cup also boxed as a bottle, 4 cm apart: one object, the cup (more score mass) stays.

    The bottle was refined in more frames, yet its boxes gave 'bottle' less score in all. Without the
    rule (twin_overlap 0) the quarter-width rule keeps both (4 cm > 2.25 cm).
    """
    kept: dict[float, set[str]] = {}
    for share in (0.5, 0.0):
        fusion = InstanceFusion(SemanticMap(), FusionParams(twin_overlap=share))
        cup_mass, bottle_mass = {"cup": 10.5, "bottle": 0.8}, {"bottle": 3.9, "cup": 0.1}
        cup = _with_mass(fusion, "cup", (7.72, 5.32), 0.06, (0.09, 0.09, 0.11), 13, cup_mass)
        _with_mass(fusion, "bottle", (7.74, 5.285), 0.1, (0.09, 0.09, 0.22), 15, bottle_mass)
        fusion.merge_overlapping(1.0)
        kept[share] = {i.label for i in fusion.map}
        if share:
            removed = [c for c in fusion.map.drain_changes() if c.kind == "removed"]
            assert len(removed) == 1 and cup.id in removed[0].reason
    assert kept == {0.5: {"cup"}, 0.0: {"cup", "bottle"}}


def test_small_objects_side_by_side_and_large_ones_stay_apart() -> None:
    """A bottle touching a cup (centres 9 cm apart) stays; so does a backpack 0.35 m from a chair."""
    fusion = InstanceFusion(SemanticMap())
    _with_mass(fusion, "cup", (1.0, 1.0), 0.06, (0.09, 0.09, 0.11), 10, {"cup": 8.0})
    _with_mass(fusion, "bottle", (1.09, 1.0), 0.1, (0.09, 0.09, 0.22), 10, {"bottle": 8.0})
    _with_mass(fusion, "chair", (3.0, 1.0), 0.45, (0.55, 0.55, 0.9), 30, {"chair": 25.0})
    _with_mass(fusion, "backpack", (3.35, 1.0), 0.22, (0.36, 0.36, 0.45), 10, {"backpack": 8.0})
    fusion.merge_overlapping(1.0)
    assert sorted(i.label for i in fusion.map) == ["backpack", "bottle", "chair", "cup"]


def test_an_instance_placed_on_something_before_another_of_its_label_is_that_one() -> None:
    """Boxes round a chair 3.5 m ahead whose depth fell on a face 2 m ahead made a second chair there.

    Every view of the front chair held the established chair behind it in the box, and none
    refined that one: the front chair goes, and later such boxes at its place start no candidate.
    With front_share 0 it stays.
    """
    from test_fusion_views import K, frame, projection, room_depth

    box = (K.cx - 17, 60.0, K.cx + 17, 180.0)  # the 0.5 m chair 3.5 m ahead: 33 pixels wide
    left: dict[float, list[str]] = {}
    for share in (0.8, 0.0):
        fusion = InstanceFusion(SemanticMap(), FusionParams(front_share=share))
        behind = fusion.map.add("chair", (3.5, 0.0, 0.45), 0.0, size=(0.5, 0.5, 0.9), observations=60)
        front = fusion.map.add("chair", (2.0, 0.0, 0.45), 0.0, size=(0.45, 0.45, 0.9), observations=10)
        for k in range(8):
            stamp = 1.0 + k
            p = projection("chair", stamp, box, (2.0, 0.0, 0.45), 2.0, (0.45, 0.45, 0.9))
            fusion.process(frame(stamp, room_depth(2.0)), [p])
        left[share] = sorted(i.id for i in fusion.map)
        if share:
            assert not fusion.voting.candidates
            removed = [c for c in fusion.map.drain_changes() if c.kind == "removed"]
            assert [c.id for c in removed] == [front.id] and behind.id in removed[0].reason
    assert left == {0.8: [behind.id], 0.0: sorted([behind.id, front.id])}


def test_a_large_instance_placed_by_cut_boxes_beside_one_of_its_label_is_that_one() -> None:
    """A dining table (80 views, whole) and a 'table' 0.93 m away placed by 11 cut boxes of 14: one.

    Two chairs side by side, both seen whole, stay two. Without the rule (cut_share None) the
    tables stay two as well.
    """
    counts: dict[float | None, int] = {}
    for share in (0.5, None):
        fusion = InstanceFusion(SemanticMap(), FusionParams(cut_share=share))
        add = fusion.map.add
        table = add("table", (4.48, 3.05, 0.37), 0.0, size=(1.44, 1.44, 1.0), colour="brown", observations=80)
        fusion.track(table.id).xs.extend([(4.48, 3.05, 0.37)] * 29)
        edge = add("table", (3.56, 2.85, 0.38), 0.0, size=(0.97, 0.97, 0.95), colour="black", observations=14)
        fusion.track(edge.id).xs.extend([(3.56, 2.85, 0.38)] * 3)
        fusion.track(edge.id).clipped.extend([(3.5, 2.9, 0.38)] * 11)
        for k, y in enumerate((6.0, 6.6)):
            size = (0.65, 0.65, 0.9)
            chair = add("chair", (5.0, y, 0.45), 0.0, size=size, colour="red", observations=30 + k)
            fusion.track(chair.id).xs.extend([(5.0, y, 0.45)] * 20)
        fusion.merge_overlapping(1.0)
        counts[share] = len(fusion.map)
        if share:
            assert fusion.map.get(table.id) is not None and fusion.map.get(edge.id) is None
            assert sorted(i.label for i in fusion.map) == ["chair", "chair", "table"]
    assert counts == {0.5: 3, None: 4}


def test_one_object_seen_twice_keeps_both_instances_surface_cells_and_colours() -> None:
    """Two chairs of one colour 0.2 m apart are one chair.

    The one seen more often stays and takes the other's positions, surface cells (its outline),
    colours and class evidence.
    """
    fusion = InstanceFusion(SemanticMap())
    keep = _with_mass(fusion, "chair", (2.0, 2.0), 0.45, (0.5, 0.5, 0.9), 20, {"chair": 15.0})
    drop = _with_mass(fusion, "chair", (2.2, 2.0), 0.45, (0.5, 0.5, 0.9), 5, {"chair": 4.0, "sofa": 0.5})
    fusion.track(drop.id).cells.update({(44, 40): 3, (45, 40): 2})
    fusion.track(drop.id).colours.update({"white": 5})
    fusion.track(drop.id).xs.append((2.2, 2.0, 0.45))
    fusion.merge_overlapping(1.0)
    assert [i.id for i in fusion.map] == [keep.id]
    track = fusion.track(keep.id)
    assert track.cells == {(44, 40): 3, (45, 40): 2}
    assert track.colours["white"] == 5
    assert track.xs == [(2.2, 2.0, 0.45)]
    assert track.evidence == {"chair": 19.0, "sofa": 0.5}


def test_a_nearer_object_of_the_label_before_another_stays() -> None:
    """Two 1.2 m desks in a row, 1.5 and 3.3 m ahead: the near one's box is twice the far one's width there.

    A box round the desk behind would be its size at 3.3 m; the near desk's is wider, so it is another
    desk and stays. Without the size check (front_fit None) the front rule removes it.
    """
    from test_fusion_views import K, frame, projection, room_depth

    half = 0.5 * 1.2 * K.fx / 1.5
    box = (K.cx - half, 90.0, K.cx + half, 200.0)
    left: dict[float | None, int] = {}
    for fit in (1.4, None):
        fusion = InstanceFusion(SemanticMap(), FusionParams(front_fit=fit))
        fusion.map.add("table", (3.3, 0.0, 0.37), 0.0, size=(1.2, 1.2, 0.75), observations=60)
        fusion.map.add("table", (1.5, 0.0, 0.37), 0.0, size=(1.2, 1.2, 0.75), observations=10)
        for k in range(8):
            stamp = 1.0 + k
            p = projection("table", stamp, box, (1.5, 0.0, 0.37), 1.5, (1.2, 1.2, 0.75))
            fusion.process(frame(stamp, room_depth(1.5)), [p])
        fusion.merge_overlapping(10.0)
        left[fit] = len(fusion.map)
    assert left == {1.4: 2, None: 1}
