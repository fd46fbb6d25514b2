"""The look on arrival of the intent leaf (GoToIntent): face, detect, confirm, look again.

At a standoff pose the robot turns to face the object, waits for a fresh frame, asks the detector to
see the object's class where the graph puts it (up to :data:`LOOK_FRAMES` frames) and the
vision-language model to confirm the asked-for attributes. An object nothing could confirm (a class the
detector does not know, or above the camera's view) is served only as a strong choice. A miss is
looked at once more from another standoff pose before the object is doubted. The steps are one
state machine with the leaf's serving and failing over (:class:`ArrivalLook` is its base); they live
here so that the leaf's module holds choosing and driving, this one looking.
"""

from __future__ import annotations

import dataclasses
import enum
import math
from typing import Any

from missiontree.behaviours.approach_steps import camera_view
from missiontree.behaviours.background import Background, waits
from missiontree.engine.leaf import Leaf, Status
from missiontree.perception.detectors import detection_job
from missiontree.reasoning.calls import CallStatus, ModelCall, model_caller
from missiontree.reasoning.intent import (
    Candidate,
    SceneObjects,
    look_crop,
    look_for,
    match_detection,
    other_viewpoint,
)
from missiontree.reasoning.knowledge import STRONG
from missiontree.reasoning.phrases import fold_label
from missiontree.reasoning.prompts import crop_match_prompt
from missiontree.reasoning.schemas import CropMatch
from missiontree.types import RGBDFrame

#: Heading error (rad) at which the robot counts as facing the object, and the time allowed to turn (s).
FACING, FACE_TIMEOUT = 0.12, 8.0
#: Frames a look may take (detector and vision-language model) before the object is doubted.
LOOK_FRAMES = 3
#: How much of the surroundings the vision-language model sees around the detection (share of the box a side).
LOOK_GROW = 1.0


class Step(enum.Enum):
    """The leaf's steps, each with what the robot is doing (its running message)."""

    INTERPRET = "interpreting the command"
    FACE = "turning to face the object"
    PLAN = "checking and ranking candidates"
    DRIVE = "driving to the candidate"
    FRAME = "waiting for a fresh camera frame"
    DETECT = "looking with the detector"
    CONFIRM = "asking the vision-language model"
    VIEWPOINT = "finding another place to look from"


class ArrivalLook(Leaf):
    """The looking steps of the intent leaf (see the module docstring); the leaf supplies the rest."""

    params: Any  # the leaf's Params: look_timeout, robot_radius, allow_unknown
    target: Candidate | None
    scene: SceneObjects | None
    call: ModelCall | None
    job: Background | None
    frame: RGBDFrame | None
    step: Step
    text: str
    wanted: str
    started: float
    looks: int
    second_look: bool
    first_miss: str
    reapproached: bool   # the current candidate's goal was replaced once after the stack could not reach it
    approach_miss: str   # why, while the other standoff pose is being found ("" otherwise)

    # supplied by the leaf
    def _served(self, confirmed: bool, note: str) -> Status:
        raise NotImplementedError

    def _strength(self) -> tuple[float, str]:
        raise NotImplementedError

    def _doubt(self, reason: str) -> Status:
        raise NotImplementedError

    def _by_embedding(self) -> bool:
        raise NotImplementedError

    def _drive_to(self, candidate: Candidate) -> Status:
        raise NotImplementedError

    def _next(self, reason: str) -> Status:
        raise NotImplementedError

    def _faced(self) -> Status:
        """Turn in place until the object is straight ahead (the navigation stack may stop short)."""
        assert self.target is not None
        robot = self.context.robot
        stamped = robot.pose()
        error = stamped.pose.bearing_to(*self.target.xy) if stamped is not None else 0.0
        if abs(error) > FACING and robot.now() - self.started < FACE_TIMEOUT:
            robot.drive(0.0, max(-1.0, min(1.0, 2.0 * error)))
            return self.running(f"turning to face {self.target.id} ({math.degrees(error):.0f} deg)")
        robot.stop()
        self.started = robot.now()
        self.step = Step.FRAME
        return self.running(Step.FRAME.value)

    def _framed(self) -> Status:
        assert self.target is not None
        robot = self.context.robot
        if robot.now() - self.started > self.params.look_timeout:
            return self._doubt("no camera frame after arriving")
        frame = robot.rgbd()
        if frame is None or frame.stamp < self.started:
            return self.running(Step.FRAME.value)
        self.frame = frame
        detector = self.context.model("detector")
        unseen = self._unverifiable(detector, frame)
        if unseen:
            # Nothing here can check it: only a strong choice is served unconfirmed, a weak one is doubted
            strength, why = self._strength()
            if strength < STRONG:
                return self._doubt(f"{unseen}, and it was a weak choice ({why}, {strength:.2f} < {STRONG:g})")
            if self._by_embedding():  # a reading by likeness alone is never served unchecked
                return self._doubt(f"{unseen}, and the command was understood only by embedding ({why})")
            self.emit("object_unverifiable", command=self.text, object=self.target.id, reason=unseen)
            return self._served(False, f"not confirmed: {unseen}; a strong choice: {why} {strength:.2f}")
        self.call = model_caller(self.context).submit(
            "detector", detection_job(detector, frame), node=self.name
        )
        self.step = Step.DETECT
        return self.running(Step.DETECT.value)

    def _detected(self) -> Status:
        assert self.call is not None and self.target is not None and self.frame is not None
        status = self.call.status()
        if not status.done:
            return self.running(Step.DETECT.value)
        if status is not CallStatus.SUCCEEDED:
            return self._doubt(f"the detector failed: {self.call.error()}")
        detections = self.call.result()
        self.call = None
        found, why = match_detection(detections, self.target.label, self.frame, self.target.xy)
        self.looks += 1
        if found is None and self.looks < LOOK_FRAMES:
            self.started = self.frame.stamp + 1e-6  # a newer frame: detectors miss now and then
            self.step = Step.FRAME
            return self.running(f"{Step.FRAME.value} (look {self.looks + 1} of {LOOK_FRAMES})")
        if found is None:
            return self._look_elsewhere(f"{why} (in {self.looks} frames)")
        wanted = look_for(self.target.label, self.wanted.split())
        # Only the region around the detection is asked about, even when it is the only one of its
        # class the detector reports: a neighbour it scored below its threshold (a blue chair beside a
        # red one) would otherwise answer for it, and a wrong object would be served as confirmed.
        image = look_crop(self.frame.color, found.box, grow=LOOK_GROW)
        self.call = model_caller(self.context).ask(
            "vlm", [image], crop_match_prompt(wanted), CropMatch, node=self.name
        )
        self.step = Step.CONFIRM
        return self.running(f"{Step.CONFIRM.value}: is it a {wanted}?")

    def _confirmed(self) -> Status:
        assert self.call is not None and self.target is not None
        status = self.call.status()
        if not status.done:
            return self.running(Step.CONFIRM.value)
        if status is not CallStatus.SUCCEEDED:
            return self._doubt(f"the vision-language model failed: {self.call.error()}")
        verdict: CropMatch = self.call.result().value
        self.call = None
        wanted = look_for(self.target.label, self.wanted.split())
        if not verdict.matches and self.looks < LOOK_FRAMES:
            assert self.frame is not None
            self.started = self.frame.stamp + 1e-6  # look again at a newer frame
            self.step = Step.FRAME
            return self.running(f"{Step.FRAME.value} (look {self.looks + 1} of {LOOK_FRAMES})")
        if not verdict.matches:
            return self._look_elsewhere(f"the vision-language model does not see a {wanted}: "
                                        f"{verdict.reason} (in {self.looks} frames)")
        self.emit(
            "object_verified",
            command=self.text,
            object=self.target.id,
            looked_for=wanted,
            reason=verdict.reason,
            confidence=verdict.confidence,
        )
        return self._served(True, f"a {wanted} seen ({verdict.reason})")

    def _look_elsewhere(self, reason: str) -> Status:
        """A look that did not confirm the target: look once more from another side before doubting it.

        A detector misses a cup seen edge-on on a cluttered table, or one cut by the view's edge;
        the graph's instance came from views elsewhere. One second standoff pose (another side, or
        nearer/farther: :func:`~missiontree.reasoning.intent.other_viewpoint`) is tried first.
        """
        assert self.target is not None and self.scene is not None
        robot = self.context.robot
        stamped = robot.pose()
        grid = robot.occupancy()
        obj = self.scene.objects.get(self.target.id)
        if self.second_look or stamped is None or grid is None or obj is None:
            return self._doubt(reason if not self.second_look else f"{self.first_miss}; again from a "
                               f"second place: {reason}")
        self.second_look = True
        self.first_miss = reason
        self.job = Background(
            other_viewpoint, obj, grid, stamped.pose, self.target.goal, self.params.robot_radius,
            self.params.allow_unknown, camera_view(self.frame), wait=waits(self.context),
        )
        self.step = Step.VIEWPOINT
        return self.running(Step.VIEWPOINT.value)

    def _approach_again(self, reason: str) -> Status:
        """A standoff goal the navigation stack gave up on: stand somewhere else by it once before moving on.

        On a map learned as the robot goes, the cell chosen may turn out to hug an obstacle or lie
        behind one seen later; another side of the same object
        (:func:`~missiontree.reasoning.intent.other_viewpoint` on the map as it is now) often is free.
        """
        assert self.target is not None and self.scene is not None
        robot = self.context.robot
        stamped = robot.pose()
        grid = robot.occupancy()
        obj = self.scene.objects.get(self.target.id)
        if stamped is None or grid is None or obj is None:
            return self._next(reason)
        self.reapproached = True
        self.approach_miss = reason
        self.job = Background(
            other_viewpoint, obj, grid, stamped.pose, self.target.goal, self.params.robot_radius,
            self.params.allow_unknown, camera_view(robot.rgbd()), wait=waits(self.context),
        )
        self.step = Step.VIEWPOINT
        return self.running(f"finding another place to stand by {self.target.id}")

    def _viewpoint(self) -> Status:
        assert self.job is not None and self.target is not None
        done, pose, _ = self.job.poll()  # a failed search: no other place
        if not done:
            return self.running(Step.VIEWPOINT.value)
        self.job = None
        if self.approach_miss:
            miss, self.approach_miss = self.approach_miss, ""
            if pose is None:
                return self._next(f"{miss}; no other place to stand by it")
            self.emit("approach_again", command=self.text, object=self.target.id, reason=miss,
                      x=round(pose.x, 3), y=round(pose.y, 3), yaw=round(pose.yaw, 3))
            return self._drive_to(dataclasses.replace(self.target, goal=pose))
        if pose is None:
            return self._doubt(f"{self.first_miss}; no other place to look at it from")
        self.emit("look_again", command=self.text, object=self.target.id, reason=self.first_miss,
                  x=round(pose.x, 3), y=round(pose.y, 3), yaw=round(pose.yaw, 3))
        return self._drive_to(dataclasses.replace(self.target, goal=pose))

    def _unverifiable(self, detector: Any, frame: RGBDFrame) -> str:
        """Why nothing could confirm the target from here ("" when a look can)."""
        assert self.target is not None and self.scene is not None
        label = self.target.label
        known = [fold_label(str(x)) for x in (getattr(detector, "labels", None) or [])]
        if known and fold_label(label) not in known:
            return f"the detector knows no {label}"
        z = self.scene.objects[self.target.id].z
        cam = frame.camera_pose
        distance = math.hypot(self.target.xy[0] - cam.x, self.target.xy[1] - cam.y)
        top = frame.camera_height + distance * frame.intrinsics.cy / frame.intrinsics.fy
        if z > top:
            return (f"the {label} is {z:.2f} m up, above what the camera sees from "
                    f"{distance:.1f} m ({top:.2f} m)")
        return ""
