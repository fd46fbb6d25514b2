"""The scene-graph benchmark's dynamic-phase route: a look at every known place no viewpoint is near."""

from __future__ import annotations

import math
import sys
from pathlib import Path

from missiontree.backends.sim import create_robot

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
import scene_eval_route as scene_graph_eval  # noqa: E402


def test_revisit_adds_a_look_near_each_place_far_from_the_route() -> None:
    robot = create_robot({"world": "office", "seed": 0})
    try:
        route = scene_graph_eval.viewpoints(robot)
        first = route[0]
        far = max(route, key=lambda p: math.hypot(p[0] - first[0], p[1] - first[1]))
        assert math.hypot(far[0] - first[0], far[1] - first[1]) > scene_graph_eval.REVISIT_MAX
        near = (first[0] + 0.5, first[1])
        stops = scene_graph_eval.revisit_points(robot, [near, far], [first])
        assert sorted(stops, key=lambda s: s[2] is not None) == [(first[0], first[1], None), stops[1]]
        x, y, place = stops[1]
        assert place == far  # the place near the route's viewpoint needs no look of its own
        assert (
            scene_graph_eval.REVISIT_MIN <= math.hypot(x - far[0], y - far[1]) <= scene_graph_eval.REVISIT_MAX
        )
        grid = robot.occupancy()
        col = int((x - grid.origin.x) / grid.resolution)
        row = int((y - grid.origin.y) / grid.resolution)
        assert 0 <= grid.data[row, col] < 50  # a free cell of the robot's own map
    finally:
        robot.close()
