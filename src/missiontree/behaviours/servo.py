"""Visual servoing on an alarm (the patrol-robot thesis §5.3.1): turn to face the person, measure.

The patrol-robot thesis found that a person seen at the edge of the 70° camera lies outside its
±15° lidar cone and proposed a reflex: preempt the patrol goal and rotate the chassis to centre the target.
:class:`ServoToTarget` does that with a proportional controller on the bearing error, where the
bearing comes from the detector run on each new frame (the person nearest the expected bearing)
or, while the person is not in view, from the alarm's estimated map position. Once the person is
centred it stops, measures (by the chosen method, now straight ahead), records a ``servoed`` alarm
and succeeds; a target not seen for ``lost_timeout`` seconds ends it with FAILURE ("target lost").

In a tree it sits in front of the patrol in a reactive Selector, wrapped so that its end always
hands control back to the patrol::

    Selector (memory: false)
      ├── ForceFailure ─ ServoToTarget     RUNNING only while a new alarm is being served
      └── Parallel ─ Patrol, Surveillance  halted (goal cancelled, place kept) while servoing

With no new alarm on the blackboard it fails at once, so the Selector ticks the patrol.

The detector is a model call like any other: a new frame is submitted on one tick and its
detections are read on a later one (one frame in flight; the control step in between steers by
the last known bearing). A frame older than ``max_frame_age`` is not looked at.
"""

from __future__ import annotations

import math
from typing import Annotated

from pydantic import BaseModel, Field

from missiontree.behaviours.alarms import SERVOED, Alarm, record_alarm
from missiontree.behaviours.measure import Method, measure
from missiontree.behaviours.surveillance import alarm_from
from missiontree.engine.leaf import Leaf, Status
from missiontree.engine.ports import Input, Output
from missiontree.perception.detectors import detection_job
from missiontree.perception.lidar import box_bearings
from missiontree.reasoning.calls import CallStatus, ModelCall, model_caller
from missiontree.types import Detection, Pose2D, RGBDFrame, wrap_angle


class ServoToTarget(Leaf):
    """On a new alarm, turn to centre the person (P control on bearing), measure and record; else fail.

    Fails at once when the ``alarm`` port holds no alarm newer than the last one served, so it can
    guard a patrol in a Selector. Emits ``servo_started``, ``servo_done`` or ``servo_lost``.
    """

    class Params(BaseModel):
        gain: float = Field(1.5, gt=0, description="Angular speed per radian of bearing error (1/s).")
        max_speed: float = Field(1.2, gt=0, description="Largest angular speed (rad/s).")
        centred: float = Field(
            math.radians(4.0), gt=0, description="Bearing error that counts as centred (rad).")
        lost_timeout: float = Field(3.0, gt=0, description="Seconds unseen before giving up the target.")
        timeout: float = Field(15.0, gt=0, description="Longest servo, seconds.")
        method: Method = Field("cone", description="Distance method once centred: seed, cone or depth.")
        surface_offset: float = Field(0.1, ge=0, description="Added to measured ranges (m).")
        min_score: float = Field(0.4, ge=0, le=1, description="Detector score needed to track the person.")
        max_jump: float = Field(
            math.radians(25.0), gt=0, description="Largest bearing jump accepted between frames (rad).")
        ignore_radius: float = Field(
            1.5, ge=0, description="Skip an alarm this close (m) to a person served within ignore_for.")
        ignore_for: float = Field(20.0, ge=0, description="Seconds a served person is not served again.")
        max_frame_age: float = Field(
            1.0, gt=0, description="A frame older than this (s, robot clock) is not looked at.")
        detect_period: float = Field(
            0.0, ge=0, description="Seconds between the frames the detector looks at while servoing "
            "(0: every new frame).")
        alarm: Annotated[str, Input("the alarm to serve", type="dict")] = "alarm"
        result: Annotated[str, Output("the servoed alarm record", type="dict")] = "servo_result"

    params: Params

    def __init__(self, name: str, params: BaseModel | None = None) -> None:
        super().__init__(name, params)
        self.served_id = 0
        self.alarm: Alarm | None = None
        self.target: tuple[float, float] | None = None
        self.bearing_hint = 0.0
        self.started = 0.0
        self.last_seen = 0.0
        self.last_frame = float("-inf")
        self.seen_once = False
        self.active = False
        self.served: list[tuple[float, float, float]] = []  # (time, x, y) of people served
        self.detecting: tuple[ModelCall, RGBDFrame] | None = None
        self.detector_error = ""

    def on_setup(self) -> None:
        """Check that a detector is configured (it tracks the person while turning)."""
        if self.ctx is not None:
            self.ctx.model("detector")
            model_caller(self.ctx)  # binds simulation-only providers to the robot

    def initialise(self) -> None:
        """Take a new alarm, if there is one, and start turning towards it."""
        raw = self.read("alarm")
        self.active = False
        if not isinstance(raw, dict) or int(raw.get("id", 0)) <= self.served_id:
            return
        self.alarm = Alarm.from_dict(raw)
        self.served_id = self.alarm.id
        if self._recently_served(self.alarm):
            self.emit("servo_skipped", alarm=self.alarm.id, reason="person served moments ago")
            return
        self.active = True
        self.seen_once = False
        robot = self.context.robot
        self.started = self.last_seen = robot.now()
        pose = self._pose()
        # Keep the direction in the map frame (turning changes the robot's): where the camera saw the
        # person, else where the distance method put them.
        seen = self.alarm.extra.get("map_bearing")
        self.bearing_hint = float(seen) if seen is not None else wrap_angle(
            self.alarm.robot_pose[2] + self.alarm.bearing)
        self.target = self.alarm.position
        if self.target is not None:  # a position that disagrees with the camera (the thesis cone) is ignored
            at = self.alarm.pose
            gap = abs(wrap_angle(at.bearing_to(*self.target) + at.yaw - self.bearing_hint))
            self.target = self.target if gap <= self.params.max_jump else None
        self.emit("servo_started", alarm=self.alarm.id, bearing=round(self._expected_bearing(pose), 4))

    def update(self) -> Status:
        """One control step: find the person, turn towards them, finish when centred."""
        if not self.active or self.alarm is None:
            return self.fail("no new alarm")
        robot = self.context.robot
        now = robot.now()
        pose = self._pose()
        seen = self._collect(pose)
        frame = robot.rgbd()
        fresh = frame is not None and now - frame.stamp <= self.params.max_frame_age
        if (frame is not None and fresh and self.detecting is None
                and frame.stamp - self.last_frame >= max(self.params.detect_period - 1e-6, 1e-9)):
            self.last_frame = frame.stamp
            # it tracks people only: a banded mirror pass is worth running for a person candidate only
            job = detection_job(self.context.model("detector"), frame, band_labels=("person",))
            call = model_caller(self.context).submit(  # the role's timeout; only failures are logged
                "detector", job, node=self.name, log_success=False)
            self.detecting = (call, frame)
        if seen is not None:
            frame, person, bearing_then = seen
            self.last_seen = now
            self.seen_once = True
            frame_pose = robot.pose_at(frame.stamp) or pose
            self.bearing_hint = wrap_angle(frame_pose.yaw + bearing_then)
            error = wrap_angle(self.bearing_hint - pose.yaw)
            if abs(bearing_then) <= self.params.centred:
                return self._finish(frame, person)
        else:
            if now - self.last_seen > self.params.lost_timeout:
                why = f"; the detector failed: {self.detector_error}" if self.detector_error else ""
                return self._give_up(f"target lost: not seen for {self.params.lost_timeout:g} s{why}")
            error = self._expected_bearing(pose)
        if now - self.started > self.params.timeout:
            return self._give_up(f"not centred within {self.params.timeout:g} s")
        speed = max(-self.params.max_speed, min(self.params.max_speed, self.params.gain * error))
        robot.drive(0.0, speed)
        return self.running(f"turning to alarm {self.alarm.id}: {math.degrees(error):.1f}° off")

    def terminate(self, new_status: Status) -> None:
        """Stop turning (also when halted) and cancel the detection in flight."""
        if self.active and self.ctx is not None:
            self.ctx.robot.drive(0.0, 0.0)
        self.active = False
        if self.detecting is not None:
            self.detecting[0].cancel()
            self.detecting = None

    # -- helpers ---------------------------------------------------------------------------------

    def _recently_served(self, alarm: Alarm) -> bool:
        now = self.context.robot.now()
        self.served = [s for s in self.served if now - s[0] <= self.params.ignore_for]
        if alarm.position is None:
            return False
        return any(math.dist(alarm.position, (x, y)) <= self.params.ignore_radius for _, x, y in self.served)

    def _remember(self, position: tuple[float, float] | None) -> None:
        if position is not None:
            self.served.append((self.context.robot.now(), position[0], position[1]))

    def _pose(self) -> Pose2D:
        stamped = self.context.robot.pose()
        if stamped is None:
            raise RuntimeError(f"{self.name}: the robot has no pose; wait for localisation")
        return stamped.pose

    def _expected_bearing(self, pose: Pose2D) -> float:
        if self.target is not None:
            return pose.bearing_to(*self.target)
        return wrap_angle(self.bearing_hint - pose.yaw)

    def _collect(self, pose: Pose2D) -> tuple[RGBDFrame, Detection, float] | None:
        """The target in the frame whose detections just arrived, if they did and show it."""
        if self.detecting is None:
            return None
        call, frame = self.detecting
        status = call.status()
        if not status.done:
            return None
        self.detecting = None
        if status is not CallStatus.SUCCEEDED:
            self.detector_error = call.error() if status is not CallStatus.CANCELLED else ""
            return None
        self.detector_error = ""
        return self._find(frame, pose, call.result())

    def _find(self, frame: RGBDFrame, pose: Pose2D,
              detections: list[Detection]) -> tuple[RGBDFrame, Detection, float] | None:
        """The person in ``frame`` nearest the expected bearing, with their bearing at the frame's time."""
        frame_pose = self.context.robot.pose_at(frame.stamp) or pose
        expected = wrap_angle(self.bearing_hint - frame_pose.yaw)
        if self.target is not None and not self.seen_once:
            expected = frame_pose.bearing_to(*self.target)
        k = frame.intrinsics
        best: tuple[float, Detection, float] | None = None
        for det in detections:
            if det.label != "person" or det.score < self.params.min_score:
                continue
            bearing, _ = box_bearings(frame.camera_pose, frame_pose, det.box[0], det.box[2], k.fx, k.cx)
            jump = abs(wrap_angle(bearing - expected))
            if jump <= self.params.max_jump and (best is None or jump < best[0]):
                best = (jump, det, bearing)
        return None if best is None else (frame, best[1], best[2])

    def _finish(self, frame: RGBDFrame, person: Detection) -> Status:
        robot = self.context.robot
        robot.drive(0.0, 0.0)
        assert self.alarm is not None
        measurement = measure(robot, frame, person, self.params.method, fuse_at="frame",
                              surface_offset=self.params.surface_offset)
        record = alarm_from(self.alarm.id, frame, person, measurement, self.params.method, robot.now(),
                            self.alarm.verdict, phase=SERVOED,
                            detected_distance=None if not math.isfinite(self.alarm.distance)
                            else round(self.alarm.distance, 4))
        record = record_alarm(self.context, record, self.name, frame.color)
        self._remember(record.position or self.alarm.position)
        self.write("result", record.to_dict())
        self.emit("servo_done", alarm=self.alarm.id, distance=record.to_dict()["distance"],
                  seconds=round(robot.now() - self.started, 3))
        self.active = False
        return self.succeed(f"alarm {self.alarm.id}: person at {record.distance:.2f} m, centred")

    def _give_up(self, reason: str) -> Status:
        self.context.robot.drive(0.0, 0.0)
        assert self.alarm is not None
        self.emit("servo_lost", alarm=self.alarm.id, reason=reason)
        self._remember(self.alarm.position)
        self.active = False
        return self.fail(reason)
