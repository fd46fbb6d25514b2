"""Tests of the Surveillance leaf: polling vs detect-and-confirm, non-blocking calls, fusion time."""

from __future__ import annotations

import json
import math
import threading
from pathlib import Path

import numpy as np
import pytest
from patrol_doubles import Events, FakeRobot, K, ScriptedVLM, SlabDetector, person_frame, wall_scan

from missiontree.behaviours.surveillance import Surveillance
from missiontree.behaviours.tracks import CallBudget, PersonTracks
from missiontree.engine.context import MissionContext
from missiontree.engine.leaf import Status
from missiontree.reasoning.calls import CALLER_KEY, LatencyModel, ModelCaller
from missiontree.types import Detection, Pose2D, RGBDFrame


def setup_leaf(robot: FakeRobot, latency: float = 1.0, vlm: ScriptedVLM | None = None,
               run_dir: Path | None = None, **params: object) -> tuple[Surveillance, Events, dict]:
    events = Events()
    models: dict = {"detector": SlabDetector(), "vlm": vlm or ScriptedVLM()}
    models[CALLER_KEY] = ModelCaller(robot.now, events, simulated=True, models=models,
                                     latency={"vlm": LatencyModel(latency, latency)})
    leaf = Surveillance("watch", Surveillance.Params(**params))
    leaf.setup(context=MissionContext(robot=robot, models=models, events=events, run_dir=run_dir))
    return leaf, events, models


def step(robot: FakeRobot, leaf: Surveillance, person_bearing: float | None, dt: float = 0.2,
         depth: float = 1.0) -> None:
    """Advance 0.2 s, take a new frame and scan showing the person (robot-frame bearing), tick."""
    robot.advance(dt)
    robot.frame = person_frame(robot.time, robot.current, person_bearing, depth)
    robot.scans.push(robot.time, wall_scan(robot.time, person=None if person_bearing is None
                                           else (depth + 0.15, person_bearing)))
    leaf.tick_once()


def test_detect_mode_asks_the_vlm_only_about_frames_with_people() -> None:
    """With nobody in view and detect_period 0 the detector runs on every frame; the VLM is never asked."""
    robot = FakeRobot()
    leaf, _, models = setup_leaf(robot, detect_period=0.0)
    for _ in range(10):
        step(robot, leaf, None)
    leaf.tick_once()  # the last frame's detections are read on the tick after it was submitted
    assert models["detector"].calls == 10
    assert models["vlm"].asked == 0


def test_poll_mode_asks_every_period() -> None:
    """Polling at 0.5 s with frames every 0.2 s sends a frame at most every 0.5 s, people or not."""
    robot = FakeRobot()
    leaf, events, models = setup_leaf(robot, latency=0.1, mode="poll", period=0.5, max_in_flight=10)
    for _ in range(50):  # 5 s of 0.1 s ticks
        step(robot, leaf, None, dt=0.1)
    assert 9 <= models["vlm"].asked <= 10
    assert events.of("alarm") == []


def test_model_call_does_not_block_the_tick() -> None:
    """While the VLM's 1 s answer is pending the leaf keeps returning RUNNING and raises no alarm yet."""
    robot = FakeRobot()
    leaf, events, _ = setup_leaf(robot, latency=1.0)
    step(robot, leaf, math.radians(10))  # t=0.2: the frame goes to the detector
    step(robot, leaf, math.radians(10))  # t=0.4: its detections are read; the VLM is asked
    assert leaf.status == Status.RUNNING
    assert "1 waiting" in leaf.feedback_message
    for _ in range(2):
        step(robot, leaf, math.radians(10))
    assert events.of("alarm") == []
    for _ in range(3):
        step(robot, leaf, math.radians(10))  # the answer is due at t=1.4
    assert len(events.of("alarm")) == 1


@pytest.mark.parametrize("method", ["cone", "depth"])
def test_alarm_carries_distance_and_position_of_frame_instant(method: str) -> None:
    """The distance is measured on the frame's data although the robot moved before the answer came."""
    robot = FakeRobot()
    leaf, events, _ = setup_leaf(robot, latency=1.0, method=method, surface_offset=0.15)
    step(robot, leaf, math.radians(25), depth=1.0)  # frame at t=0.2, person 25° left, 1.15 m to centre
    robot.set_pose(Pose2D(0.3, 0.0, 0.0))  # the robot drives on; the person leaves the view
    for _ in range(6):
        step(robot, leaf, None)
    alarm = events.of("alarm")[0]
    assert alarm["stamp"] == pytest.approx(0.2)
    assert alarm["distance"] == pytest.approx(1.15, abs=0.05)
    assert alarm["bearing"] == pytest.approx(math.radians(25), abs=math.radians(2))
    truth = (1.15 * math.cos(math.radians(25)), 1.15 * math.sin(math.radians(25)))
    assert alarm["position"] == pytest.approx(truth, abs=0.06)
    assert alarm["robot_pose"] == [0.0, 0.0, 0.0]


def test_seed_method_reads_the_wall_for_an_off_axis_person() -> None:
    """With the seed's front cone a person 25° off the axis is measured at the wall (seed 001 §4.5.8)."""
    robot = FakeRobot()
    leaf, events, _ = setup_leaf(robot, latency=0.5, method="seed")
    for _ in range(5):
        step(robot, leaf, math.radians(25))
    assert events.of("alarm")[0]["distance"] == pytest.approx(5.0, abs=0.01)


def test_fuse_at_answer_reproduces_the_seed_drift() -> None:
    """Reading the latest scan when the answer arrives measures where the person no longer is."""
    robot = FakeRobot()
    leaf, events, _ = setup_leaf(robot, latency=1.0, mode="poll", method="seed", fuse_at="answer")
    step(robot, leaf, 0.0, depth=1.0)  # person straight ahead in the frame
    for _ in range(6):
        step(robot, leaf, None)  # gone by the time the answer arrives
    assert events.of("alarm")[0]["distance"] == pytest.approx(5.0, abs=0.01)


def test_free_text_answer_is_rejected_not_substring_matched() -> None:
    """An answer that is not the verdict schema's JSON raises no alarm, however much it says ALARM."""
    robot = FakeRobot()
    vlm = ScriptedVLM(lambda image: "ALARM: PERSON DETECTED. A man in a red coat.")
    leaf, events, _ = setup_leaf(robot, latency=0.2, vlm=vlm)
    for _ in range(5):
        step(robot, leaf, 0.0)
    assert events.of("alarm") == []
    failed = events.of("surveillance_check_failed")
    assert failed and "SurveillanceVerdict" in failed[0]["error"]


def test_safe_verdict_raises_nothing() -> None:
    """A VLM that answers SAFE for a detected person overrules the detector."""
    robot = FakeRobot()
    vlm = ScriptedVLM(lambda image: json.dumps({"verdict": "SAFE", "description": "a coat on a hook"}))
    leaf, events, _ = setup_leaf(robot, latency=0.2, vlm=vlm)
    for _ in range(5):
        step(robot, leaf, 0.0)
    assert events.of("alarm") == []
    assert events.of("surveillance_verdict")[0]["verdict"] == "SAFE"


def test_a_person_in_view_costs_one_call() -> None:
    """A person seen in 50 frames is asked about once (tracked), raising one alarm."""
    robot = FakeRobot()
    leaf, events, models = setup_leaf(robot, latency=0.3, period=0.5)
    for _ in range(50):  # 10 s
        step(robot, leaf, 0.1)
    assert models["vlm"].asked == 1
    assert len(events.of("alarm")) == 1


def test_a_safe_verdict_is_rechecked_after_a_while() -> None:
    """A person the VLM called SAFE is asked about again after `recheck` seconds, not every frame."""
    robot = FakeRobot()
    vlm = ScriptedVLM(lambda image: json.dumps({"verdict": "SAFE", "description": "a mannequin"}))
    leaf, _, _ = setup_leaf(robot, latency=0.2, vlm=vlm, recheck=3.0)
    for _ in range(50):  # 10 s
        step(robot, leaf, 0.1)
    assert 3 <= vlm.asked <= 4


def test_call_budget_holds_the_average_rate() -> None:
    """The token bucket allows a burst of two, then one call per period on average."""
    budget = CallBudget(rate=2.0, burst=2)
    granted = sum(budget.take(t * 0.05) for t in range(200))  # 10 s of asking every 50 ms
    assert 20 <= granted <= 22


def test_tracks_follow_a_walking_person_and_forget_them() -> None:
    """A person moving 0.3 m between frames keeps their track; after forget_after a new one starts."""
    tracks = PersonTracks(forget_after=2.0)
    first = tracks.match(0.0, (1.0, 0.0), 0.0)
    assert tracks.match(0.2, (1.0, 0.3), 0.3).id == first.id
    assert tracks.match(0.4, (4.0, 3.0), 0.6).id != first.id
    tracks.expire(3.0)
    assert tracks.match(3.0, (1.0, 0.6), 0.5).id not in (first.id,)


def test_halting_cancels_calls_in_flight() -> None:
    """Halting the leaf cancels its pending call; the late answer raises nothing."""
    robot = FakeRobot()
    leaf, events, _ = setup_leaf(robot, latency=1.0)
    step(robot, leaf, 0.0)
    leaf.stop(Status.INVALID)
    assert events.of("model_call")[0]["outcome"] == "cancelled"
    for _ in range(6):
        step(robot, leaf, None)
    assert events.of("alarm") == []


def test_alarm_is_recorded_in_run_dir(tmp_path: Path) -> None:
    """An alarm writes alarms.jsonl with pose, bearing, distance, method, position and saves the frame."""
    robot = FakeRobot()
    leaf, _, _ = setup_leaf(robot, latency=0.2, run_dir=tmp_path)
    for _ in range(3):
        step(robot, leaf, 0.0)
    lines = (tmp_path / "alarms.jsonl").read_text().splitlines()
    record = json.loads(lines[0])
    for key in ("stamp", "robot_pose", "bearing", "distance", "method", "position", "image"):
        assert key in record
    assert record["method"] == "depth"
    assert (tmp_path / record["image"]).is_file()
    assert leaf.ctx is not None and leaf.ctx.markers[0].kind == "alarm"


def test_alarm_cooldown_suppresses_repeats() -> None:
    """Within the cooldown a person still in view raises no second alarm."""
    robot = FakeRobot()
    leaf, events, _ = setup_leaf(robot, latency=0.2, alarm_cooldown=100.0)
    for _ in range(20):
        step(robot, leaf, 0.0)
    assert len(events.of("alarm")) == 1


def test_a_one_frame_detection_is_not_asked_about_with_min_hits_two() -> None:
    """A person (or a false detection) seen in a single frame costs no call; seen twice, it does."""
    robot = FakeRobot()
    leaf, _, models = setup_leaf(robot, latency=0.2, min_hits=2, detect_period=0.0)
    step(robot, leaf, 0.0)
    for _ in range(10):
        step(robot, leaf, None)
    assert models["vlm"].asked == 0
    step(robot, leaf, 0.0)
    step(robot, leaf, 0.0)
    step(robot, leaf, None)  # the second sighting's detections are read here; the VLM is asked
    step(robot, leaf, None)
    assert models["vlm"].asked == 1


# -- which person an alarm is about -----------------------------------------------------------------

class TwoPeopleDetector:
    """A false 'person' (a pillar cut by the left edge: big box, low score) and a real person on the right."""

    name = "two"
    labels = ["person"]
    PILLAR = (0.0, 0.0, 45.0, 216.0)
    PERSON = (244.0, 40.0, 277.0, 200.0)

    def __init__(self) -> None:
        self.threads: list[int] = []

    def detect(self, image: np.ndarray) -> list[Detection]:
        self.threads.append(threading.get_ident())
        return [Detection("person", 0.54, self.PILLAR), Detection("person", 0.93, self.PERSON)]


def two_people_frame(stamp: float, camera: Pose2D) -> RGBDFrame:
    """The pillar at 1.4 m on the left edge, the person 3 m away on the right."""
    color = np.full((240, 320, 3), 90, np.uint8)
    depth = np.full((240, 320), 6.0, np.float32)
    depth[0:216, 0:45] = 1.4
    depth[40:200, 244:277] = 3.0
    return RGBDFrame(stamp, color, depth, K, camera)


def watch_two(vlm_boxes: list[tuple[tuple[float, ...], float]], **params: object) -> tuple[Events, dict]:
    answer = json.dumps({"verdict": "ALARM", "description": "people",
                         "people": [{"box": list(b), "score": s} for b, s in vlm_boxes]})
    robot = FakeRobot()
    events = Events()
    models: dict = {"detector": TwoPeopleDetector(), "vlm": ScriptedVLM(lambda image: answer)}
    models[CALLER_KEY] = ModelCaller(robot.now, events, simulated=True, models=models,
                                     latency={"vlm": LatencyModel(0.2, 0.2)})
    leaf = Surveillance("watch", Surveillance.Params(lidar_check=False, **params))
    leaf.setup(context=MissionContext(robot=robot, models=models, events=events))
    for _ in range(6):
        robot.advance(0.2)
        robot.frame = two_people_frame(robot.time, robot.current)
        leaf.tick_once()
    return events, models


def test_alarm_goes_to_the_person_the_vlm_confirmed_not_the_bigger_box() -> None:
    """The VLM boxes only the real person: the alarm's box and position are theirs, not the pillar's."""
    events, _ = watch_two([(TwoPeopleDetector.PERSON, 0.9)])
    alarms = events.of("alarm")
    assert len(alarms) == 1
    assert alarms[0]["box"] == list(TwoPeopleDetector.PERSON)
    assert alarms[0]["bearing"] < 0  # on the right
    assert alarms[0]["distance"] == pytest.approx(3.0 / math.cos(alarms[0]["bearing"]) + 0.1, abs=0.15)


def test_alarm_cooldown_keeps_the_best_confirmed_person() -> None:
    """Both boxes confirmed with a cooldown: the one alarm is the better-confirmed person, not the pillar."""
    events, _ = watch_two([(TwoPeopleDetector.PILLAR, 0.54), (TwoPeopleDetector.PERSON, 0.93)],
                          alarm_cooldown=5.0)
    alarms = events.of("alarm")
    assert len(alarms) == 1 and alarms[0]["box"] == list(TwoPeopleDetector.PERSON)


def test_detector_runs_on_a_worker_and_is_read_a_tick_later() -> None:
    """The detector is a model call: never run on the tick thread; its detections arrive on the next tick."""
    events, models = watch_two([(TwoPeopleDetector.PERSON, 0.9)])
    threads = models["detector"].threads
    assert threads and threading.get_ident() not in threads
    # Per-frame detections that succeed are not logged one by one (they would be most of the log).
    assert [e for e in events.of("model_call") if e["role"] == "detector"] == []


def test_a_failing_detector_is_logged_and_fails_the_leaf_after_the_limit() -> None:
    """Detector calls that fail are model_call events with the error; N in a row fail the leaf."""
    class Broken(SlabDetector):
        def detect(self, image: np.ndarray) -> list[Detection]:
            raise RuntimeError("onnxruntime: cannot allocate")

    robot = FakeRobot()
    leaf, events, models = setup_leaf(robot, latency=0.2, max_failed_calls=4)
    models["detector"] = Broken()
    for _ in range(10):
        step(robot, leaf, 0.0)
        if leaf.status != Status.RUNNING:
            break
    failed = [e for e in events.of("model_call") if e["role"] == "detector"]
    assert len(failed) == 4 and all(e["outcome"] == "failed" and e["node"] == "watch" for e in failed)
    assert leaf.status == Status.FAILURE and "4 detector calls in a row failed" in leaf.feedback_message
    assert "cannot allocate" in leaf.feedback_message


# -- faults that must not pass quietly --------------------------------------------------------------

def test_a_stale_frame_is_never_looked_at_and_a_quiet_camera_fails_the_leaf() -> None:
    """A frame older than max_frame_age raises no alarm; no fresh frame for camera_timeout fails with why."""
    robot = FakeRobot()
    leaf, events, models = setup_leaf(robot, latency=0.2, max_frame_age=1.0, camera_timeout=3.0)
    robot.frame = person_frame(0.0, robot.current, 0.0)
    robot.advance(1.5)  # the camera went quiet 1.5 s ago: its last frame shows a person
    for _ in range(5):
        robot.advance(0.2)
        leaf.tick_once()
    assert models["detector"].calls == 0 and events.of("alarm") == []
    assert leaf.status == Status.RUNNING and "camera quiet" in leaf.feedback_message
    for _ in range(20):
        robot.advance(0.2)
        leaf.tick_once()
        if leaf.status != Status.RUNNING:
            break
    assert leaf.status == Status.FAILURE and "camera quiet" in leaf.feedback_message


def test_every_model_call_failing_fails_the_leaf_with_the_last_error() -> None:
    """Malformed answers every time: after max_failed_calls failures in a row the leaf fails, saying why."""
    robot = FakeRobot()
    vlm = ScriptedVLM(lambda image: "not json at all")
    leaf, events, _ = setup_leaf(robot, latency=0.1, vlm=vlm, max_failed_calls=3, period=0.2)
    for _ in range(60):
        step(robot, leaf, 0.0)
        if leaf.status != Status.RUNNING:
            break
    assert leaf.status == Status.FAILURE
    assert "3 vlm calls in a row failed" in leaf.feedback_message
    assert "SurveillanceVerdict" in leaf.feedback_message
    assert events.of("alarm") == []


def test_one_good_answer_resets_the_failure_count() -> None:
    """Failures that are not in a row (every other answer good) do not fail the leaf."""
    robot = FakeRobot()
    answers = iter(["garbage", "garbage", ScriptedVLM.by_detector] * 100)

    def flaky(image: np.ndarray) -> str:
        answer = next(answers)
        return answer(image) if callable(answer) else answer

    leaf, _, _ = setup_leaf(robot, latency=0.1, vlm=ScriptedVLM(flaky), max_failed_calls=2, period=0.2,
                            recheck=0.2)
    for _ in range(60):
        step(robot, leaf, 0.0)
    assert leaf.status == Status.RUNNING


class BrokenBoxDetector:
    """A detector whose answer holds non-finite and impossible boxes beside one good one."""

    name = "broken-boxes"
    labels = ["person"]

    def detect(self, image: np.ndarray) -> list[Detection]:
        good = SlabDetector().detect(image)
        return [Detection("person", 0.9, (math.nan, 0.0, 10.0, 10.0)),
                Detection("person", math.inf, (0.0, 0.0, 10.0, 10.0)),
                Detection("person", 0.9, (90000.0, 90000.0, 90010.0, 90010.0)),
                Detection("person", 0.9, (50.0, 40.0, -math.inf, 100.0)), *good]


def test_non_finite_and_impossible_detector_boxes_are_dropped_not_fatal() -> None:
    """NaN/inf boxes and a box far outside the image are dropped where they enter; the real person alarms."""
    robot = FakeRobot()
    leaf, events, models = setup_leaf(robot, latency=0.2)
    models["detector"] = BrokenBoxDetector()
    for _ in range(6):
        step(robot, leaf, math.radians(10))
    assert leaf.status == Status.RUNNING and events.of("error") == []
    alarms = events.of("alarm")
    assert len(alarms) == 1 and all(math.isfinite(v) for v in alarms[0]["box"])
    assert abs(alarms[0]["bearing"] - math.radians(10)) < math.radians(3)


def test_a_vlm_box_outside_the_image_gives_no_alarm_at_an_impossible_bearing() -> None:
    """Poll mode: a VLM box at (90000, 90000) in a 320x240 frame is rejected (retried, then failed)."""
    robot = FakeRobot()
    answer = json.dumps({"verdict": "ALARM", "description": "someone",
                         "people": [{"box": [90000, 90000, 90050, 90100], "score": 0.9}]})
    vlm = ScriptedVLM(lambda image: answer)
    leaf, events, _ = setup_leaf(robot, latency=0.1, vlm=vlm, mode="poll", period=0.5)
    for _ in range(5):
        step(robot, leaf, 0.0)
    assert events.of("alarm") == []
    failed = events.of("surveillance_check_failed")
    assert failed and "outside the 320x240 image" in failed[0]["error"]


class PillarThenBoth(TwoPeopleDetector):
    """The person is seen first (and confirmed); from the fourth frame on the pillar shows too."""

    def detect(self, image: np.ndarray) -> list[Detection]:
        self.threads.append(threading.get_ident())
        person = Detection("person", 0.93, self.PERSON)
        return [person] if len(self.threads) < 4 else [Detection("person", 0.54, self.PILLAR), person]


def test_a_vlm_box_over_a_person_already_alarmed_raises_nothing_for_the_newcomer() -> None:
    """Only the pillar is new; the VLM boxes the known person: no alarm for the pillar, none repeated."""
    answer = json.dumps({"verdict": "ALARM", "description": "a person",
                         "people": [{"box": list(TwoPeopleDetector.PERSON), "score": 0.9}]})
    robot, events = FakeRobot(), Events()
    models: dict = {"detector": PillarThenBoth(), "vlm": ScriptedVLM(lambda image: answer)}
    models[CALLER_KEY] = ModelCaller(robot.now, events, simulated=True, models=models,
                                     latency={"vlm": LatencyModel(0.2, 0.2)})
    leaf = Surveillance("watch", Surveillance.Params(lidar_check=False))
    leaf.setup(context=MissionContext(robot=robot, models=models, events=events))
    for _ in range(12):
        robot.advance(0.2)
        robot.frame = two_people_frame(robot.time, robot.current)
        leaf.tick_once()
    assert models["vlm"].asked == 2  # the person, then the pillar
    alarms = events.of("alarm")
    assert len(alarms) == 1 and alarms[0]["box"] == list(TwoPeopleDetector.PERSON)


def test_a_person_the_detector_missed_gets_the_vlms_box() -> None:
    """The VLM boxes someone where the detector saw nobody: the alarm takes the VLM's box."""
    elsewhere = (120.0, 30.0, 150.0, 200.0)
    events, _ = watch_two([(elsewhere, 0.8)])
    alarms = events.of("alarm")
    assert alarms and alarms[0]["box"] == list(elsewhere)


@pytest.mark.parametrize(("params", "expected"), [({}, False), ({"mirror": True}, True),
                                                  ({"mirror": None}, None)])
def test_the_detector_is_asked_for_the_single_pass_unless_told(monkeypatch: pytest.MonkeyPatch,
                                                               params: dict, expected: bool | None) -> None:
    """By default the leaf asks the detector for no mirror pass; ``mirror`` overrides it."""
    import missiontree.behaviours.surveillance as surveillance

    asked: list[bool | None] = []
    real = surveillance.detection_job

    def recording_job(detector: object, frame: RGBDFrame, mirror: bool | None = None) -> object:
        asked.append(mirror)
        return real(detector, frame, mirror=mirror)

    monkeypatch.setattr(surveillance, "detection_job", recording_job)
    robot = FakeRobot()
    leaf, _, _ = setup_leaf(robot, **params)
    step(robot, leaf, None)
    assert asked == [expected]


def test_with_nobody_in_view_the_detector_looks_at_a_frame_every_detect_period() -> None:
    """Frames every 0.2 s and the default detect_period 0.4 s: every other frame."""
    robot = FakeRobot()
    leaf, _, models = setup_leaf(robot)
    for _ in range(10):
        step(robot, leaf, None)
    leaf.tick_once()
    assert models["detector"].calls == 5


def test_with_a_person_in_view_the_detector_still_looks_every_detect_period() -> None:
    """The rate is the leaf's own: a person in view does not make it detect on every frame."""
    robot = FakeRobot()
    leaf, events, models = setup_leaf(robot, latency=0.2)
    for _ in range(10):
        step(robot, leaf, 0.1)
    leaf.tick_once()
    assert models["detector"].calls == 5
    assert models["vlm"].asked == 1 and len(events.of("alarm")) == 1


def test_the_camera_is_not_read_on_ticks_no_detection_can_be_due() -> None:
    """Between detections (detect_period 0.4 s, frames every 0.2 s) the leaf leaves the camera unread."""
    robot = FakeRobot()
    leaf, _, models = setup_leaf(robot)
    reads = []
    original = robot.rgbd
    robot.rgbd = lambda: reads.append(robot.time) or original()  # type: ignore[method-assign]
    for _ in range(10):
        step(robot, leaf, None)
    leaf.tick_once()
    assert models["detector"].calls == 5
    assert len(reads) < 10 and leaf.status == Status.RUNNING
