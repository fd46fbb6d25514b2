"""Test doubles for the behaviour tests: a scripted robot, an event recorder, a detector and a VLM.

Fakes of the layers below the behaviours only (the simulator has its own tests); the behaviour
tests that need physics run on missiontree.backends.sim.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from typing import Any

import numpy as np

from missiontree.robot.actions import ActionResult, ActionStatus, NavFeedback
from missiontree.robot.history import StampedHistory
from missiontree.types import (
    CameraIntrinsics,
    Detection,
    LaserScan,
    Pose2D,
    PoseStamped,
    RGBDFrame,
    Tolerance,
)

K = CameraIntrinsics(width=320, height=240, fx=228.5, fy=228.5, cx=160.0, cy=120.0)


class Events:
    """An event sink that keeps every event."""

    def __init__(self) -> None:
        self.items: list[dict[str, Any]] = []

    def emit(self, event: str, **fields: Any) -> None:
        json.dumps(fields)  # events must be JSON-serialisable
        self.items.append({"event": event, **fields})

    def of(self, kind: str) -> list[dict[str, Any]]:
        return [e for e in self.items if e["event"] == kind]


class FakeHandle:
    """A navigation goal that ends after ``polls`` polls with ``outcome``."""

    def __init__(self, goal: Pose2D, tolerance: Tolerance | None, outcome: ActionStatus, reason: str,
                 polls: int) -> None:
        self.goal, self.tolerance = goal, tolerance
        self.outcome, self.reason, self.polls = outcome, reason, polls
        self.cancelled = False
        self._status = ActionStatus.ACCEPTED

    def status(self) -> ActionStatus:
        if self._status.done:
            return self._status
        self.polls -= 1
        self._status = self.outcome if self.polls <= 0 else ActionStatus.RUNNING
        return self._status

    def feedback(self) -> NavFeedback | None:
        return NavFeedback(Pose2D(0, 0), 1.0)

    def result(self) -> ActionResult | None:
        return ActionResult(self._status, self.reason) if self._status.done else None

    def cancel(self) -> None:
        self.cancelled = True
        if not self._status.done:
            self._status = ActionStatus.CANCELED


class FakeRobot:
    """A robot whose clock, pose, scans and frames the test sets; navigation outcomes are scripted.

    ``drive(v, w)`` turns the robot on ``advance(dt)``; ``unreachable`` goals abort with a reason.
    """

    name = "fake"
    simulated = True

    def __init__(self) -> None:
        self.time = 0.0
        self.current = Pose2D(0.0, 0.0, 0.0)
        self.poses: StampedHistory[Pose2D] = StampedHistory()
        self.scans: StampedHistory[LaserScan] = StampedHistory()
        self.frame: RGBDFrame | None = None
        self.goals: list[FakeHandle] = []
        self.unreachable: set[tuple[float, float]] = set()
        self.polls_per_goal = 3
        self.w = 0.0
        self.drives: list[tuple[float, float]] = []
        self.poses.push(0.0, self.current)

    def now(self) -> float:
        return self.time

    def spin_until(self, t: float) -> None:
        self.advance(t - self.time)

    def advance(self, dt: float) -> None:
        self.time += dt
        self.current = Pose2D(self.current.x, self.current.y, self.current.yaw + self.w * dt)
        self.poses.push(self.time, self.current)

    def set_pose(self, pose: Pose2D) -> None:
        self.current = pose
        self.poses.push(self.time, pose)

    def pose(self) -> PoseStamped | None:
        return PoseStamped(self.time, self.current)

    def scan(self) -> LaserScan | None:
        latest = self.scans.latest()
        return latest[1] if latest else None

    def rgbd(self) -> RGBDFrame | None:
        return self.frame

    def occupancy(self) -> None:
        return None

    def pose_at(self, stamp: float) -> Pose2D | None:
        return self.poses.nearest(stamp)

    def scan_at(self, stamp: float) -> LaserScan | None:
        return self.scans.nearest(stamp)

    def navigate_to(self, goal: Pose2D, tolerance: Tolerance | None = None) -> FakeHandle:
        if (goal.x, goal.y) in self.unreachable:
            handle = FakeHandle(goal, tolerance, ActionStatus.ABORTED, "goal inside an obstacle", 1)
        else:
            handle = FakeHandle(goal, tolerance, ActionStatus.SUCCEEDED, "", self.polls_per_goal)
        self.goals.append(handle)
        return handle

    def drive(self, v: float, w: float) -> None:
        self.w = w
        self.drives.append((v, w))

    def stop(self) -> None:
        self.w = 0.0

    def close(self) -> None:
        self.stop()


def wall_scan(stamp: float, wall: float = 5.0, person: tuple[float, float] | None = None,
              radius: float = 0.15, n: int = 720) -> LaserScan:
    """A TurtleBot-layout scan in a round room with an optional round person at (range, bearing)."""
    angles = -math.pi / 2 + 2 * math.pi / n * np.arange(n)
    ranges = np.full(n, wall)
    if person is not None:
        px, py = person[0] * math.cos(person[1]), person[0] * math.sin(person[1])
        along = np.cos(angles) * px + np.sin(angles) * py
        miss2 = px * px + py * py - along * along
        t = along - np.sqrt(np.clip(radius * radius - miss2, 0, None))
        ranges = np.where((along > 0) & (miss2 <= radius * radius), np.minimum(t, ranges), ranges)
    return LaserScan(stamp, -math.pi / 2, 2 * math.pi / n, 0.1, 12.0, ranges.astype(np.float32))


def person_frame(stamp: float, camera: Pose2D, bearing: float | None, depth: float = 1.0) -> RGBDFrame:
    """A frame with a person slab at ``bearing`` (camera frame) and ``depth``; None: nobody."""
    color = np.full((240, 320, 3), 90, np.uint8)
    depth_img = np.full((240, 320), 6.0, np.float32)
    if bearing is not None:
        u = K.cx - math.tan(bearing) * K.fx
        half = max(4, int(0.2 * K.fx / depth))
        x1, x2 = int(max(0, u - half)), int(min(320, u + half))
        depth_img[40:235, x1:x2] = depth * math.cos(bearing)
        color[40:235, x1:x2] = (200, 40, 40)
    return RGBDFrame(stamp, color, depth_img, K, camera)


class SlabDetector:
    """Finds the red person slab painted by :func:`person_frame` (a real search over the pixels)."""

    name = "slab"
    labels = ["person"]

    def __init__(self) -> None:
        self.calls = 0

    def detect(self, image: np.ndarray) -> list[Detection]:
        self.calls += 1
        red = (image[:, :, 0] > 150) & (image[:, :, 1] < 100)
        cols = np.flatnonzero(red.any(axis=0))
        rows = np.flatnonzero(red.any(axis=1))
        if cols.size == 0:
            return []
        return [Detection("person", 0.9, (float(cols[0]), float(rows[0]), float(cols[-1] + 1),
                                          float(rows[-1] + 1)))]


class ScriptedVLM:
    """Answers with ``answer(image)`` (JSON text of the verdict schema unless the test says otherwise)."""

    name = "scripted-vlm"

    def __init__(self, answer: Callable[[np.ndarray], str] | None = None) -> None:
        self.asked = 0
        self.answer = answer or self.by_detector

    def ask(self, images: Any, prompt: str, schema: Any = None) -> str:
        self.asked += 1
        return self.answer(images[0])

    def check(self) -> str:
        return "scripted"

    @staticmethod
    def by_detector(image: np.ndarray) -> str:
        people = SlabDetector().detect(image)
        if not people:
            return json.dumps({"verdict": "SAFE", "description": "an empty corridor"})
        return json.dumps({"verdict": "ALARM", "description": "a person walks by",
                           "people": [{"box": list(people[0].box), "score": 0.9}]})
