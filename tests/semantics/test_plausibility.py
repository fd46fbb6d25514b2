"""A detection whose depth support the map shows as a thin wall is not the solid object its class is."""

from __future__ import annotations

import numpy as np
import pytest

from missiontree.perception.projection import project
from missiontree.semantics.builder import BuilderParams, SceneBuilder
from missiontree.semantics.plausibility import (
    LEAST_DEPTH,
    SupportParams,
    plausible,
    surface_point,
    thin_support,
)
from missiontree.types import CameraIntrinsics, Detection, OccupancyGrid, Pose2D, RGBDFrame

RES = 0.05
ORIGIN = Pose2D(-1.0, -2.0, 0.0)
K = CameraIntrinsics(320, 240, 277.0, 277.0, 159.5, 119.5)


def grid_with(cells: dict[tuple[float, float], int], default: int = 0) -> OccupancyGrid:
    """An 80 x 100 cell map (x -1..4, y -2..2) filled with ``default``; ``cells`` maps x-ranges to values.

    Keys are (x_from, x_to): every cell whose centre lies in that x range, all rows, gets the value.
    """
    data = np.full((80, 100), default, dtype=np.int8)
    for (x0, x1), value in cells.items():
        for col in range(100):
            x = ORIGIN.x + (col + 0.5) * RES
            if x0 <= x < x1:
                data[:, col] = value
    return OccupancyGrid(0.0, RES, ORIGIN, data)


def frame_at(depth: float = 1.0, stamp: float = 1.0) -> RGBDFrame:
    """The camera at the origin looking along +x at a flat surface ``depth`` metres away."""
    return RGBDFrame(
        stamp=stamp,
        color=np.full((240, 320, 3), 200, dtype=np.uint8),
        depth=np.full((240, 320), depth, dtype=np.float32),
        intrinsics=K,
        camera_pose=Pose2D(0.0, 0.0, 0.0),
        camera_height=0.3,
    )


def fridge(label: str = "refrigerator") -> Detection:
    """A box in the middle of the image, cut by its top (a tall thing seen from close by)."""
    return Detection(label, 0.9, (100.0, 0.0, 220.0, 200.0))


def projection(label: str = "refrigerator"):
    p = project(frame_at(), fridge(label))
    assert p is not None
    return p


def test_the_surface_point_is_the_measured_depth_along_the_ray() -> None:
    p = projection()
    assert p.position[0] > 1.2  # the centre is pushed behind the face
    x, y = surface_point(p)
    assert x == pytest.approx(1.0, abs=0.02) and y == pytest.approx(0.0, abs=0.02)


def test_a_wall_with_free_space_behind_it_is_too_thin_for_a_refrigerator() -> None:
    wall = grid_with({(1.0, 1.1): 100})  # 10 cm wall on the measured surface, the next room free behind
    p = projection()
    assert thin_support(wall, p, LEAST_DEPTH["refrigerator"])
    kept, rejected = plausible([p], wall)
    assert kept == [] and rejected == [p]


def test_a_wall_as_thick_as_the_least_depth_is_not_judged_thin() -> None:
    thick = grid_with({(1.0, 1.5): 100})  # a refrigerator the map holds: occupied half a metre deep
    assert not thin_support(thick, projection(), LEAST_DEPTH["refrigerator"])


def test_unknown_space_behind_the_surface_is_no_evidence() -> None:
    learned = grid_with({(1.0, 1.1): 100, (1.1, 4.0): -1})  # a learned map: only the front was scanned
    assert not thin_support(learned, projection(), LEAST_DEPTH["refrigerator"])


def test_a_surface_the_map_does_not_hold_is_not_judged() -> None:
    empty = grid_with({})  # a refrigerator placed after the map was made: free cells where it stands
    assert not thin_support(empty, projection(), LEAST_DEPTH["refrigerator"])


def test_a_single_free_cell_behind_a_wall_is_not_a_far_side() -> None:
    # wall, one free cell (noise), then occupied again: no free run of free_run metres
    noisy = grid_with({(1.0, 1.1): 100, (1.1, 1.15): 0, (1.15, 2.0): 100})
    assert not thin_support(noisy, projection(), LEAST_DEPTH["refrigerator"])


def test_classes_without_a_least_depth_are_kept() -> None:
    wall = grid_with({(1.0, 1.1): 100})
    chair = projection("chair")
    assert "chair" not in LEAST_DEPTH
    assert plausible([chair], wall) == ([chair], [])
    assert plausible([projection()], wall, SupportParams(least_depth={}))[1] == []
    assert plausible([projection()], None)[1] == []


def test_the_builder_drops_a_wall_boxed_as_a_refrigerator_before_it_votes() -> None:
    """The map given to update_rooms judges the next frames' projections; without the rule the wall votes."""
    wall = grid_with({(1.0, 1.1): 100})

    def candidates(params: BuilderParams) -> tuple[int, int]:
        builder = SceneBuilder(params)
        builder.update_rooms(wall, (0.0, 0.0), 0.0)
        builder.add_frame(frame_at(), [fridge()])
        return len(builder.fusion.voting.candidates), builder.fusion.dropped.get("thin support", 0)

    assert candidates(BuilderParams()) == (0, 1)
    assert candidates(BuilderParams(support=SupportParams(least_depth={}))) == (1, 0)
