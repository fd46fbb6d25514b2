"""A small planar transform buffer over /tf and /tf_static (tf2_ros is not on PyPI).

Keeps, for every child frame, its parent and a short history of planar transforms; looks up
the pose of one frame in another at a time (interpolated) or at the latest common time, the way
tf2 does for a tree such as ``map → odom → base_link → rplidar_link``. Pure Python, no rclpy:
the robot feeds it with :func:`conversions.transform_from_msg` tuples.
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass, field

from missiontree.robot.history import StampedHistory
from missiontree.types import Pose2D

#: Longest chain followed before a loop in the frame tree is assumed.
_MAX_DEPTH = 32


def interpolate(a: Pose2D, b: Pose2D, f: float) -> Pose2D:
    """The pose a fraction ``f`` of the way from ``a`` to ``b`` (heading along the shorter arc)."""
    dyaw = math.atan2(math.sin(b.yaw - a.yaw), math.cos(b.yaw - a.yaw))
    yaw = a.yaw + f * dyaw
    return Pose2D(a.x + f * (b.x - a.x), a.y + f * (b.y - a.y), math.atan2(math.sin(yaw), math.cos(yaw)))


def compose(a: Pose2D, b: Pose2D) -> Pose2D:
    """The pose ``b`` (given in frame ``a``) expressed in ``a``'s parent frame."""
    x, y = a.transform(b.x, b.y)
    yaw = a.yaw + b.yaw
    return Pose2D(x, y, math.atan2(math.sin(yaw), math.cos(yaw)))


def invert(a: Pose2D) -> Pose2D:
    """The inverse transform: the parent frame's pose seen from ``a``."""
    c, s = math.cos(a.yaw), math.sin(a.yaw)
    return Pose2D(-c * a.x - s * a.y, s * a.x - c * a.y, -a.yaw)


def history_at(history: StampedHistory[Pose2D], stamp: float) -> Pose2D | None:
    """The pose of ``history`` at ``stamp``, interpolated between the entries around it."""
    around = history.bracket(stamp)
    if around is None:
        return None
    (t0, p0), (t1, p1) = around
    return p0 if t1 <= t0 else interpolate(p0, p1, (stamp - t0) / (t1 - t0))


@dataclass
class _Edge:
    parent: str
    static: bool
    history: StampedHistory[Pose2D] = field(default_factory=StampedHistory)


class TransformBuffer:
    """Planar transforms between named frames, fed from /tf and /tf_static.

    Args:
        horizon: Seconds of dynamic transforms kept per frame.
    """

    def __init__(self, horizon: float = 10.0) -> None:
        self.horizon = horizon
        self._edges: dict[str, _Edge] = {}
        self._lock = threading.Lock()

    def set_transform(
        self, parent: str, child: str, stamp: float, pose: Pose2D, static: bool = False
    ) -> None:
        """Record that ``child`` is at ``pose`` in ``parent`` at ``stamp`` (static: at all times)."""
        with self._lock:
            edge = self._edges.get(child)
            if edge is None or edge.parent != parent or edge.static != static:
                edge = _Edge(parent, static, StampedHistory(horizon=self.horizon))
                self._edges[child] = edge
            if static:
                edge.history = StampedHistory(horizon=math.inf, maxlen=1)
                edge.history.push(stamp, pose)
            elif (latest := edge.history.latest()) is None or stamp >= latest[0]:
                edge.history.push(stamp, pose)

    def frames(self) -> set[str]:
        """Every frame named so far, parents and children."""
        with self._lock:
            return set(self._edges) | {e.parent for e in self._edges.values()}

    def _chain(self, frame: str) -> list[str]:
        """``frame`` and its ancestors up to the root of its tree."""
        chain = [frame]
        while chain[-1] in self._edges and len(chain) < _MAX_DEPTH:
            chain.append(self._edges[chain[-1]].parent)
        return chain

    def lookup(self, target: str, source: str, stamp: float | None = None) -> tuple[float, Pose2D] | None:
        """The pose of frame ``source`` in frame ``target``.

        Args:
            target: Frame to express the pose in (e.g. ``map``).
            source: Frame whose pose is wanted (e.g. ``base_link``).
            stamp: Time to look up at (interpolated); None for the latest time every dynamic
                transform on the path is known at (tf2's "time 0").

        Returns:
            (stamp, pose), or None when the frames are not connected or ``stamp`` lies outside
            a transform's history.
        """
        with self._lock:
            up_source, up_target = self._chain(source), self._chain(target)
            common = next((f for f in up_source if f in up_target), None)
            if common is None:
                return None
            path_source = up_source[: up_source.index(common)]
            path_target = up_target[: up_target.index(common)]
            edges = [self._edges[f] for f in path_source + path_target]
            dynamic = [last[0] for e in edges if not e.static and (last := e.history.latest())]
            if stamp is None:
                stamp = min(dynamic) if dynamic else 0.0
            source_in_common = self._pose_along(path_source, stamp)
            target_in_common = self._pose_along(path_target, stamp)
        if source_in_common is None or target_in_common is None:
            return None
        return stamp, compose(invert(target_in_common), source_in_common)

    def _pose_along(self, path: list[str], stamp: float) -> Pose2D | None:
        """The pose of ``path[0]`` in the parent of ``path[-1]`` at ``stamp`` (identity for [])."""
        pose = Pose2D(0.0, 0.0, 0.0)
        for frame in path:
            edge = self._edges[frame]
            if edge.static:
                latest = edge.history.latest()
                step = latest[1] if latest else None
            else:
                step = history_at(edge.history, stamp)
            if step is None:
                return None
            pose = compose(step, pose)
        return pose
