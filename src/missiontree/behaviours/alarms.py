"""Alarm records: what surveillance and servoing found, written where a security guard looks.

An :class:`Alarm` is raised by :class:`~missiontree.behaviours.surveillance.Surveillance` when a
frame is confirmed to show a person, and recorded again by
:class:`~missiontree.behaviours.servo.ServoToTarget` once the robot has turned to face the person
and measured them. :func:`record_alarm` puts each record in three places:

- the tick log, as an ``alarm`` event;
- ``<run_dir>/alarms.jsonl``, one JSON line per record (time, robot pose, bearing, distance,
  method, estimated position, image path);
- ``<run_dir>/alarms/<id>-<phase>.png``, the frame with the person's box drawn;

plus a marker on the run's top-down picture (``MissionContext.mark``). On the blackboard an
alarm travels as the plain dict of :meth:`Alarm.to_dict` (JSON-friendly for the tick log).
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from missiontree.engine.context import MissionContext
from missiontree.types import Pose2D

#: Phases of an alarm record.
DETECTED = "detected"
SERVOED = "servoed"


@dataclass(frozen=True)
class Alarm:
    """One sighting of a person worth raising.

    Attributes:
        id: Increasing number within the run.
        stamp: Time the frame was taken (the instant every measurement refers to).
        raised_at: Time the alarm was raised (the model's answer arrived).
        robot_pose: Robot pose (x, y, yaw) at ``stamp``.
        bearing: Bearing of the person at ``stamp``, robot frame, rad (positive left).
        distance: Estimated distance from the robot at ``stamp`` in metres (``inf`` if unknown).
        method: Distance method used: ``seed``, ``cone`` or ``depth``.
        position: Estimated map position (x, y) of the person, None when the distance is unknown.
        phase: ``detected`` (surveillance) or ``servoed`` (after turning to the person).
        box: The person's box in the frame, None when the model gave none.
        verdict: The model's one-sentence description.
        image: Path of the saved frame, relative to the run directory ("" when not saved).
    """

    id: int
    stamp: float
    raised_at: float
    robot_pose: tuple[float, float, float]
    bearing: float
    distance: float
    method: str
    position: tuple[float, float] | None
    phase: str = DETECTED
    box: tuple[float, float, float, float] | None = None
    verdict: str = ""
    image: str = ""
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def pose(self) -> Pose2D:
        """The robot pose at the frame's time."""
        return Pose2D(*self.robot_pose)

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-friendly form (infinite distance as None, numbers rounded to 0.1 mm)."""
        data = asdict(self)
        data["distance"] = _round(self.distance)
        data["bearing"] = _round(self.bearing)
        data["stamp"] = _round(self.stamp)
        data["raised_at"] = _round(self.raised_at)
        data["robot_pose"] = [_round(v) for v in self.robot_pose]
        data["position"] = None if self.position is None else [_round(v) for v in self.position]
        data["box"] = None if self.box is None else [_round(v) for v in self.box]
        return data

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Alarm:
        """Rebuild an alarm from :meth:`to_dict` output (as read from the blackboard)."""
        values = dict(data)
        values["distance"] = math.inf if values.get("distance") is None else float(values["distance"])
        values["robot_pose"] = tuple(values["robot_pose"])
        values["position"] = None if values.get("position") is None else tuple(values["position"])
        values["box"] = None if values.get("box") is None else tuple(values["box"])
        return cls(**values)


def _round(value: float) -> float | None:
    return round(float(value), 4) if math.isfinite(value) else None


def record_alarm(context: MissionContext, alarm: Alarm, node: str, image: np.ndarray | None = None) -> Alarm:
    """Write ``alarm`` to the tick log, ``alarms.jsonl`` and (with ``image``) ``alarms/``; mark it.

    Args:
        context: The mission context (events, run directory, markers).
        alarm: The record.
        node: Name of the recording node (tagged on the event).
        image: The frame's RGB image, saved with the box drawn when the run has a directory.

    Returns:
        The alarm as recorded (with the image path filled in when one was saved).
    """
    run_dir = context.run_dir
    if run_dir is not None and image is not None:
        folder = Path(run_dir) / "alarms"
        if context.starts(folder):  # frames an earlier run left in this directory are not this run's
            for stale in folder.glob("[0-9][0-9][0-9][0-9]-*.png"):
                stale.unlink()
        alarm = _with_image(alarm, _save_frame(Path(run_dir), alarm, image))
    record = alarm.to_dict()
    context.events.emit("alarm", node=node, **record)
    if run_dir is not None:
        path = Path(run_dir) / "alarms.jsonl"
        path.parent.mkdir(parents=True, exist_ok=True)
        with path.open("w" if context.starts(path) else "a", encoding="utf-8") as handle:
            handle.write(json.dumps(record, sort_keys=True) + "\n")
    if alarm.position is not None and all(math.isfinite(v) for v in alarm.position):
        context.mark("alarm", alarm.position[0], alarm.position[1], f"alarm {alarm.id} ({alarm.phase})")
    return alarm


def _with_image(alarm: Alarm, relative: str) -> Alarm:
    values = dict(alarm.__dict__)
    values["image"] = relative
    return Alarm(**values)


def _save_frame(run_dir: Path, alarm: Alarm, image: np.ndarray) -> str:
    folder = run_dir / "alarms"
    folder.mkdir(parents=True, exist_ok=True)
    picture = cv2.cvtColor(np.ascontiguousarray(image), cv2.COLOR_RGB2BGR)
    if alarm.box is not None and all(math.isfinite(v) for v in alarm.box):
        x1, y1, x2, y2 = (int(round(v)) for v in alarm.box)
        cv2.rectangle(picture, (x1, y1), (x2, y2), (0, 0, 255), 2)
        label = "person" if not math.isfinite(alarm.distance) else f"person {alarm.distance:.2f} m"
        cv2.putText(picture, label, (x1, max(10, y1 - 4)), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (0, 0, 255), 1)
    name = f"{alarm.id:04d}-{alarm.phase}.png"
    cv2.imwrite(str(folder / name), picture)
    return f"alarms/{name}"
