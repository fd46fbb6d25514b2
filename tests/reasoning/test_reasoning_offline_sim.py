"""The offline VLM stand-in on rendered simulator frames, seeing through the simulation oracle detector."""

from __future__ import annotations

import pytest

from missiontree.backends.sim import create_robot
from missiontree.perception.oracle import OracleDetector
from missiontree.reasoning.checks import ask_checked
from missiontree.reasoning.offline_vlm import OfflineVisionModel
from missiontree.reasoning.prompts import crop_match_prompt, room_prompt, surveillance_prompt
from missiontree.reasoning.schemas import CropMatch, RoomClassification, SurveillanceVerdict


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
