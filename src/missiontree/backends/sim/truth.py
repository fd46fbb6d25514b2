"""Ground truth of a simulated run: what really is where, and who was visible in which frame.

For scoring, benchmarks and declared simulation oracles only. It is reachable as
``SimRobot.truth`` — deliberately *not* through the :class:`~missiontree.robot.interface.Robot`
protocol — so a behaviour written against the protocol cannot see it, and a behaviour that
reached for it would break on ROS 2. Behaviours must never import or use this module.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from missiontree.backends.sim.world import InstanceInfo, Room, World, WorldObject
from missiontree.robot.history import StampedHistory
from missiontree.types import Pose2D


@dataclass(frozen=True)
class Sighting:
    """An instance seen in one camera frame."""

    name: str
    kind: str
    label: str
    pixels: int


class GroundTruth:
    """Read-only access to the simulator's state for evaluation."""

    def __init__(self, world: World, true_pose: Callable[[], Pose2D], horizon: float,
                 flush: Callable[[], None] = lambda: None) -> None:
        self.world = world
        self._true_pose = true_pose
        self._flush = flush  # publishes a camera frame still being rendered
        self._poses: StampedHistory[Pose2D] = StampedHistory(horizon=max(horizon, 60.0), maxlen=100_000)
        self._masks: StampedHistory[np.ndarray] = StampedHistory(horizon=horizon, maxlen=1000)
        self._visibility: list[tuple[float, dict[str, Sighting]]] = []

    # -- recording (called by the simulator) -------------------------------------------------------

    def record_pose(self, stamp: float, pose: Pose2D) -> None:
        """Remember the true pose at ``stamp``."""
        self._poses.push(stamp, pose)

    def record_frame(self, stamp: float, instances: np.ndarray, counts: np.ndarray | None = None) -> None:
        """Remember a frame's instance mask and who it shows (``counts``: pixels per instance id)."""
        self._masks.push(stamp, instances)
        if counts is None:
            counts = np.bincount(instances.ravel(), minlength=len(self.world.instances))
        seen = {}
        for inst in np.flatnonzero(counts).tolist():
            info = self.world.instances.get(inst)
            if info is not None and info.kind in ("object", "person"):
                seen[info.name] = Sighting(info.name, info.kind, info.label, int(counts[inst]))
        self._visibility.append((stamp, seen))

    # -- queries -----------------------------------------------------------------------------------

    @property
    def visibility(self) -> list[tuple[float, dict[str, Sighting]]]:
        """Every frame's sightings for the whole run: (stamp, {name: Sighting})."""
        self._flush()
        return self._visibility

    def robot_pose(self) -> Pose2D:
        """The robot's true pose now (the robot itself only knows its estimate)."""
        return self._true_pose()

    def robot_pose_at(self, stamp: float) -> Pose2D | None:
        """The true pose nearest ``stamp`` within the recent history."""
        return self._poses.nearest(stamp, max_gap=0.2)

    @property
    def objects(self) -> list[WorldObject]:
        """Every object with its true pose."""
        return list(self.world.objects)

    def object(self, object_id: str) -> WorldObject:
        """One object by id."""
        return self.world.object(object_id)

    def people_at(self, stamp: float) -> list[tuple[str, float, float]]:
        """(id, x, y) of every person present at ``stamp`` (any time, past or future)."""
        return self.world.crowd.positions(stamp)

    def room_at(self, x: float, y: float) -> Room | None:
        """The room holding a point."""
        return self.world.room_at(x, y)

    @property
    def instances(self) -> dict[int, InstanceInfo]:
        """What each instance id in a mask stands for."""
        return dict(self.world.instances)

    def instance_mask(self, stamp: float) -> np.ndarray | None:
        """The instance mask of the frame taken at ``stamp`` (nearest within 1 ms), if still kept."""
        self._flush()
        return self._masks.nearest(stamp, max_gap=1e-3)

    def visible_at(self, stamp: float, min_pixels: int = 1) -> dict[str, Sighting]:
        """Objects and people visible in the frame taken at ``stamp``, with their pixel counts."""
        self._flush()
        for frame_stamp, seen in reversed(self._visibility):
            if abs(frame_stamp - stamp) <= 1e-3:
                return {k: v for k, v in seen.items() if v.pixels >= min_pixels}
            if frame_stamp < stamp - 1e-3:
                break
        return {}
