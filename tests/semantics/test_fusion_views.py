"""Fusion across views on hand-made frames: small objects, cut boxes, large objects' boxes and outlines.

A camera 0.4 m above the floor at the origin looks along +x; the depth image is computed exactly
(floor, a wall 6 m ahead, optionally a box-shaped object), so each rule is checked on its own.
"""

from __future__ import annotations

import math
from collections import Counter

import numpy as np

from missiontree.perception.depth import surface_points
from missiontree.perception.projection import Projection
from missiontree.perception.tracking import TemporalVoting
from missiontree.semantics.fusion import FusionParams, InstanceFusion
from missiontree.semantics.fusion_state import Track
from missiontree.semantics.semantic_map import SemanticMap
from missiontree.types import CameraIntrinsics, Detection, Pose2D, RGBDFrame

K = CameraIntrinsics(width=320, height=240, fx=228.5, fy=228.5, cx=159.5, cy=119.5)
CAMERA_HEIGHT = 0.4


def room_depth(face: float | None = None, half_width: float = 0.5) -> np.ndarray:
    """Floor below the horizon, a wall 6 m ahead; with ``face``, an object's flat face at that depth."""
    rows = np.arange(K.height, dtype=float)[:, None] + 0.5
    below = rows - K.cy
    depth = np.where(below > 0, CAMERA_HEIGHT * K.fy / np.maximum(below, 1e-6), 6.0)
    depth = np.broadcast_to(np.minimum(depth, 6.0), (K.height, K.width)).astype(np.float32).copy()
    if face is not None:
        cols = np.arange(K.width, dtype=float) + 0.5
        lateral = (K.cx - cols) * face / K.fx
        inside = np.abs(lateral) <= half_width
        height = CAMERA_HEIGHT - (rows - K.cy) * face / K.fy  # (rows, 1)
        on = (height >= 0.0) & (height <= 0.8)
        depth[np.ix_(on[:, 0], inside)] = face
    return depth


def frame(stamp: float, depth: np.ndarray) -> RGBDFrame:
    colour = np.full((K.height, K.width, 3), 128, np.uint8)
    return RGBDFrame(stamp, colour, depth, K, Pose2D(0.0, 0.0, 0.0), CAMERA_HEIGHT)


def projection(
    label: str,
    stamp: float,
    box: tuple[float, float, float, float],
    position: tuple[float, float, float],
    depth: float,
    size: tuple[float, float, float],
) -> Projection:
    det = Detection(label, 0.9, box)
    return Projection(label, 0.9, box, position, depth, depth, size, stamp, Pose2D(0, 0, 0), det)


def cup(stamp: float) -> Projection:
    box = (K.cx - 12, K.cy + 60, K.cx + 12, K.cy + 85)
    return projection("cup", stamp, box, (1.2, 0.0, 0.05), 1.2, (0.09, 0.09, 0.11))


def test_a_small_object_is_confirmed_in_fewer_frames() -> None:
    """A cup seen in five frames is in the map; with small_min_frames at the paper's 10 it is not yet."""
    quick = InstanceFusion(SemanticMap(), FusionParams(small_min_frames=5, min_bounded_share=0))
    paper = InstanceFusion(SemanticMap(), FusionParams(small_min_frames=10, min_bounded_share=0))
    for k in range(5):
        quick.process(frame(1.0 + k, room_depth()), [cup(1.0 + k)])
        paper.process(frame(1.0 + k, room_depth()), [cup(1.0 + k)])
    assert [i.label for i in quick.map] == ["cup"] and len(paper.map) == 0


def test_frames_of_several_visits_add_up() -> None:
    """Three frames now, three more two minutes later: the small candidate was remembered and is confirmed."""
    fusion = InstanceFusion(SemanticMap(), FusionParams(small_min_frames=6, min_bounded_share=0))
    for stamp in (1.0, 1.1, 1.2, 120.0, 120.1, 120.2):
        fusion.process(frame(stamp, room_depth()), [cup(stamp)])
    assert [i.label for i in fusion.map] == ["cup"]


def test_boxes_cut_at_the_bottom_or_a_side_do_not_confirm_alone() -> None:
    """A 'refrigerator' whose boxes the image's side and bottom cut waits; views with its foot in confirm it.

    The top may cut them (a tall object seen from close) when the whole-view rule is off.
    """
    fusion = InstanceFusion(SemanticMap(), FusionParams(min_bounded_share=0, whole_size=None))
    cut = (0.0, 0.0, 220.0, 240.0)
    whole = (100.0, 0.0, 220.0, 200.0)
    stamp = 1.0
    for _ in range(20):
        fusion.process(
            frame(stamp, room_depth()),
            [projection("refrigerator", stamp, cut, (3.0, 0, 0.8), 2.7, (0.7, 0.7, 1.6))],
        )
        stamp += 1.0
    assert len(fusion.map) == 0
    for _ in range(6):
        fusion.process(
            frame(stamp, room_depth()),
            [projection("refrigerator", stamp, whole, (3.0, 0, 0.8), 2.7, (0.7, 0.7, 1.6))],
        )
        stamp += 1.0
    assert [i.label for i in fusion.map] == ["refrigerator"]


def test_a_large_candidate_every_box_of_which_the_top_cuts_is_not_confirmed() -> None:
    """A wall seen from close called a refrigerator, cut by the image's top in every box, never becomes one.

    One view that shows it whole (no border cuts it) confirms it.
    """
    fusion = InstanceFusion(SemanticMap(), FusionParams(min_bounded_share=0))
    top_cut = (100.0, 0.0, 220.0, 200.0)
    whole = (120.0, 20.0, 200.0, 200.0)
    stamp = 1.0
    for _ in range(30):
        fusion.process(
            frame(stamp, room_depth()),
            [projection("refrigerator", stamp, top_cut, (3.0, 0, 0.8), 2.7, (0.7, 0.7, 1.6))],
        )
        stamp += 1.0
    assert len(fusion.map) == 0
    fusion.process(
        frame(stamp, room_depth()),
        [projection("refrigerator", stamp, whole, (3.0, 0, 0.8), 2.7, (0.7, 0.7, 1.6))],
    )
    assert [i.label for i in fusion.map] == ["refrigerator"]


def test_a_box_holding_a_large_instance_refines_it_though_its_centre_falls_far() -> None:
    """A sofa's box seen end-on places its near face 1.2 m before the known centre: still the same sofa."""
    smap = SemanticMap()
    fusion = InstanceFusion(smap)
    sofa = smap.add("sofa", (3.5, 0.0, 0.4), 0.0, size=(1.9, 1.9, 0.8), colour="grey", observations=20)
    box = (K.cx - 60, 80.0, K.cx + 60, 170.0)
    p = projection("sofa", 1.0, box, (2.3, 0.0, 0.4), 2.3, (1.0, 1.0, 0.8))
    fusion.process(frame(1.0, room_depth(2.3)), [p])
    assert [i.id for i in smap] == [sofa.id] and smap.get(sofa.id).observations == 21  # type: ignore[union-attr]
    assert not fusion.voting.candidates


def test_a_small_instance_is_not_taken_by_a_box_beyond_the_radius() -> None:
    """Image-space association is for large things only: a cup 0.8 m off stays a separate candidate."""
    smap = SemanticMap()
    fusion = InstanceFusion(smap)
    smap.add("cup", (2.0, 0.0, 0.05), 0.0, size=(0.09, 0.09, 0.11), colour="red", observations=20)
    box = (K.cx - 8, K.cy + 40, K.cx + 8, K.cy + 60)
    fusion.process(
        frame(1.0, room_depth()), [projection("cup", 1.0, box, (1.2, 0.0, 0.05), 1.2, (0.09, 0.09, 0.11))]
    )
    assert len(fusion.voting.candidates) == 1


def test_two_instances_one_box_holds_are_one_object() -> None:
    """Two sofas 1.1 m apart along the view ray, both inside one box at consistent depth: merged."""
    smap = SemanticMap()
    fusion = InstanceFusion(smap)
    near = smap.add("sofa", (2.8, 0.05, 0.4), 0.0, size=(0.9, 0.9, 0.8), colour="grey", observations=30)
    far = smap.add("sofa", (3.9, -0.05, 0.4), 0.0, size=(0.9, 0.9, 0.8), colour="blue", observations=10)
    box = (K.cx - 70, 80.0, K.cx + 70, 170.0)
    fusion.process(
        frame(1.0, room_depth(2.4)), [projection("sofa", 1.0, box, (2.8, 0.0, 0.4), 2.4, (1.2, 1.2, 0.8))]
    )
    assert [i.id for i in smap] == [near.id]
    removed = [c for c in smap.drain_changes() if c.kind == "removed"]
    assert [c.id for c in removed] == [far.id] and "one box holds both" in removed[0].reason


def _cells(points: list[tuple[float, float]], cell: float = 0.05) -> Counter[tuple[int, int]]:
    return Counter({(math.floor(x / cell), math.floor(y / cell)): 3 for x, y in points})


def test_two_faces_outline_the_centre() -> None:
    """The long and a short face of a 1.9 x 0.9 sofa centred at (2, 1): the rectangle's centre."""
    fusion = InstanceFusion(SemanticMap())
    inst = fusion.map.add("sofa", (1.6, 1.0, 0.4), 0.0, size=(1.9, 1.9, 0.8))
    xs = np.arange(1.05, 2.95, 0.02)
    ys = np.arange(0.55, 1.45, 0.02)
    points = [(float(x), 0.55) for x in xs] + [(1.05, float(y)) for y in ys]
    track = Track(cells=_cells(points))
    centre = fusion.outline_centre(track, (1.6, 1.0, 0.4), inst)
    assert centre is not None and math.hypot(centre[0] - 2.0, centre[1] - 1.0) < 0.08


def test_one_face_keeps_the_fused_depth_on_its_bisector() -> None:
    """Only the long face seen: the centre lies on its perpendicular bisector, as far behind it as fused."""
    fusion = InstanceFusion(SemanticMap())
    inst = fusion.map.add("sofa", (1.7, 1.0, 0.4), 0.0, size=(1.9, 1.9, 0.8))
    points = [(float(x), 0.55) for x in np.arange(1.05, 2.95, 0.02)]
    centre = fusion.outline_centre(Track(cells=_cells(points)), (1.7, 1.0, 0.4), inst)
    assert centre is not None and abs(centre[0] - 2.0) < 0.05 and abs(centre[1] - 1.0) < 0.05


def test_surface_points_lie_on_the_face_the_box_shows() -> None:
    """A flat face 2.5 m ahead, 1 m wide: its points at x = 2.5, |y| <= 0.5; floor and wall left out."""
    f = frame(1.0, room_depth(2.5))
    box = (K.cx - 50, 60.0, K.cx + 50, 200.0)
    pts = surface_points(f, box)
    assert len(pts) > 50
    assert np.allclose(pts[:, 0], 2.5, atol=0.02) and np.all(np.abs(pts[:, 1]) <= 0.55)


def test_voting_joins_a_large_projection_within_half_its_width() -> None:
    """Size-aware voting: views of one sofa 0.8 m apart make one candidate; the paper's voting makes two."""
    aware = TemporalVoting(3, 0.5, 30.0, size_aware=True)
    paper = TemporalVoting(3, 0.5, 30.0)
    for voting in (aware, paper):
        voting.vote(projection("sofa", 1.0, (0, 0, 10, 10), (3.0, 0.0, 0.4), 2.5, (1.8, 1.8, 0.8)))
        voting.vote(projection("sofa", 2.0, (0, 0, 10, 10), (3.8, 0.0, 0.4), 2.5, (1.8, 1.8, 0.8)))
    assert len(aware.candidates) == 1 and len(paper.candidates) == 2


def test_voting_asks_the_candidate_rule_and_the_ready_test() -> None:
    """required() sets the frames a candidate needs; ready() holds it back until it passes."""
    held = {"ok": False}
    voting = TemporalVoting(10, 0.5, 30.0, required=lambda c: 2, ready=lambda c: held["ok"])
    p = [
        projection("cup", float(k), (0, 0, 10, 10), (1.0, 0.0, 0.05), 1.0, (0.1, 0.1, 0.1)) for k in range(4)
    ]
    assert voting.vote(p[0]) is None and voting.vote(p[1]) is None
    held["ok"] = True
    accepted = voting.vote(p[2])
    assert accepted is not None and accepted.frames == 3


def test_a_candidate_too_small_for_its_class_is_not_confirmed() -> None:
    """A 'tv' 0.12 m wide (a closed umbrella, misnamed) stays a candidate; a 0.8 m tv is confirmed."""
    fusion = InstanceFusion(SemanticMap(), FusionParams(min_bounded_share=0))
    thin = (150.0, 60.0, 160.0, 140.0)
    wide = (100.0, 60.0, 180.0, 140.0)
    for k in range(12):
        stamp = 1.0 + k
        fusion.process(
            frame(stamp, room_depth()),
            [
                projection("tv", stamp, thin, (2.5, 0.0, 0.6), 2.5, (0.12, 0.12, 0.8)),
                projection("tv", stamp, wide, (2.5, 2.0, 0.6), 2.5, (0.8, 0.8, 0.6)),
            ],
        )
    assert [round(i.position[1]) for i in fusion.map] == [2]
    assert len(fusion.voting.candidates) == 1


def test_a_place_only_seen_behind_something_stays_unchecked() -> None:
    """A cup's place hidden behind a box in front: unchecked (go and look).

    Seen empty: doubtful (look again); seen with the cup: neither.
    """
    smap = SemanticMap()
    fusion = InstanceFusion(smap)
    cup_id = smap.add("cup", (1.2, 0.0, 0.05), 0.0, size=(0.09, 0.09, 0.11), observations=10).id
    fusion.process(frame(1.0, room_depth(0.6)), [])
    assert [i.id for i in fusion.unchecked_since(0.5)] == [cup_id]
    fusion.process(frame(2.0, room_depth()), [])
    assert [i.id for i in fusion.unchecked_since(0.5)] == [cup_id] and smap.get(cup_id).misses == 1  # type: ignore[union-attr]
    fusion.process(frame(3.0, room_depth()), [cup(3.0)])
    assert fusion.unchecked_since(0.5) == []


def test_a_box_on_a_flat_wall_is_not_an_object_but_one_standing_out_is() -> None:
    """Boxes around part of the far wall never stand out in depth: no instance. A face 2.5 m ahead does."""
    wall_box = (120.0, 20.0, 200.0, 100.0)  # above the horizon: the wall 6 m away, flat past the box
    face_box = (K.cx - 45, 70.0, K.cx + 45, 160.0)  # the 1 m wide face at 2.5 m, fitted
    wall = InstanceFusion(SemanticMap())
    face = InstanceFusion(SemanticMap())
    for k in range(12):
        stamp = 1.0 + k
        p = projection("refrigerator", stamp, wall_box, (6.0, 0.0, 1.0), 6.0 * 0.7, (1.0, 1.0, 1.2))
        wall.process(frame(stamp, room_depth()), [p])
        q = projection("sofa", stamp, face_box, (2.9, 0.0, 0.4), 2.5, (1.0, 1.0, 0.8))
        face.process(frame(stamp, room_depth(2.5)), [q])
    assert len(wall.map) == 0 and [i.label for i in face.map] == ["sofa"]


def test_the_outline_leaves_out_the_surface_of_a_smaller_instance_in_front() -> None:
    """A 0.9 x 0.6 table at (2, 1), its near and left faces seen, a laptop on the floor before it.

    The table's boxes held the laptop's surface too; the laptop is an instance of its own, so its
    cells are left out and the outline's centre is the table's. Without the rule it is pulled forward.
    """
    near_face = [(float(x), 0.72) for x in np.arange(1.56, 2.45, 0.02)]
    left_face = [(1.56, float(y)) for y in np.arange(0.72, 1.29, 0.02)]
    laptop = [(float(x), float(y)) for x in np.arange(1.84, 2.16, 0.02) for y in np.arange(0.26, 0.46, 0.02)]
    cells = _cells(near_face + left_face + laptop)
    centres = {}
    for margin in (0.05, None):
        fusion = InstanceFusion(SemanticMap(), FusionParams(explained_margin=margin))
        table = fusion.map.add("table", (2.0, 0.9, 0.2), 0.0, size=(0.95, 0.95, 0.4))
        fusion.map.add("laptop", (2.0, 0.36, 0.1), 0.0, size=(0.34, 0.34, 0.22))
        centres[margin] = fusion.outline_centre(Track(cells=Counter(cells)), (2.0, 0.9, 0.2), table)
    kept, off = centres[0.05], centres[None]
    assert kept is not None and math.hypot(kept[0] - 2.0, kept[1] - 1.0) < 0.06
    assert off is not None and math.hypot(off[0] - 2.0, off[1] - 1.0) > 0.15


def test_the_outline_keeps_the_cells_of_a_large_instance_at_its_place() -> None:
    """A 1.1 x 0.4 tv also boxed as a 0.93 m 'table' at its place: the table's cells are the tv's.

    A large instance is not left out of the outline (it may be the same object under another
    name): the centre is the one found without the rule. A 0.4 m one there would be left out.
    """
    front = [(float(x), 7.12) for x in np.arange(6.88, 7.97, 0.02)]
    side = [(6.88, float(y)) for y in np.arange(7.12, 7.51, 0.02)]
    cells = _cells(front + side)
    centres = {}
    for size, margin in ((0.93, 0.05), (0.93, None), (0.4, 0.05)):
        fusion = InstanceFusion(SemanticMap(), FusionParams(explained_margin=margin))
        tv = fusion.map.add("tv", (7.45, 7.3, 0.3), 0.0, size=(1.13, 1.13, 0.69))
        fusion.map.add("table", (7.05, 7.25, 0.3), 0.0, size=(size, size, 0.72))
        centres[(size, margin)] = fusion.outline_centre(Track(cells=Counter(cells)), (7.45, 7.3, 0.3), tv)
    assert centres[(0.93, 0.05)] == centres[(0.93, None)] is not None
    assert centres[(0.4, 0.05)] != centres[(0.93, None)]


def test_the_colour_comes_from_the_pixels_at_the_objects_depth_not_the_wall_behind() -> None:
    """A blue chair's back fills a quarter of its box, the wall behind the rest: the instance is blue."""
    from missiontree.semantics.fusion import _colour

    depth = np.full((K.height, K.width), 4.0, np.float32)  # the wall behind the chair
    colour = np.zeros((K.height, K.width, 3), np.uint8)
    colour[:] = (214, 210, 200)  # the wall
    box = (100.0, 60.0, 200.0, 180.0)
    depth[60:180, 140:155] = 2.0  # the chair's back and legs: a quarter of the inner box
    colour[60:180, 140:155] = (35, 70, 200)
    f = RGBDFrame(1.0, colour, depth, K, Pose2D(0.0, 0.0, 0.0), CAMERA_HEIGHT)
    det = Detection("chair", 0.9, box)
    assert _colour(f, det) != "blue"  # the whole inner box: mostly wall
    assert _colour(f, det, 2.0) == "blue"
