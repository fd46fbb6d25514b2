"""Tests of ServoToTarget: turn to centre the person, measure, record; give up on a lost target."""

from __future__ import annotations

import math
import threading

import py_trees
import pytest
from patrol_doubles import Events, FakeRobot, K, SlabDetector, person_frame, wall_scan

from missiontree.behaviours.alarms import Alarm
from missiontree.behaviours.servo import ServoToTarget
from missiontree.engine.context import MissionContext
from missiontree.engine.leaf import Status


def world_frame(robot: FakeRobot, person: tuple[float, float] | None) -> None:
    """Render what the robot sees of a person standing at the map point ``person``."""
    bearing, rng = None, 1.0
    if person is not None:
        b = robot.current.bearing_to(*person)
        if abs(b) < K.hfov / 2 - math.radians(2):
            bearing, rng = b, math.hypot(person[0] - robot.current.x, person[1] - robot.current.y) - 0.15
    robot.frame = person_frame(robot.time, robot.current, bearing, rng)
    scan_person = None
    if person is not None:
        scan_person = (math.hypot(person[0] - robot.current.x, person[1] - robot.current.y),
                       robot.current.bearing_to(*person))
    robot.scans.push(robot.time, wall_scan(robot.time, person=scan_person))


def post_alarm(bearing: float, distance: float = 1.2) -> None:
    client = py_trees.blackboard.Client(name="surveillance")
    client.register_key("alarm", access=py_trees.common.Access.WRITE)
    position = (distance * math.cos(bearing), distance * math.sin(bearing))
    client.alarm = Alarm(1, 0.0, 0.5, (0.0, 0.0, 0.0), bearing, distance, "depth", position).to_dict()


def run(robot: FakeRobot, leaf: ServoToTarget, person: tuple[float, float] | None, seconds: float) -> None:
    for _ in range(int(seconds / 0.1)):
        world_frame(robot, person)
        leaf.tick_once()
        if leaf.status != Status.RUNNING:
            return
        robot.advance(0.1)


def make(robot: FakeRobot) -> tuple[ServoToTarget, Events]:
    events = Events()
    leaf = ServoToTarget("servo", ServoToTarget.Params(method="seed"))
    leaf.setup(context=MissionContext(robot=robot, models={"detector": SlabDetector()}, events=events))
    return leaf, events


def test_servo_fails_at_once_without_an_alarm() -> None:
    """With no alarm on the blackboard the servo fails on its first tick (the patrol keeps going)."""
    robot = FakeRobot()
    leaf, _ = make(robot)
    leaf.tick_once()
    assert leaf.status == Status.FAILURE
    assert robot.drives == []


def test_servo_centres_person_at_25_degrees_then_seed_cone_measures_right() -> None:
    """A person 25° off the axis is turned to, centred, and then even the seed's ±15° cone measures them."""
    robot = FakeRobot()
    person = (1.2 * math.cos(math.radians(25)), 1.2 * math.sin(math.radians(25)))
    post_alarm(math.radians(25))
    leaf, events = make(robot)
    run(robot, leaf, person, 10.0)
    assert leaf.status == Status.SUCCESS
    assert robot.current.yaw == pytest.approx(math.radians(25), abs=math.radians(5))
    record = [e for e in events.of("alarm") if e["phase"] == "servoed"][0]
    assert record["distance"] == pytest.approx(1.05, abs=0.06)  # the near surface, seed method
    assert any(w > 0 for _, w in robot.drives)
    assert robot.drives[-1] == (0.0, 0.0)


def test_servo_serves_each_alarm_once() -> None:
    """After serving alarm 1 the servo fails at once until a newer alarm arrives."""
    robot = FakeRobot()
    person = (1.2, 0.05)
    post_alarm(0.04)
    leaf, _ = make(robot)
    run(robot, leaf, person, 5.0)
    assert leaf.status == Status.SUCCESS
    leaf.tick_once()
    assert leaf.status == Status.FAILURE and "no new alarm" in leaf.feedback_message


def test_lost_target_ends_servo_after_timeout() -> None:
    """A person who is gone is searched for lost_timeout seconds, then the servo fails saying so."""
    robot = FakeRobot()
    post_alarm(math.radians(-30))
    leaf, events = make(robot)
    run(robot, leaf, None, 10.0)
    assert leaf.status == Status.FAILURE
    assert "target lost" in leaf.feedback_message
    assert events.of("servo_lost")
    assert robot.current.yaw < 0  # it turned towards where the person was reported


def test_servo_skips_a_person_served_moments_ago() -> None:
    """A new alarm for the same spot right after serving it does not preempt the patrol again."""
    robot = FakeRobot()
    person = (1.2, 0.05)
    post_alarm(0.04)
    leaf, events = make(robot)
    run(robot, leaf, person, 5.0)
    assert leaf.status == Status.SUCCESS
    client = py_trees.blackboard.Client(name="surveillance2")
    client.register_key("alarm", access=py_trees.common.Access.WRITE)
    again = Alarm(2, robot.time, robot.time, (0.0, 0.0, 0.0), 0.04, 1.2, "depth", (1.2, 0.05))
    client.alarm = again.to_dict()
    leaf.tick_once()
    assert leaf.status == Status.FAILURE
    assert events.of("servo_skipped")[0]["alarm"] == 2


class ThreadNotingDetector(SlabDetector):
    """The slab detector, noting which thread each call runs on."""

    def __init__(self) -> None:
        super().__init__()
        self.threads: list[int] = []

    def detect(self, image):  # type: ignore[no-untyped-def]
        self.threads.append(threading.get_ident())
        return super().detect(image)


def test_servo_detects_on_a_worker_not_the_tick_thread() -> None:
    """The servo's detector is a model call: run off the tick thread, its answer read on a later tick."""
    robot = FakeRobot()
    person = (1.2 * math.cos(math.radians(25)), 1.2 * math.sin(math.radians(25)))
    post_alarm(math.radians(25))
    events = Events()
    detector = ThreadNotingDetector()
    leaf = ServoToTarget("servo", ServoToTarget.Params(method="seed"))
    leaf.setup(context=MissionContext(robot=robot, models={"detector": detector}, events=events))
    run(robot, leaf, person, 10.0)
    assert leaf.status == Status.SUCCESS
    assert detector.threads and threading.get_ident() not in detector.threads


def test_servo_with_a_broken_detector_gives_up_with_its_error() -> None:
    """A detector that always raises ends the servo (target lost) with the detector's error in the reason."""

    class Broken(SlabDetector):
        def detect(self, image):  # type: ignore[no-untyped-def]
            raise RuntimeError("the model file is corrupt")

    robot = FakeRobot()
    post_alarm(math.radians(25))
    leaf = ServoToTarget("servo", ServoToTarget.Params(method="seed", lost_timeout=1.0))
    leaf.setup(context=MissionContext(robot=robot, models={"detector": Broken()}, events=Events()))
    run(robot, leaf, (1.0, 0.5), 5.0)
    assert leaf.status == Status.FAILURE
    assert "target lost" in leaf.feedback_message and "the model file is corrupt" in leaf.feedback_message
    assert robot.drives[-1] == (0.0, 0.0)


def test_servo_asks_the_detector_to_band_its_mirror_pass_on_people(monkeypatch: pytest.MonkeyPatch) -> None:
    """The servo tracks people only, so its detection jobs name 'person' for the detector's mirror band."""
    import missiontree.behaviours.servo as servo_module

    asked: list[object] = []
    real = servo_module.detection_job

    def recording(detector, frame, mirror=None, band_labels=None):  # noqa: ANN001, ANN202
        asked.append(band_labels)
        return real(detector, frame, mirror=mirror, band_labels=band_labels)

    monkeypatch.setattr(servo_module, "detection_job", recording)
    robot = FakeRobot()
    post_alarm(math.radians(20))
    leaf, _ = make(robot)
    run(robot, leaf, (1.2 * math.cos(math.radians(20)), 1.2 * math.sin(math.radians(20))), 1.0)
    assert asked and all(labels == ("person",) for labels in asked)


@pytest.mark.parametrize("period", [0.0, 0.4])
def test_servo_detect_period_spaces_the_detectors_frames(period: float) -> None:
    """With detect_period 0 the detector looks at every new frame; with 0.4 s at most one frame in 0.4 s."""
    robot = FakeRobot()
    post_alarm(math.radians(-30))
    events = Events()
    detector = ThreadNotingDetector()
    leaf = ServoToTarget("servo", ServoToTarget.Params(method="seed", detect_period=period))
    leaf.setup(context=MissionContext(robot=robot, models={"detector": detector}, events=events))
    run(robot, leaf, None, 2.0)   # nobody there: it keeps looking for 2 s of new frames every tick
    submitted = 20 if period == 0.0 else 5   # frames at 0.0, 0.1, ... 1.9 s; or 0.0, 0.4, ... 1.6 s
    assert len(detector.threads) in (submitted - 1, submitted)   # the last may still be in flight
