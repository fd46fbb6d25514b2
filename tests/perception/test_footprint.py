"""Footprint helpers alone: size priors and the depth step at a box's sides."""

from __future__ import annotations

import math

import numpy as np

from missiontree.perception.footprint import SIZE_PRIORS, plausible_size, stands_out
from missiontree.perception.projection import Projection
from missiontree.types import CameraIntrinsics, Detection, Pose2D, RGBDFrame

K = CameraIntrinsics(width=320, height=240, fx=228.5, fy=228.5, cx=159.5, cy=119.5)


def measured(label: str, width: float, height: float) -> Projection:
    box = (100.0, 50.0, 150.0, 150.0)
    return Projection(
        label,
        0.9,
        box,
        (2.0, 0.0, 0.5),
        2.0,
        2.0,
        (width, width, height),
        0.0,
        Pose2D(0, 0, 0),
        Detection(label, 0.9, box),
    )


def test_size_priors_turn_down_only_what_is_too_small_for_its_class() -> None:
    thin_tv = [measured("tv", 0.12, 0.8)] * 5
    assert not plausible_size("tv", thin_tv, 0.7)
    assert plausible_size("tv", [measured("tv", 0.9, 0.6)] * 5, 0.7)
    assert plausible_size("umbrella", [measured("umbrella", 0.1, 0.9)] * 5, 0.7)
    assert plausible_size("spaceship", [measured("spaceship", 0.01, 0.01)], 0.7)  # not listed: not checked
    assert plausible_size("tv", thin_tv, 0.0)  # off
    assert all(w > 0 and h > 0 for w, h in SIZE_PRIORS.values())


def test_a_box_stands_out_where_the_depth_steps_at_an_uncut_side() -> None:
    depth = np.full((K.height, K.width), 4.0, np.float32)  # a flat wall 4 m away
    colour = np.zeros((K.height, K.width, 3), np.uint8)
    frame = RGBDFrame(0.0, colour, depth, K, Pose2D(0, 0, 0), 0.4)
    box = (100.0, 60.0, 180.0, 180.0)
    assert not stands_out(frame, box, 6, 0.15)  # the wall continues past both sides
    depth[:, 100:181] = 2.5  # an object 1.5 m in front of the wall fills the box
    assert stands_out(frame, box, 6, 0.15)
    assert not stands_out(frame, (0.0, 60.0, 319.0, 180.0), 6, 0.15)  # both sides cut: no evidence


def test_an_outline_that_does_not_hold_the_fused_position_is_a_neighbours() -> None:
    """Cells outlining a 0.6 x 0.5 object whose rectangle ends 0.52 m before the fused position.

    The boxes' centre points (at most 0.45 m behind the surface seen) lie outside it: the cells are
    a neighbour's, no centre. Without the check the centre would move 0.85 m onto the neighbour.
    """
    from collections import Counter

    from missiontree.perception.footprint import outline_centre

    cell = 0.05
    points = [(10.9 + 0.02 * k, 0.7) for k in range(31)] + [(10.9, 0.7 + 0.02 * k) for k in range(26)]
    cells = Counter({(int(x // cell), int(y // cell)): 3 for x, y in points})
    fused = (12.05, 0.95, 0.35)
    moved = outline_centre(cells, fused, 1.26, cell)
    assert moved is not None and math.hypot(moved[0] - fused[0], moved[1] - fused[1]) > 0.75
    assert outline_centre(cells, fused, 1.26, cell, holds_fused=0.45) is None
    assert outline_centre(cells, (11.6, 0.9, 0.35), 1.26, cell, holds_fused=0.45) is not None
