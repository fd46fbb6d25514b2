"""Ground truth of a simulated run: what really is where, and who was visible in which frame.

For scoring, benchmarks and declared simulation oracles only. It is reachable as
``SimRobot.truth`` — deliberately *not* through the :class:`~missiontree.robot.interface.Robot`
protocol — so a behaviour written against the protocol cannot see it, and a behaviour that
reached for it would break on ROS 2. Behaviours must never import or use this module.
"""

from __future__ import annotations

import bisect
from array import array
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from typing import overload

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


class VisibilityLog(Sequence[tuple[float, dict[str, Sighting]]]):
    """Every frame's sightings, stored compactly (12 bytes a sighting, 16 a frame).

    Reads as a sequence of ``(stamp, {name: Sighting})``, built on access, so a whole run's log
    costs a few MB even over hours (a list of dicts cost about 17 MiB an hour).
    """

    def __init__(self, instances: dict[int, InstanceInfo]) -> None:
        self._instances = instances
        self._stamps = array("d")
        self._starts = array("q", [0])
        self._ids = array("i")
        self._pixels = array("i")

    def append(self, stamp: float, ids: Sequence[int], pixels: Sequence[int]) -> None:
        """Add a frame: the instance ids it shows and their pixel counts."""
        self._stamps.append(stamp)
        self._ids.extend(ids)
        self._pixels.extend(pixels)
        self._starts.append(len(self._ids))

    def __len__(self) -> int:
        return len(self._stamps)

    @overload
    def __getitem__(self, index: int) -> tuple[float, dict[str, Sighting]]: ...

    @overload
    def __getitem__(self, index: slice) -> list[tuple[float, dict[str, Sighting]]]: ...

    def __getitem__(self, index: int | slice) -> tuple[float, dict[str, Sighting]] | list[
            tuple[float, dict[str, Sighting]]]:
        if isinstance(index, slice):
            return [self[i] for i in range(*index.indices(len(self)))]
        if index < 0:
            index += len(self)
        if not 0 <= index < len(self):
            raise IndexError("visibility index out of range")
        seen = {}
        for j in range(self._starts[index], self._starts[index + 1]):
            info = self._instances[self._ids[j]]
            seen[info.name] = Sighting(info.name, info.kind, info.label, self._pixels[j])
        return self._stamps[index], seen

    def __iter__(self) -> Iterator[tuple[float, dict[str, Sighting]]]:
        for i in range(len(self)):
            yield self[i]

    def __reversed__(self) -> Iterator[tuple[float, dict[str, Sighting]]]:
        for i in range(len(self) - 1, -1, -1):
            yield self[i]

    @property
    def nbytes(self) -> int:
        """Bytes held by the log's arrays."""
        return sum(a.itemsize * len(a) for a in (self._stamps, self._starts, self._ids, self._pixels))


class MaskRing:
    """The instance masks of the last ``horizon`` seconds of frames, in one buffer allocated once.

    A long run renders five frames a second and the ground truth keeps each frame's mask for the
    horizon (10 s: about 50 masks of 150 KB). Kept as separate arrays, each mask is a heap block
    living for the horizon among the run's short-lived buffers. Here the masks are copied into the
    slots of one array (``(capacity, height, width)``), so their memory is fixed; on its own this
    made no difference to the soak's RSS growth measurable against its noise (that growth was
    failed model calls' frames held in reference cycles, see :mod:`missiontree.reasoning.calls`).
    The array grows (by a quarter, plus a few slots) only while more frames fall inside the
    horizon than it holds, so a run of constant frame rate allocates it a few times in its first
    seconds and then never again. :meth:`nearest` returns a copy: a slot is reused once it leaves the horizon.

    Args:
        horizon: Seconds of frames kept (a frame older than the newest minus this is dropped).
        dtype: The kept masks' type (the recorded masks are cast to it).
        max_frames: The most frames kept whatever the horizon.
    """

    def __init__(self, horizon: float, dtype: np.dtype | type = np.int32, max_frames: int = 1000) -> None:
        self.horizon = horizon
        self.dtype = np.dtype(dtype)
        self.max_frames = max_frames
        self._buffer: np.ndarray | None = None
        self._stamps: list[float] = []  # oldest first; _stamps[i] is in slot (_first + i) % capacity
        self._first = 0

    @property
    def capacity(self) -> int:
        """Slots in the buffer (0 before the first frame)."""
        return 0 if self._buffer is None else len(self._buffer)

    @property
    def nbytes(self) -> int:
        """Bytes of the buffer."""
        return 0 if self._buffer is None else int(self._buffer.nbytes)

    def __len__(self) -> int:
        return len(self._stamps)

    def push(self, stamp: float, mask: np.ndarray) -> None:
        """Keep ``mask`` (cast to the ring's type) as the frame at ``stamp`` (stamps non-decreasing)."""
        if self._buffer is None or self._buffer.shape[1:] != mask.shape:
            self._buffer = np.empty((4, *mask.shape), dtype=self.dtype)
            self._stamps, self._first = [], 0
        cutoff = stamp - self.horizon
        drop = 0
        while drop < len(self._stamps) and self._stamps[drop] < cutoff:
            drop += 1
        if drop:
            del self._stamps[:drop]
            self._first = (self._first + drop) % len(self._buffer)
        if len(self._stamps) >= self.max_frames:
            del self._stamps[0]
            self._first = (self._first + 1) % len(self._buffer)
        if len(self._stamps) == len(self._buffer):
            self._grow(min(self.max_frames, len(self._buffer) + len(self._buffer) // 4 + 4))
        slot = (self._first + len(self._stamps)) % len(self._buffer)
        np.copyto(self._buffer[slot], mask, casting="unsafe")
        self._stamps.append(stamp)

    def _grow(self, capacity: int) -> None:
        assert self._buffer is not None
        old, n = self._buffer, len(self._stamps)
        order = [(self._first + i) % len(old) for i in range(n)]
        self._buffer = np.empty((capacity, *old.shape[1:]), dtype=self.dtype)
        self._buffer[:n] = old[order]
        self._first = 0

    def nearest(self, stamp: float, max_gap: float = float("inf")) -> np.ndarray | None:
        """A copy of the mask whose stamp is nearest ``stamp`` if within ``max_gap``, else None."""
        if self._buffer is None or not self._stamps:
            return None
        i = bisect.bisect_left(self._stamps, stamp)
        best, best_gap = -1, max_gap
        for j in (i - 1, i):
            if 0 <= j < len(self._stamps) and abs(self._stamps[j] - stamp) <= best_gap:
                best, best_gap = j, abs(self._stamps[j] - stamp)
        if best < 0:
            return None
        return self._buffer[(self._first + best) % len(self._buffer)].copy()


class GroundTruth:
    """Read-only access to the simulator's state for evaluation."""

    def __init__(self, world: World, true_pose: Callable[[], Pose2D], horizon: float,
                 flush: Callable[[], None] = lambda: None) -> None:
        self.world = world
        self._true_pose = true_pose
        self._flush = flush  # publishes a camera frame still being rendered
        self._poses: StampedHistory[Pose2D] = StampedHistory(horizon=max(horizon, 60.0), maxlen=100_000)
        # The kept masks are the simulator's largest buffer on long runs (a horizon of frames): with
        # fewer than 65,536 instance ids they are kept as uint16, half the memory of the camera's int32,
        # in one ring buffer of fixed memory (MaskRing).
        small = max(world.instances, default=0) <= np.iinfo(np.uint16).max
        self._masks = MaskRing(horizon, np.uint16 if small else np.int32)
        self._visibility = VisibilityLog(world.instances)

    # -- recording (called by the simulator) -------------------------------------------------------

    def record_pose(self, stamp: float, pose: Pose2D) -> None:
        """Remember the true pose at ``stamp``."""
        self._poses.push(stamp, pose)

    def record_frame(self, stamp: float, instances: np.ndarray, counts: np.ndarray | None = None) -> None:
        """Remember a frame's instance mask and who it shows (``counts``: pixels per instance id)."""
        self._masks.push(stamp, instances)
        if counts is None:
            counts = np.bincount(instances.ravel(), minlength=len(self.world.instances))
        ids, pixels = [], []
        for inst in np.flatnonzero(counts).tolist():
            info = self.world.instances.get(inst)
            if info is not None and info.kind in ("object", "person", "robot"):
                ids.append(inst)
                pixels.append(int(counts[inst]))
        self._visibility.append(stamp, ids, pixels)

    # -- queries -----------------------------------------------------------------------------------

    @property
    def visibility(self) -> VisibilityLog:
        """Every frame's sightings for the whole run: a sequence of (stamp, {name: Sighting})."""
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
        """Objects, people and other robots visible in the frame taken at ``stamp``, with pixel counts."""
        self._flush()
        for frame_stamp, seen in reversed(self._visibility):
            if abs(frame_stamp - stamp) <= 1e-3:
                return {k: v for k, v in seen.items() if v.pixels >= min_pixels}
            if frame_stamp < stamp - 1e-3:
                break
        return {}
