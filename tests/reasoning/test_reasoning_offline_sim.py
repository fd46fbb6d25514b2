"""The offline VLM stand-in on rendered simulator frames, seeing through the simulation oracle detector."""

from __future__ import annotations

import pytest

from missiontree.backends.sim import create_robot
from missiontree.engine.context import MissionContext
from missiontree.engine.leaf import Leaf, Status
from missiontree.perception.oracle import OracleDetector
from missiontree.plugins.manager import load_plugins
from missiontree.reasoning.calls import CallStatus, model_caller
from missiontree.reasoning.checks import ask_checked
from missiontree.reasoning.prompts import crop_match_prompt, room_prompt, surveillance_prompt
from missiontree.reasoning.providers.offline_vlm import OfflineVisionModel
from missiontree.reasoning.schemas import CropMatch, RoomClassification, SurveillanceVerdict
from missiontree.session.models import build_models
from missiontree.testing import capture_tick_log


def frame_and_vlm(world: str, t: float = 0.2) -> tuple[object, OfflineVisionModel]:
    robot = create_robot({"world": world, "seed": 0})
    robot.spin_until(t)
    frame = robot.rgbd()
    assert frame is not None
    return frame, OfflineVisionModel(OracleDetector(robot))


def test_walker_in_the_corridor_raises_the_alarm() -> None:
    """In the corridor world a person walks in view: ALARM with their box."""
    frame, vlm = frame_and_vlm("corridor")
    verdict = ask_checked(vlm, [frame.color], surveillance_prompt(), SurveillanceVerdict).value
    assert verdict.alarm and len(verdict.people) == 1


def test_office_view_without_people_is_safe_and_an_office() -> None:
    """The office world's first view holds no person and shows an office."""
    frame, vlm = frame_and_vlm("office")
    assert not ask_checked(vlm, [frame.color], surveillance_prompt(), SurveillanceVerdict).value.alarm
    assert ask_checked(vlm, [frame.color], room_prompt(), RoomClassification).value.room_type == "office"


@pytest.mark.parametrize(("description", "expected"), [
    ("red backpack", True), ("grey backpack", False), ("brown sofa", True), ("grey sofa", False),
])
def test_colour_of_rendered_objects_decides_the_match(description: str, expected: bool) -> None:
    """The colour measured on the rendered objects (the world says red backpack, brown sofa) decides."""
    frame, vlm = frame_and_vlm("office")
    answer = ask_checked(vlm, [frame.color], crop_match_prompt(description), CropMatch)
    assert answer.value.matches is expected


class Surveil(Leaf):
    """Asks the vlm about the current camera frame; SUCCESS on ALARM (test leaf of the layer above)."""

    def initialise(self) -> None:
        frame = self.context.robot.rgbd()
        self.call = model_caller(self.context).ask("vlm", [frame.color], surveillance_prompt(),
                                                   SurveillanceVerdict, node=self.name)

    def update(self) -> Status:
        status = self.call.status()
        if not status.done:
            return self.running()
        if status is not CallStatus.SUCCEEDED:
            return self.fail(self.call.error())
        return self.succeed() if self.call.result().value.alarm else self.fail("no person")


def test_mission_on_the_oracle_config_binds_and_alarms() -> None:
    """On the shipped oracle config a mission binds the oracle to the sim robot and sees the walker."""
    robot = create_robot({"world": "corridor", "seed": 0})
    models = build_models("oracle", load_plugins(autoload=False).providers, seed=0)
    context = MissionContext(robot=robot, models=models, seed=0)
    result, log = capture_tick_log(Surveil("surveil"), context, tick_hz=10.0)
    robot.close()
    assert result.status == Status.SUCCESS
    (call,) = [line for line in log if line.get("event") == "model_call"]
    assert call["outcome"] == "succeeded" and 0.5 <= call["latency"] <= 3.0
