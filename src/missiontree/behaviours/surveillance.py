"""Surveillance while moving: look for people in the camera frames and raise alarms with positions.

Runs beside the patrol (a Parallel) and never finishes by itself. Two modes:

- ``poll`` — the patrol-robot thesis: every ``period`` seconds (0.5 s, or 0.2 s in scenario D) the
  latest frame goes to the vision-language model with the ALARM/SAFE prompt. People who cross the view between
  two checks, or while answers are slow, are missed.
- ``detect`` — a cheap detector looks at *every* frame; a frame showing a person not seen before
  (light tracks by map position and clothing colour, :mod:`missiontree.behaviours.tracks`; a
  detection counts only where the lidar also sees legs at the measured range, which drops boxes on
  walls; ``min_hits`` frames may be asked for as well)
  goes to the VLM, which
  confirms; calls stay within a budget of one per ``period`` on average (short bursts of two, so
  two newcomers are both asked at once) and ``max_in_flight`` at once. Each person costs one call.

Model calls never block the tick: they are submitted through the mission's
:class:`~missiontree.reasoning.calls.ModelCaller` and polled — the VLM's and the detector's alike
(a frame's detections are read on a later tick than the one that submitted it; one detection is in
flight at a time, newer frames wait). Detector boxes are checked where they enter
(:func:`~missiontree.perception.detectors.detection_job`): non-finite boxes are dropped, boxes are
clipped to the image.

**Which person an alarm is about.** A frame may show several people, some of them false detections
(a white pillar at the frame's edge). When the VLM answers ALARM with people's boxes, only the
detector's people whose boxes overlap one of them are confirmed; the others are marked safe. The
alarms go out best-confirmed first (the VLM's score, then the detector's), so an alarm cooldown
never lets a doubtful box take the place of the person the model saw. A VLM box over none of
the people sent is about someone else: over a person seen before it raises nothing (they had
their alarm), over nobody the detector saw it is a person the detector missed, and the alarm
takes the VLM's box. When the VLM gives no boxes, every person sent is confirmed, highest
detector score first.

**Faults are not quiet.** A frame older than ``max_frame_age`` is never looked at (a camera that
went quiet shows a stale stamp); with no fresh frame for ``camera_timeout`` seconds the leaf fails
saying so. ``max_failed_calls`` model calls failing in a row (malformed answers, timeouts, a dead
server) fail it too, with the last error: a patrol whose every check failed did not watch.

The answer is read through the :class:`~missiontree.reasoning.schemas.SurveillanceVerdict` schema
(checked, retried once), never by searching its text. The person's bearing, distance and map
position come from the sensor data of the instant the frame was taken (``fuse_at: frame``), by the
chosen ``method`` (seed | cone | depth, :mod:`missiontree.behaviours.measure`); ``fuse_at: answer``
reproduces the patrol-robot thesis, which read the latest scan once the answer came back.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import BaseModel, Field

from missiontree.behaviours.alarms import Alarm, record_alarm
from missiontree.behaviours.measure import FuseAt, Measurement, Method, measure
from missiontree.behaviours.tracks import CallBudget, PersonTracks, Track, TrackState
from missiontree.engine.leaf import Leaf, Status
from missiontree.engine.ports import Output
from missiontree.perception.depth import centre_region
from missiontree.perception.detectors import checked_detections, detection_job, iou_matrix, share_frame
from missiontree.perception.lidar import legs_at
from missiontree.reasoning.calls import CallStatus, ModelCall, model_caller
from missiontree.reasoning.checks import ask_checked
from missiontree.reasoning.prompts import surveillance_prompt
from missiontree.reasoning.schemas import SurveillanceVerdict
from missiontree.types import Detection, RGBDFrame, wrap_angle

#: Overlap (IoU) above which a detector's box is the person a VLM box shows.
CONFIRM_IOU = 0.3


@dataclass
class _Sighting:
    """One person in a frame: their box, what was measured at the frame's instant, their track."""

    detection: Detection | None
    measurement: Measurement | None
    track: Track | None = None


@dataclass
class _Pending:
    """A frame sent to the VLM, with the people it was sent for."""

    call: ModelCall
    frame: RGBDFrame
    sightings: list[_Sighting]
    known: tuple[Detection, ...] = ()  # the frame's other people, seen before (not asked about)


class Surveillance(Leaf):
    """Watch the camera for people (poll a VLM, or detect on every frame and confirm); raise alarms.

    Writes each alarm (a dict, see :class:`~missiontree.behaviours.alarms.Alarm`) to its ``alarm``
    port and records it (tick-log ``alarm`` event, ``alarms.jsonl``, the frame under ``alarms/``).
    Always RUNNING; halting it cancels the calls in flight.
    """

    class Params(BaseModel):
        mode: Literal["poll", "detect"] = Field(
            "detect", description="poll: send a frame every period (the patrol-robot thesis); detect: "
            "detector on every frame, VLM confirms.")
        period: float = Field(
            0.5, gt=0, description="Seconds between VLM calls (poll); seconds per call on average (detect).")
        max_in_flight: int = Field(1, ge=1, description="Most VLM calls waiting for an answer at once.")
        confirm: bool = Field(True, description="detect mode: the VLM confirms (false: detector decides).")
        method: Method = Field("depth", description="Distance method: seed (the patrol-robot thesis's front "
                                      "cone), cone or depth.")
        fuse_at: FuseAt = Field(
            "frame", description="Sensor data of the frame's instant (frame) or the answer's (the "
            "patrol-robot thesis).")
        min_score: float = Field(0.5, ge=0, le=1, description="Detector score needed to count a person.")
        label: str = Field("person", description="Detector label that counts as a person.")
        mirror: bool | None = Field(
            False, description="detect mode: also run the detector's mirror pass (null: as its models "
            "config says). Off: for people it costs 40 % of the patrol's CPU and adds no precision.")
        surface_offset: float = Field(
            0.1, ge=0, description="Added to measured ranges: sensors see a person's near surface (m).")
        forget_after: float = Field(
            1.0, gt=0, description="detect mode: seconds out of view before a person counts as new.")
        lidar_check: bool = Field(
            True, description="detect mode: count a detection only where the lidar sees legs at its range.")
        detect_period: float = Field(
            0.4, ge=0, description="detect mode: least seconds between two frames the detector looks at "
            "(0: every new frame). 0.4: every other frame of a 5 Hz camera; a person crossing the view "
            "at walking pace is in it for several of them.")
        min_hits: int = Field(
            1, ge=1, description="detect mode: frames a person must be detected in before the VLM is asked.")
        recheck: float = Field(3.0, gt=0, description="detect mode: seconds before asking again if SAFE.")
        alarm_cooldown: float = Field(
            0.0, ge=0, description="Seconds after an alarm with no new alarm (0: every sighting).")
        timeout: float = Field(10.0, gt=0, description="Seconds to wait for a VLM answer.")
        max_frame_age: float = Field(
            1.0, gt=0, description="A frame older than this (s, robot clock) is never looked at.")
        camera_timeout: float = Field(
            10.0, gt=0, description="Fail when no frame younger than max_frame_age came for this long (s).")
        max_failed_calls: int = Field(
            10, ge=0, description="Fail after this many calls of one model role failed in a row (0: never).")
        prompt: str | None = Field(
            None, description="Question for the VLM; default: the patrol-robot thesis's prompt.")
        alarm: Annotated[str, Output("the last alarm raised", type="dict")] = "alarm"

    params: Params

    def __init__(self, name: str, params: BaseModel | None = None) -> None:
        super().__init__(name, params)
        self.pending: list[_Pending] = []
        self.last_frame_stamp = float("-inf")
        self.last_submit = float("-inf")
        self.last_alarm_time = float("-inf")
        self.alarm_count = 0
        self.checks = 0
        self.sightings = 0
        self.rejected = 0
        self.tracks = PersonTracks(forget_after=self.params.forget_after)
        self.budget = CallBudget(1.0 / self.params.period)
        self.detecting: tuple[ModelCall, RGBDFrame] | None = None
        self.last_fresh = 0.0
        self.last_seen_stamp = float("-inf")  # the newest frame's stamp read so far
        self.failed_in_row: dict[str, int] = {}  # per role: a working detector does not hide a broken VLM
        self.last_error = ""
        self.stale_frames = 0

    def on_setup(self) -> None:
        """Check that the models this mode needs are configured."""
        if self.ctx is None:
            return
        if self.params.mode == "detect":
            self.ctx.model("detector")
        if self.params.mode == "poll" or self.params.confirm:
            self.ctx.model("vlm")
        model_caller(self.ctx)  # the mission's caller; it also binds simulation-only providers to the robot

    # -- lifecycle -------------------------------------------------------------------------------

    def initialise(self) -> None:
        """Start the camera's staleness clock (again after a halt: servoing, for example)."""
        self.last_fresh = self.context.robot.now()

    def update(self) -> Status:
        """Collect answers and detections that arrived, then look at the newest frame."""
        for pending in list(self.pending):
            if self._settle(pending):
                self.pending.remove(pending)
        self._collect_detections()
        limit = self.params.max_failed_calls
        worst = max(self.failed_in_row.items(), key=lambda item: item[1], default=("", 0))
        if limit and worst[1] >= limit:
            return self.fail(f"{worst[1]} {worst[0]} calls in a row failed; the last: {self.last_error}")
        robot = self.context.robot
        now = robot.now()
        if self._frame_unused(now):
            self.last_fresh = now
            return self.running(f"{self.checks} frames checked, {len(self.pending)} waiting, "
                                f"{self.alarm_count} alarms")
        frame = robot.rgbd()
        if frame is not None:
            self.last_seen_stamp = max(self.last_seen_stamp, frame.stamp)
        if frame is None or now - frame.stamp > self.params.max_frame_age:
            self.stale_frames += 1
            quiet = now - self.last_fresh
            if quiet > self.params.camera_timeout:
                age = ("no frame at all" if frame is None
                       else f"the latest frame is {now - frame.stamp:.1f} s old")
                return self.fail(f"camera quiet for {quiet:.1f} s ({age}); surveillance cannot watch")
            return self.running(f"camera quiet for {quiet:.1f} s; {self.alarm_count} alarms")
        self.last_fresh = now
        if self.params.mode == "poll":
            self._poll(frame)  # the thesis sends the latest frame when the period is up, new or not
        elif frame.stamp > self.last_frame_stamp and self.detecting is None and self._frame_due(frame.stamp):
            self.last_frame_stamp = frame.stamp
            self._submit_detection(frame)
        return self.running(f"{self.checks} frames checked, {len(self.pending)} waiting, "
                            f"{self.alarm_count} alarms")

    def terminate(self, new_status: Status) -> None:
        """Cancel the calls in flight (a halted surveillance does not act on late answers)."""
        now = self.context.robot.now() if self.ctx is not None else 0.0
        for pending in self.pending:
            pending.call.cancel()
            self._set_tracks(pending, "new", now)  # never answered: ask again when seen again
        self.pending.clear()
        if self.detecting is not None:
            self.detecting[0].cancel()
            self.detecting = None

    # -- frames ----------------------------------------------------------------------------------

    def _poll(self, frame: RGBDFrame) -> None:
        now = self.context.robot.now()
        if not self._may_submit(now):
            return
        measurement = None
        if self.params.fuse_at == "frame":
            measurement = measure(self.context.robot, frame, None, self.params.method, fuse_at="frame",
                                  surface_offset=self.params.surface_offset)
        self._submit(frame, [_Sighting(None, measurement)])

    def _frame_unused(self, now: float) -> bool:
        """Whether this tick would neither look at the newest frame nor find it stale, whatever it is.

        Frames come in stamp order, so the newest is at least as young as the last one read, and
        no younger than ``now``: while no detection can be due the camera is not read at all (the
        simulator renders a frame only when it is read).
        """
        if self.params.mode == "poll" or now - self.last_seen_stamp > self.params.max_frame_age:
            return False
        return self.detecting is not None or not self._frame_due(now)

    def _frame_due(self, stamp: float) -> bool:
        """Whether ``detect_period`` has passed since the last frame the detector looked at."""
        return stamp - self.last_frame_stamp >= self.params.detect_period - 1e-6

    def _submit_detection(self, frame: RGBDFrame) -> None:
        """Send ``frame`` to the detector; the answer is read on a later tick (``_collect_detections``)."""
        detector = self.context.model("detector")
        call = model_caller(self.context).submit(  # the role's timeout; only failures are logged
            "detector", detection_job(detector, frame, mirror=self.params.mirror), node=self.name,
            log_success=False)
        self.detecting = (call, frame)

    def _collect_detections(self) -> None:
        """Act on the detector's answer once it is there."""
        if self.detecting is None:
            return
        call, frame = self.detecting
        status = call.status()
        if not status.done:
            return
        self.detecting = None
        if status is CallStatus.SUCCEEDED:
            self._called("detector", True)
            self._detect(frame, call.result())
        elif status is not CallStatus.CANCELLED:
            self._called("detector", False, call.error())

    def _called(self, role: str, ok: bool, error: str = "") -> None:
        """Count a model call's outcome towards its role's consecutive-failure limit."""
        if ok:
            self.failed_in_row[role] = 0
        else:
            self.failed_in_row[role] = self.failed_in_row.get(role, 0) + 1
            self.last_error = error

    def _detect(self, frame: RGBDFrame, detections: list[Detection]) -> None:
        people = [d for d in detections if d.label == self.params.label and d.score >= self.params.min_score]
        self.checks += 1
        now = self.context.robot.now()
        self.tracks.expire(now)
        newcomers: list[_Sighting] = []
        taken: set[int] = set()
        for person in sorted(people, key=lambda d: -(d.box[2] - d.box[0]) * (d.box[3] - d.box[1])):
            self.sightings += 1
            sighting = self._sighting(frame, person, taken)
            if sighting is None:
                continue
            track = sighting.track
            assert track is not None
            recheck = track.state == "safe" and now - track.state_since > self.params.recheck
            if (track.state == "new" and track.hits >= self.params.min_hits) or recheck:
                newcomers.append(sighting)
        if not newcomers:
            return
        if not self.params.confirm:
            for sighting in newcomers:
                self._raise(frame, sighting, "detector: person")
            return
        if len(self.pending) < self.params.max_in_flight and self.budget.take(now):
            for sighting in newcomers:
                assert sighting.track is not None
                sighting.track.set("pending", now)
            asked = {id(s.detection) for s in newcomers}
            self._submit(frame, newcomers, tuple(d for d in people if id(d) not in asked))

    def _sighting(self, frame: RGBDFrame, person: Detection, taken: set[int]) -> _Sighting | None:
        """Measure a person at the frame's instant and find their track (None: the lidar saw no legs)."""
        measurement = measure(self.context.robot, frame, person, self.params.method, fuse_at="frame",
                              surface_offset=self.params.surface_offset)
        checkable = self.params.method != "seed"  # the thesis's cone measures straight ahead, not the box
        if (self.params.lidar_check and checkable and measurement is not None
                and math.isfinite(measurement.distance)):
            scan = self.context.robot.scan_at(frame.stamp)
            near_surface = measurement.distance - self.params.surface_offset
            if scan is not None and not legs_at(scan, measurement.bearing, near_surface):
                self.rejected += 1
                return None
        now = self.context.robot.now()
        if measurement is not None:
            pose = measurement.robot_pose
            map_bearing = pose.yaw + measurement.bearing
        else:
            k = frame.intrinsics
            map_bearing = frame.camera_pose.yaw + k.pixel_bearing(person.center[0])
        track = self.tracks.match(now, measurement.position if measurement else None, map_bearing, taken,
                                  appearance_of(frame, person))
        taken.add(track.id)
        kept = measurement if self.params.fuse_at == "frame" else None
        return _Sighting(person, kept, track)

    def _may_submit(self, now: float) -> bool:
        waited = now - self.last_submit >= self.params.period - 1e-9
        return waited and len(self.pending) < self.params.max_in_flight

    def _submit(self, frame: RGBDFrame, sightings: list[_Sighting],
                known: tuple[Detection, ...] = ()) -> None:
        caller = model_caller(self.context)
        vlm = self.context.model("vlm")
        prompt = self.params.prompt or surveillance_prompt()
        share_frame(self.context.models, frame)  # an oracle behind the VLM reads the frame's mask now
        call = caller.submit("vlm", ask_checked, vlm, [frame.color], prompt, SurveillanceVerdict,
                             timeout=self.params.timeout, node=self.name)
        self.last_submit = self.context.robot.now()
        if self.params.mode == "poll":
            self.checks += 1
        self.pending.append(_Pending(call, frame, sightings, known))

    # -- answers ---------------------------------------------------------------------------------

    def _settle(self, pending: _Pending) -> bool:
        """Act on a finished call; return True when it is finished."""
        status = pending.call.status()
        if not status.done:
            return False
        now = self.context.robot.now()
        if status is not CallStatus.SUCCEEDED:
            if status is not CallStatus.CANCELLED:
                self._called("vlm", False, pending.call.error())
            self.emit("surveillance_check_failed", frame_stamp=pending.frame.stamp,
                      error=pending.call.error())
            self._set_tracks(pending, "new", now)  # ask again on a later frame
            return True
        self._called("vlm", True)
        verdict: SurveillanceVerdict = pending.call.result().value
        self.emit("surveillance_verdict", frame_stamp=pending.frame.stamp, verdict=verdict.verdict,
                  latency=pending.call.latency)
        if not verdict.alarm:
            self._set_tracks(pending, "safe", now)
            return True
        for sighting in self._confirmed(pending, verdict, now):
            self._raise(pending.frame, sighting, verdict.as_text())
        return True

    def _confirmed(self, pending: _Pending, verdict: SurveillanceVerdict, now: float) -> list[_Sighting]:
        """The people of an ALARM answer to raise alarms for, best-confirmed first (see module docstring).

        Each comes with its box and the measurement of the frame's instant; sightings the VLM's
        boxes do not cover are marked safe.
        """
        frame = pending.frame
        height, width = frame.color.shape[:2]
        boxes, _ = checked_detections([Detection("person", p.score, p.box) for p in verdict.people],
                                      width, height, "vlm")
        sent = [s for s in pending.sightings if s.detection is not None]
        ranked: list[tuple[float, float, _Sighting]] = []
        if sent and boxes:
            overlap = iou_matrix(np.array([s.detection.box for s in sent if s.detection is not None]),
                                 np.array([b.box for b in boxes]))
            for i, sighting in enumerate(sent):
                assert sighting.detection is not None
                j = int(np.argmax(overlap[i]))
                inside = _centre_inside(sighting.detection, boxes[j])
                if overlap[i, j] >= CONFIRM_IOU or inside:
                    ranked.append((boxes[j].score, sighting.detection.score, sighting))
                    if sighting.track is not None:
                        sighting.track.set("confirmed", now)
                elif sighting.track is not None:
                    sighting.track.set("safe", now)  # the model did not see a person there
            if not ranked:  # the model saw someone else: a person the detector missed gets its own box
                missed = [b for b in boxes if not any(_same_person(k, b) for k in pending.known)]
                if missed:
                    ranked.append((0.0, 0.0, self._measured(frame, max(missed, key=lambda b: b.score))))
        elif sent:  # no boxes in the answer: every person sent is confirmed
            self._set_tracks(pending, "confirmed", now)
            ranked = [(0.0, s.detection.score, s) for s in sent if s.detection is not None]
        else:  # poll mode: the VLM's own best box, if it gave one
            best = max(boxes, key=lambda b: b.score) if boxes else None
            sighting = pending.sightings[0] if pending.sightings else _Sighting(None, None)
            if best is not None or sighting.measurement is None:
                sighting = self._measured(frame, best)
            ranked.append((0.0, 0.0, sighting))
        ranked.sort(key=lambda r: (-r[0], -r[1]))
        return [r[2] for r in ranked]

    def _measured(self, frame: RGBDFrame, detection: Detection | None) -> _Sighting:
        measurement = measure(self.context.robot, frame, detection, self.params.method,
                              fuse_at=self.params.fuse_at, surface_offset=self.params.surface_offset)
        return _Sighting(detection, measurement)

    @staticmethod
    def _set_tracks(pending: _Pending, state: TrackState, now: float) -> None:
        for sighting in pending.sightings:
            if sighting.track is not None:
                sighting.track.set(state, now)

    def _raise(self, frame: RGBDFrame, sighting: _Sighting, text: str) -> None:
        robot = self.context.robot
        now = robot.now()
        if now - self.last_alarm_time < self.params.alarm_cooldown:
            return
        self.last_alarm_time = now
        self.alarm_count += 1
        extra: dict[str, Any] = {}
        if sighting.detection is not None:  # where the camera saw them, whatever the distance method assumed
            seen = frame.camera_pose.yaw + frame.intrinsics.pixel_bearing(sighting.detection.center[0])
            extra["map_bearing"] = round(wrap_angle(seen), 4)
        alarm = alarm_from(self.alarm_count, frame, sighting.detection, sighting.measurement,
                           self.params.method, now, text, **extra)
        alarm = record_alarm(self.context, alarm, self.name, frame.color)
        self.write("alarm", alarm.to_dict())


def _same_person(detection: Detection, box: Detection) -> bool:
    """True when ``box`` (the VLM's) shows the person of ``detection`` (the detector's)."""
    overlap = float(iou_matrix(np.array([detection.box]), np.array([box.box]))[0, 0])
    return overlap >= CONFIRM_IOU or _centre_inside(detection, box)


def _centre_inside(detection: Detection, box: Detection) -> bool:
    """True when ``detection``'s centre lies inside ``box`` (a loose VLM box around a tight one)."""
    u, v = detection.center
    return box.box[0] <= u <= box.box[2] and box.box[1] <= v <= box.box[3]


def appearance_of(frame: RGBDFrame, person: Detection) -> tuple[float, float, float] | None:
    """Mean RGB of the central third of a person's box (their clothing), None for an empty box."""
    h, w = frame.color.shape[:2]
    x1, y1, x2, y2 = centre_region(person.box, w, h, fraction=0.33)
    patch = frame.color[y1:y2, x1:x2].reshape(-1, 3)
    if patch.size == 0:
        return None
    r, g, b = (float(v) for v in patch.mean(axis=0))
    return r, g, b


def alarm_from(number: int, frame: RGBDFrame, detection: Detection | None, measurement: Measurement | None,
               method: str, now: float, text: str, phase: str = "detected", **extra: Any) -> Alarm:
    """Build an :class:`Alarm` from a measurement (unknown distance when there is none)."""
    if measurement is None:
        pose = frame.camera_pose
        return Alarm(number, frame.stamp, now, (pose.x, pose.y, pose.yaw), 0.0, float("inf"), method, None,
                     phase, detection.box if detection else None, text, extra=dict(extra))
    p = measurement.robot_pose
    return Alarm(number, measurement.stamp if phase != "detected" else frame.stamp, now, (p.x, p.y, p.yaw),
                 measurement.bearing, measurement.distance, measurement.method, measurement.position, phase,
                 detection.box if detection else None, text, extra=dict(extra))
