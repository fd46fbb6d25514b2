"""Tests of the Surveillance leaf: polling vs detect-and-confirm, non-blocking calls, fusion time."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest
from patrol_doubles import Events, FakeRobot, ScriptedVLM, SlabDetector, person_frame, wall_scan

from missiontree.behaviours.surveillance import Surveillance
from missiontree.behaviours.tracks import CallBudget, PersonTracks
from missiontree.engine.context import MissionContext
from missiontree.engine.leaf import Status
from missiontree.reasoning.calls import CALLER_KEY, LatencyModel, ModelCaller
from missiontree.types import Pose2D


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
    """With nobody in view the detector runs on every frame and the VLM is never asked."""
    robot = FakeRobot()
    leaf, _, models = setup_leaf(robot)
    for _ in range(10):
        step(robot, leaf, None)
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
    step(robot, leaf, math.radians(10))
    assert leaf.status == Status.RUNNING
    assert "1 waiting" in leaf.feedback_message
    for _ in range(3):
        step(robot, leaf, math.radians(10))
    assert events.of("alarm") == []
    for _ in range(3):
        step(robot, leaf, math.radians(10))
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
    leaf, _, models = setup_leaf(robot, latency=0.2, min_hits=2)
    step(robot, leaf, 0.0)
    for _ in range(10):
        step(robot, leaf, None)
    assert models["vlm"].asked == 0
    step(robot, leaf, 0.0)
    step(robot, leaf, 0.0)
    assert models["vlm"].asked == 1
