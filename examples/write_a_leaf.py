"""Write a leaf: a node type of your own, used from a mission file and ticked on the simulator.

What it shows:

- ``DriveUntilObstacle``, a :class:`~missiontree.engine.leaf.Leaf` subclass that drives straight
  ahead until the lidar's front distance falls under a threshold, then stops. Its ``Params`` model
  declares the parameters (typed, bounded, documented) and the blackboard ports in one place: an
  ``Input`` (a speed limit some other node may set) and an ``Output`` (the last front distance).
- Where each piece of work goes (py_trees' lifecycle): the constructor only stores the validated parameters
  (so the tree builds and renders with no robot); ``on_setup()`` (called by ``setup``) checks the
  robot can do what the leaf needs; ``initialise()`` starts the work; ``update()`` reads one scan,
  decides and returns at once — it never blocks; ``terminate()`` stops the wheels whether the leaf
  finished or was halted by a parent (here by a ``Timeout``).
- Expected failures are values: "no clear reading" or "blocked from the start" end the leaf with
  ``self.fail(reason)``, a reason the tick log records and ``missiontree log summarize`` prints.
- Registering the type in a :class:`~missiontree.engine.registry.NodeRegistry` next to the
  built-in types, so that the mission below (a YAML string written to a file) is checked against
  its parameters and ports like any other node, then run with the runner on the simulator
  (``missiontree.backends.sim:create_robot``, the office world).

Run it from the repository root (a few seconds)::

    .venv/bin/python examples/write_a_leaf.py                 # run directory in a temporary folder
    .venv/bin/python examples/write_a_leaf.py --out runs/leaf && missiontree log summarize runs/leaf

In a real project the leaf would live in a plugin that registers it through the
``missiontree_register_nodes`` hook (see docs/plugins.md).
"""

from __future__ import annotations

import argparse
import math
import tempfile
from pathlib import Path
from typing import Annotated

import numpy as np
from pydantic import BaseModel, Field

from missiontree.backends.sim import create_robot
from missiontree.engine.build import build_tree
from missiontree.engine.context import MissionContext
from missiontree.engine.leaf import Leaf, Status
from missiontree.engine.loader import load_mission
from missiontree.engine.ports import Input, Output
from missiontree.engine.runner import Runner
from missiontree.plugins.manager import load_plugins
from missiontree.types import LaserScan


def front_distance(scan: LaserScan, half_width: float) -> float:
    """The nearest valid return within ``half_width`` radians of straight ahead (inf if none)."""
    ranges = np.asarray(scan.ranges, dtype=float)
    bearings = (scan.angles() + math.pi) % (2.0 * math.pi) - math.pi  # robot frame, 0 = ahead
    valid = np.isfinite(ranges) & (ranges >= scan.range_min) & (ranges <= scan.range_max)
    ahead = valid & (np.abs(bearings) <= half_width)
    return float(ranges[ahead].min()) if np.any(ahead) else math.inf


class DriveUntilObstacle(Leaf):
    """Drive straight ahead until the lidar sees something closer than `stop_at`, then stop.

    Fails when the way is already blocked when it starts, or when the scan goes stale.
    """

    class Params(BaseModel):
        speed: float = Field(0.3, gt=0, le=1.0, description="forward speed, m/s")
        stop_at: float = Field(0.5, gt=0, description="stop when the front distance is below this, m")
        half_width: float = Field(30.0, gt=0, le=90, description="half width of the front cone, degrees")
        max_scan_age: float = Field(0.5, gt=0, description="a scan older than this is stale, s")
        speed_limit: Annotated[str, Input("a speed cap, m/s, if set", type="float")] = "speed_limit"
        front: Annotated[str, Output("the last front distance measured, m", type="float")] = "front_distance"

    def on_setup(self) -> None:
        """Check the robot has a lidar and a velocity interface (called once, before the first tick)."""
        robot = self.context.robot
        missing = [name for name in ("scan", "drive", "stop") if not callable(getattr(robot, name, None))]
        if missing:
            raise TypeError(f"{self.name}: the robot lacks {', '.join(missing)}; use a backend with a lidar")

    def initialise(self) -> None:
        """Start: note the time; the first update() sends the first velocity command."""
        self.started = self.context.robot.now()
        self.emit("drive_started", speed=self.params.speed, stop_at=self.params.stop_at)

    def update(self) -> Status:
        """Read the latest scan, publish the front distance, then drive on or stop. Never blocks."""
        robot = self.context.robot
        scan = robot.scan()
        now = robot.now()
        if scan is None or now - scan.stamp > self.params.max_scan_age:
            robot.stop()
            if now - self.started > self.params.max_scan_age:
                return self.fail(f"no lidar scan newer than {self.params.max_scan_age:g} s")
            return self.running("waiting for a scan")
        distance = front_distance(scan, math.radians(self.params.half_width))
        self.write("front", distance)
        if distance < self.params.stop_at:
            robot.stop()
            if now == self.started:
                return self.fail(f"blocked from the start: {distance:.2f} m ahead")
            travelled = now - self.started
            self.emit("obstacle_reached", distance=distance, after=travelled)
            return self.succeed(f"stopped {distance:.2f} m before an obstacle after {travelled:.1f} s")
        limit = self.read("speed_limit")
        speed = min(self.params.speed, float(limit)) if limit is not None else self.params.speed
        robot.drive(speed, 0.0)
        return self.running(f"{distance:.2f} m ahead at {speed:.2f} m/s")

    def terminate(self, new_status: Status) -> None:
        """Stop the wheels: after success or failure, and when a parent halts this leaf (INVALID)."""
        if self.ctx is not None:
            self.ctx.robot.stop()


MISSION = """\
version: 1
description: Drive east from the kitchen towards the office door until something (the door frame) is close.
run: {tick_hz: 10, max_duration: 60}
blackboard:
  speed_limit: 0.4        # read by DriveUntilObstacle's speed_limit port
root:
  Sequence:
    name: main
    memory: true
    children:
      - Timeout:
          seconds: 40     # halts the leaf (its terminate() stops the robot) if it takes longer
          child:
            DriveUntilObstacle: {name: drive, speed: 0.5, stop_at: 0.6}
      - CheckBlackboard: {name: close_enough, key: front_distance, op: "<", value: 0.6}
"""


def main() -> int:
    """Register the leaf, load the mission, run it on the simulator; exit 0 when it succeeded."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, help="run directory (default: a temporary folder)")
    args = parser.parse_args()
    registry = load_plugins(autoload=False).nodes  # the built-in node types
    registry.add(DriveUntilObstacle, provider="examples/write_a_leaf.py")  # now missions may name it
    with tempfile.TemporaryDirectory() as scratch:
        mission_file = Path(scratch) / "drive_until_obstacle.yaml"
        mission_file.write_text(MISSION, encoding="utf-8")
        spec = load_mission(mission_file, registry)  # checks DriveUntilObstacle's params like any node
        root = build_tree(spec, registry)
        robot = create_robot({"world": "office", "seed": 0})
        run_dir = args.out or Path(scratch) / "run"
        try:
            start = robot.pose()
            result = Runner(root, MissionContext(robot=robot, seed=0), tick_hz=spec.run.tick_hz or 10.0,
                            max_duration=spec.run.max_duration, blackboard=spec.blackboard,
                            run_dir=run_dir, mission="drive_until_obstacle").run()
            end = robot.pose()
        finally:
            robot.close()
        drive = root.children[0].children[0]
        print(f"drive: {drive.feedback_message}")
        if start is not None and end is not None:
            a, b = start.pose, end.pose
            print(f"robot moved from ({a.x:.2f}, {a.y:.2f}) to ({b.x:.2f}, {b.y:.2f})")
        print(f"mission: {result.status.name} after {result.ticks} ticks, {result.duration:.1f} s of "
              f"simulated time; run directory {run_dir}")
    return result.exit_code


if __name__ == "__main__":
    raise SystemExit(main())
