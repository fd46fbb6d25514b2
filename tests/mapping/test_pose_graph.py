"""The 2-D pose graph: a drifted square loop closed by one measured closure."""

from __future__ import annotations

import math

import pytest

from missiontree.mapping.pose_graph import Edge, optimise
from missiontree.mapping.rawlog import compose
from missiontree.mapping.scan_matching import relative
from missiontree.types import Pose2D


def square(steps_per_side: int = 10, side: float = 4.0, yaw_drift: float = 0.0) -> list[Pose2D]:
    """A square loop walked counter-clockwise; each step's heading off by ``yaw_drift`` (rad)."""
    poses = [Pose2D(0.0, 0.0, 0.0)]
    step = side / steps_per_side
    for k in range(1, 4 * steps_per_side + 1):
        turn = math.pi / 2 if k % steps_per_side == 0 else 0.0
        poses.append(compose(poses[-1], Pose2D(step, 0.0, turn + yaw_drift)))
    return poses


def test_one_closure_pulls_a_drifted_loop_shut() -> None:
    """A loop whose odometry ends 1 m off closes within 5 cm once its end is tied to its start."""
    truth = square()
    drifted = square(yaw_drift=math.radians(0.7))
    steps = [Edge(k, k + 1, relative(drifted[k], drifted[k + 1]), 0.05, 0.02) for k in range(len(truth) - 1)]
    closure = Edge(0, len(truth) - 1, relative(truth[0], truth[-1]), 0.02, 0.01)
    assert drifted[-1].distance_to(truth[-1]) > 0.5
    solved = optimise(drifted, [*steps, closure])
    assert solved[-1].distance_to(truth[-1]) < 0.05
    assert solved[0] == drifted[0]                      # the first pose anchors the frame


def test_without_closures_the_poses_are_unchanged() -> None:
    """With only the chain of steps the graph is already satisfied: the first estimate comes back."""
    drifted = square(yaw_drift=0.01)
    steps = [Edge(k, k + 1, relative(drifted[k], drifted[k + 1]), 0.05, 0.02)
             for k in range(len(drifted) - 1)]
    solved = optimise(drifted, steps)
    assert max(p.distance_to(q) for p, q in zip(solved, drifted, strict=True)) < 1e-6


def test_an_edge_to_a_missing_pose_is_refused() -> None:
    """An edge naming a pose beyond the list is a ValueError naming it."""
    with pytest.raises(ValueError, match=r"edge \(0, 5\)"):
        optimise([Pose2D(0, 0), Pose2D(1, 0)], [Edge(0, 5, Pose2D(1, 0), 0.1, 0.1)])
