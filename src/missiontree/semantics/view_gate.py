"""Which camera frames the scene graph's detector looks at: new views, not every frame.

A camera that has not moved shows the detector the same picture again: the detections repeat,
the fusion's frame counts grow without new evidence, and the detector's cost (most of a mapping
mission's CPU) buys nothing. :class:`ViewGate` passes a frame when

- at least ``period`` seconds passed since the last frame it passed (a rate cap), and
- the camera moved at least ``move`` metres or turned at least ``turn`` degrees since then (a new
  view), or ``still_period`` seconds passed (a still robot still notices what changes in view).

``move`` and ``turn`` at 0 take every frame the period allows.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from missiontree.types import Pose2D

#: Slack on the period, so that frames stamped exactly one period apart pass.
EPS = 1e-6


@dataclass
class ViewGate:
    """Pass a frame when it is a new view (moved or turned enough) or enough time passed.

    Attributes:
        period: Least seconds between two frames passed (0: no cap).
        move: Metres the camera must move for a new view (0 with ``turn`` 0: no view rule).
        turn: Degrees the camera must turn for a new view.
        still_period: Most seconds between two frames passed while the camera stays still.
    """

    period: float = 0.0
    move: float = 0.0
    turn: float = 0.0
    still_period: float = 1.0
    last_stamp: float = -math.inf
    last_pose: Pose2D | None = None

    def due(self, stamp: float, pose: Pose2D) -> bool:
        """Whether the frame taken at ``stamp`` from camera ``pose`` should be looked at."""
        waited = stamp - self.last_stamp
        if waited < self.period - EPS:
            return False
        if self.last_pose is None or (self.move <= 0 and self.turn <= 0) or waited >= self.still_period - EPS:
            return True
        moved = math.hypot(pose.x - self.last_pose.x, pose.y - self.last_pose.y)
        turned = abs(math.remainder(pose.yaw - self.last_pose.yaw, math.tau))
        return (self.move > 0 and moved >= self.move) or (self.turn > 0 and turned >= math.radians(self.turn))

    def take(self, stamp: float, pose: Pose2D) -> None:
        """Note that the frame at ``stamp`` from ``pose`` was passed."""
        self.last_stamp = stamp
        self.last_pose = pose
