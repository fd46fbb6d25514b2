"""The Robot protocol: what behaviours may know of and do with a robot.

Shaped after ROS 2 and Nav2 so the ROS backend needs no adapters. Every getter returns
the *latest* value with its stamp (a sensor that went quiet shows as a stale stamp, never
as an exception); every command returns at once. Behaviours see the world only through
this interface and the models; simulator ground truth is never reachable from here.

Time: ``now()`` is the backend's clock. The runner calls ``spin_until(t)`` between ticks,
which lets the backend run up to time ``t``: the simulator steps its physics as fast as the
machine allows, the ROS 2 backend waits in wall time while its executor spins.
"""

from __future__ import annotations

from pathlib import Path
from typing import Protocol, runtime_checkable

from missiontree.robot.actions import ActionHandle
from missiontree.robot.sensors import SensorKind, SensorReading
from missiontree.types import LaserScan, Marker, OccupancyGrid, Pose2D, PoseStamped, RGBDFrame, Tolerance


@runtime_checkable
class Robot(Protocol):
    """A mobile robot with a 2D lidar, an RGB-D camera, a map and a navigation stack."""

    name: str
    #: True when time is simulated (tick logs then hold no wall-clock values).
    simulated: bool

    def now(self) -> float:
        """Current time on the backend's clock, in seconds."""
        ...

    def spin_until(self, t: float) -> None:
        """Let the backend run until its clock reaches ``t`` (returns at once if already past)."""
        ...

    def pose(self) -> PoseStamped | None:
        """Latest pose estimate in the map frame, None before localisation."""
        ...

    def scan(self) -> LaserScan | None:
        """Latest lidar scan, None before the first."""
        ...

    def rgbd(self) -> RGBDFrame | None:
        """Latest colour + depth frame, None before the first."""
        ...

    def occupancy(self) -> OccupancyGrid | None:
        """The map, None before one is known."""
        ...

    def pose_at(self, stamp: float) -> Pose2D | None:
        """Pose at ``stamp`` from the recent history (interpolated), None if outside it."""
        ...

    def scan_at(self, stamp: float) -> LaserScan | None:
        """The scan taken closest to ``stamp`` from the recent history, None if outside it."""
        ...

    def sensor(self, name: str) -> SensorReading | None:
        """Latest reading of a plugin sensor (``battery``...) with its stamp, None before the first.

        A sensor that went quiet keeps its old stamp. Raises
        :class:`~missiontree.robot.sensors.UnknownSensorError` (naming the robot's sensors) for a
        sensor no loaded plugin registered.
        """
        ...

    def sensor_names(self) -> list[str]:
        """Names of the plugin sensors this robot has."""
        ...

    def sensor_kind(self, name: str) -> SensorKind:
        """What sensor ``name`` is (value type, numeric fields, unit); unknown names raise."""
        ...

    def navigate_to(self, goal: Pose2D, tolerance: Tolerance | None = None) -> ActionHandle:
        """Send a navigation goal (NavigateToPose); a new goal preempts the previous one."""
        ...

    def drive(self, v: float, w: float) -> None:
        """Command body velocity (m/s, rad/s); overrides navigation while commanded."""
        ...

    def stop(self) -> None:
        """Cancel navigation and command zero velocity. Always works, idempotent."""
        ...

    def close(self) -> None:
        """Release resources (stop first). Idempotent."""
        ...


@runtime_checkable
class Drawable(Protocol):
    """A backend that can draw a picture of the run (the simulator's top-down PNG)."""

    def draw(self, out_dir: Path, markers: list[Marker]) -> list[Path]:
        """Write pictures of the run so far into ``out_dir``; return their paths."""
        ...
