"""The Patrol leaf on the simulator: real planning, an unreachable waypoint skipped, resuming."""

from __future__ import annotations

from pathlib import Path

import yaml
from patrol_doubles import Events

from missiontree.backends.sim import create_robot
from missiontree.behaviours.patrol import Patrol
from missiontree.engine.context import MissionContext
from missiontree.engine.leaf import Status
from missiontree.types import Pose2D


def room(tmp_path: Path) -> Path:
    world = {
        "name": "room", "description": "a 6 x 4 m room with a pillar",
        "robot": {"profile": "turtlebot4", "start": {"x": 1.0, "y": 2.0, "yaw": 0.0}},
        "walls": {"height": 2.5, "thickness": 0.1, "polygons": [[[0, 0], [6, 0], [6, 4], [0, 4]]]},
        "rooms": [], "people": [],
        "objects": [{"id": "pillar", "label": "pillar", "color": "white", "shape": "cylinder",
                     "size": [0.6, 0.6, 2.5], "pose": {"x": 3.0, "y": 3.0}, "movable": False}],
    }
    path = tmp_path / "room.yaml"
    path.write_text(yaml.safe_dump(world))
    return path


def run(leaf: Patrol, robot, seconds: float, halt_at: float | None = None) -> None:  # noqa: ANN001
    t = robot.now()
    end = t + seconds
    while t < end:
        leaf.tick_once()
        if leaf.status != Status.RUNNING:
            return
        if halt_at is not None and t >= halt_at:
            leaf.stop(Status.INVALID)
            halt_at = None
        t += 0.1
        robot.spin_until(t)


def test_patrol_skips_a_waypoint_inside_an_obstacle_on_the_simulator(tmp_path: Path) -> None:
    """A waypoint inside the pillar aborts in the planner; the patrol logs why and drives on."""
    robot = create_robot({"world": str(room(tmp_path)), "seed": 2})
    events = Events()
    leaf = Patrol("patrol", Patrol.Params(waypoints=[[2.0, 1.0], [3.0, 3.0], [4.5, 1.5]], laps=1))
    leaf.setup(context=MissionContext(robot=robot, events=events))
    run(leaf, robot, 120.0)
    assert leaf.status == Status.SUCCESS
    assert [e["waypoint"] for e in events.of("waypoint_reached")] == ["P1", "P3"]
    skipped = events.of("waypoint_skipped")
    assert [s["waypoint"] for s in skipped] == ["P2"] and skipped[0]["reason"]
    assert robot.pose().pose.distance_to(Pose2D(4.5, 1.5)) < 0.35


def test_preempted_patrol_resumes_interrupted_waypoint_on_the_simulator(tmp_path: Path) -> None:
    """Halted on its way to P2, the patrol drives to P2 (not P3) when it starts again."""
    robot = create_robot({"world": str(room(tmp_path)), "seed": 2})
    events = Events()
    leaf = Patrol("patrol", Patrol.Params(waypoints=[[1.5, 2.0], [4.5, 1.0], [4.5, 3.0]], laps=1))
    leaf.setup(context=MissionContext(robot=robot, events=events))
    run(leaf, robot, 6.0, halt_at=4.0)
    assert events.of("patrol_preempted")[0]["waypoint"] == "P2"
    run(leaf, robot, 120.0)
    assert leaf.status == Status.SUCCESS
    goals = [g["waypoint"] for g in events.of("goal_sent")]
    assert goals == ["P1", "P2", "P2", "P3"]
