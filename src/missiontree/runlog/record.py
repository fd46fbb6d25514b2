"""What a run writes for its viewer: ``runview.json`` beside ``ticks.jsonl``.

The tick log says what each node did; it does not say how the tree was declared, what the map
looks like or where the robot drove. These mission hooks (listed in
:data:`missiontree.plugins.builtin.MISSION_HOOK_MODULES`) add that, for any backend:

- at the start: the tree as the mission file declares it (names, types, parameters, sources) and
  the robot's map (``robot.occupancy()``: the simulator's world, map_server's map on ROS 2);
- at the end: the same with the map as it is then (a learned map has grown) and the robot's
  trajectory when the backend keeps one (the simulator does).

Nothing is written when the run has no directory. The file holds no wall-clock value, so the same
seed gives the same file.
"""

from __future__ import annotations

import base64
import json
import math
import os
from pathlib import Path
from typing import Any

import numpy as np

from missiontree.mapping.occupancy import BLOCKED_FROM
from missiontree.plugins.hookspecs import hookimpl
from missiontree.runlog.replay import POSES_FILE, RUNVIEW_FILE, declared_tree

#: map_server's trinary colours: free, occupied, unknown (grey levels of a .pgm).
FREE, OCCUPIED, UNKNOWN = 254, 0, 205


def encode_map(
    data: np.ndarray, resolution: float, origin: tuple[float, float], source: str
) -> dict[str, Any]:
    """A map as the viewer draws it: a PNG (top row = highest y) with its resolution and origin.

    Args:
        data: Occupancy values, row 0 at the lowest y: -1 unknown, 0 free … 100 occupied.
        resolution: Metres per cell.
        origin: Map coordinates of the corner of cell (0, 0).
        source: What the map is (shown in the viewer).
    """
    import cv2

    grid = np.asarray(data)
    image = np.full(grid.shape, UNKNOWN, dtype=np.uint8)
    image[(grid >= 0) & (grid < BLOCKED_FROM)] = FREE
    image[grid >= BLOCKED_FROM] = OCCUPIED
    ok, png = cv2.imencode(".png", np.flipud(image), [cv2.IMWRITE_PNG_COMPRESSION, 9])
    if not ok:  # pragma: no cover - cv2 encodes any uint8 image
        raise ValueError("could not encode the map as PNG")
    return {
        "png": base64.b64encode(png.tobytes()).decode("ascii"),
        "resolution": float(resolution),
        "origin": [round(float(origin[0]), 6), round(float(origin[1]), 6)],
        "width": int(grid.shape[1]),
        "height": int(grid.shape[0]),
        "source": source,
    }


def robot_map(robot: Any) -> dict[str, Any] | None:
    """The robot's current map, encoded, or None when it has none."""
    try:
        grid = robot.occupancy()
    except Exception:  # noqa: BLE001 - a backend without a map yet: the viewer draws none
        return None
    if grid is None or getattr(grid, "data", None) is None or np.asarray(grid.data).ndim != 2:
        return None
    source = "learned map" if getattr(robot, "unknown_map", False) else "the robot's map"
    return encode_map(grid.data, grid.resolution, (grid.origin.x, grid.origin.y), source)


def robot_trajectory(robot: Any) -> list[list[float]]:
    """The robot's path as [t, x, y] rows when the backend keeps one (the simulator), else []."""
    trajectory = getattr(robot, "trajectory", None)
    if not isinstance(trajectory, list):
        return []
    rows = []
    for item in trajectory:
        if isinstance(item, tuple | list) and len(item) >= 3:
            rows.append([round(float(item[0]), 3), round(float(item[1]), 3), round(float(item[2]), 3)])
    return rows


def write_runview(run_dir: Path, data: dict[str, Any]) -> Path:
    """Write ``runview.json`` atomically (a live viewer may read it at any moment)."""
    path = Path(run_dir) / RUNVIEW_FILE
    temporary = path.with_suffix(".json.tmp")
    temporary.write_text(json.dumps(data, sort_keys=True, separators=(",", ":")) + "\n", encoding="utf-8")
    os.replace(temporary, path)
    return path


def _base(context: Any, mission: Any) -> dict[str, Any]:
    data: dict[str, Any] = {"version": 1}
    if mission is not None and getattr(mission, "root", None) is not None:
        data["tree"] = declared_tree(mission)
        data["mission_file"] = str(getattr(mission, "path", ""))
        data["description"] = str(getattr(mission, "description", "") or "")
    found = robot_map(context.robot)
    if found is not None:
        data["map"] = found
    return data


@hookimpl
def missiontree_mission_started(context: Any, mission: Any) -> None:
    """Write the declared tree and the robot's map for the viewer."""
    run_dir = getattr(context, "run_dir", None)
    if run_dir is None:
        return
    data = _base(context, mission)
    context._runview = data  # kept for the finish: the spec is not handed to it
    write_runview(run_dir, data)


@hookimpl
def missiontree_mission_finished(context: Any, summary: dict[str, Any]) -> None:
    """Add the robot's trajectory and the map as it is at the end."""
    run_dir = getattr(context, "run_dir", None)
    if run_dir is None or not Path(run_dir).is_dir():
        return
    data = dict(getattr(context, "_runview", None) or {"version": 1})
    found = robot_map(context.robot)
    if found is not None:
        data["map"] = found
    poses = robot_trajectory(context.robot)
    if poses:
        data["poses"] = poses
    write_runview(run_dir, data)



class PoseTrail:
    """An ``on_tick`` callback that appends the robot's pose to ``poses.jsonl`` as the run goes.

    Used by ``run --view``, so the live viewer draws the path while the mission runs (the
    trajectory in ``runview.json`` only arrives at the end). One ``[t, x, y]`` line per
    ``period`` seconds of robot time, flushed at once; the file is replaced at the first tick.

    Args:
        run_dir: The run directory.
        period: Robot seconds between samples.
    """

    def __init__(self, run_dir: Path, period: float = 0.25) -> None:
        self.path = Path(run_dir) / POSES_FILE
        self.period = period
        self._next = -1.0
        self._stream: Any = None

    def __call__(self, session: Any) -> None:
        """Sample the pose when the period has passed (never raises: the viewer must not stop a run)."""
        try:
            stamped = session.robot.pose()
            if stamped is None or stamped.stamp < self._next:
                return
            if self._stream is None:
                self.path.parent.mkdir(parents=True, exist_ok=True)
                self._stream = self.path.open("w", encoding="utf-8")
            slot = math.floor(stamped.stamp / self.period + 1e-9) + 1  # samples on a grid of the period
            self._next = slot * self.period - 1e-9
            row = [round(stamped.stamp, 3), round(stamped.pose.x, 3), round(stamped.pose.y, 3)]
            self._stream.write(json.dumps(row) + "\n")
            self._stream.flush()
        except Exception:  # noqa: BLE001 - a pose that cannot be read is a gap in the drawn path
            return

    def close(self) -> None:
        """Close the file."""
        if self._stream is not None:
            self._stream.close()
            self._stream = None
