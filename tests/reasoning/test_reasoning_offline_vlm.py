"""Tests of the offline VLM stand-in: answers from a detector's boxes and the colour measured in them."""

from __future__ import annotations

import numpy as np
import pytest

from missiontree.errors import ModelError
from missiontree.reasoning.checks import ask_checked
from missiontree.reasoning.prompts import (
    crop_match_prompt,
    object_description_prompt,
    room_prompt,
    surveillance_prompt,
)
from missiontree.reasoning.providers.offline_vlm import OfflineVisionModel
from missiontree.reasoning.schemas import (
    CropMatch,
    ObjectDescription,
    RoomClassification,
    SurveillanceVerdict,
)
from missiontree.types import Detection

GREY = (128, 128, 128)
RED = (220, 20, 20)


class BoxDetector:
    """Reports fixed boxes (a fake of the layer below); records the images it saw."""

    name = "boxes"

    def __init__(self, *detections: Detection) -> None:
        self.detections = list(detections)
        self.seen: list[np.ndarray] = []

    @property
    def labels(self) -> list[str]:
        return ["person", "backpack", "chair", "sink", "cup", "laptop", "sofa"]

    def detect(self, image: np.ndarray) -> list[Detection]:
        self.seen.append(image)
        return list(self.detections)


Box = tuple[int, int, int, int]


def verdict_of(vlm: OfflineVisionModel) -> SurveillanceVerdict:
    answer = vlm.ask([scene()], surveillance_prompt(), SurveillanceVerdict)
    return SurveillanceVerdict.model_validate_json(answer)


def scene(box: Box = (20, 20, 60, 80), colour: tuple[int, int, int] = GREY) -> np.ndarray:
    image = np.full((100, 120, 3), (40, 90, 200), dtype=np.uint8)  # blue wall
    x1, y1, x2, y2 = box
    image[y1:y2, x1:x2] = colour
    return image


def test_person_detected_means_alarm_with_boxes() -> None:
    """A detected person gives ALARM with their box and seed 001's text form."""
    vlm = OfflineVisionModel(BoxDetector(Detection("person", 0.9, (80.0, 10.0, 110.0, 90.0))))
    verdict = verdict_of(vlm)
    assert verdict.alarm
    assert verdict.people[0].box == (80.0, 10.0, 110.0, 90.0)
    assert verdict.as_text().startswith("ALARM: PERSON DETECTED")
    assert "on the right" in verdict.description


def test_no_person_means_safe() -> None:
    """Without a person the verdict is SAFE and lists what was seen instead."""
    vlm = OfflineVisionModel(BoxDetector(Detection("chair", 0.9, (0.0, 0.0, 10.0, 10.0))))
    verdict = verdict_of(vlm)
    assert not verdict.alarm and "chair" in verdict.description


def test_low_score_person_is_ignored() -> None:
    """A person below min_score does not raise the alarm."""
    vlm = OfflineVisionModel(BoxDetector(Detection("person", 0.3, (0.0, 0.0, 10.0, 10.0))), min_score=0.5)
    assert '"SAFE"' in vlm.ask([scene()], surveillance_prompt(), SurveillanceVerdict)


def test_free_text_person_prompt_answers_in_seed_form() -> None:
    """Without a schema, seed 001's prompt gets seed 001's free-text answer."""
    vlm = OfflineVisionModel(BoxDetector(Detection("person", 0.9, (0.0, 0.0, 30.0, 30.0))))
    assert vlm.ask([scene()], surveillance_prompt()).startswith("ALARM: PERSON DETECTED")


def test_crop_matches_grey_backpack_by_measured_colour() -> None:
    """A backpack box that is grey inside matches "grey backpack"."""
    detector = BoxDetector(Detection("backpack", 0.8, (20.0, 20.0, 60.0, 80.0)))
    match = CropMatch.model_validate_json(
        OfflineVisionModel(detector).ask([scene(colour=GREY)], crop_match_prompt("grey backpack"), CropMatch))
    assert match.matches and "grey backpack" in match.reason


def test_crop_of_red_backpack_does_not_match_grey() -> None:
    """A red backpack does not match "grey backpack"; the reason says the colour measured."""
    detector = BoxDetector(Detection("backpack", 0.8, (20.0, 20.0, 60.0, 80.0)))
    match = CropMatch.model_validate_json(
        OfflineVisionModel(detector).ask([scene(colour=RED)], crop_match_prompt("gray backpack"), CropMatch))
    assert not match.matches and "red, not grey" in match.reason


def test_crop_without_the_label_does_not_match() -> None:
    """A crop where only a chair is detected does not match "grey backpack"."""
    detector = BoxDetector(Detection("chair", 0.8, (20.0, 20.0, 60.0, 80.0)))
    match = CropMatch.model_validate_json(
        OfflineVisionModel(detector).ask([scene()], crop_match_prompt("grey backpack"), CropMatch))
    assert not match.matches and match.reason == "no backpack detected"


def test_room_voted_by_objects() -> None:
    """A sink and a cup make a kitchen; a laptop of the same size alone cannot outvote them."""
    detector = BoxDetector(Detection("sink", 0.9, (0, 0, 9, 10)), Detection("cup", 0.8, (10, 0, 19, 10)),
                           Detection("laptop", 0.9, (20, 0, 29, 10)))
    room = RoomClassification.model_validate_json(
        OfflineVisionModel(detector).ask([scene()], room_prompt(), RoomClassification))
    assert room.room_type == "kitchen"
    assert room.evidence == ["cup", "sink"]
    assert room.confidence == pytest.approx(1.7 / 2.6, abs=1e-3)


def test_near_objects_outvote_far_ones() -> None:
    """One large (near) desk outvotes two small (far) kitchen objects seen through a doorway."""
    detector = BoxDetector(Detection("desk", 0.9, (0, 30, 60, 100)), Detection("sink", 0.9, (70, 40, 75, 50)),
                           Detection("cup", 0.9, (80, 40, 85, 50)))
    room = RoomClassification.model_validate_json(
        OfflineVisionModel(detector).ask([scene()], room_prompt(), RoomClassification))
    assert room.room_type == "office"


def test_room_unknown_without_evidence() -> None:
    """With nothing telling detected, the room is unknown with confidence 0."""
    room = RoomClassification.model_validate_json(
        OfflineVisionModel(BoxDetector()).ask([scene()], room_prompt(), RoomClassification))
    assert room.room_type == "unknown" and room.confidence == 0.0


def test_object_description_measures_colour_and_shape() -> None:
    """A tall red box labelled backpack is described as a red, tall, medium backpack."""
    detector = BoxDetector(Detection("backpack", 0.9, (20.0, 20.0, 60.0, 90.0)))
    description = ObjectDescription.model_validate_json(OfflineVisionModel(detector).ask(
        [scene((20, 20, 60, 90), RED)], object_description_prompt("backpack"), ObjectDescription))
    assert (description.label, description.colour, description.shape, description.size) == (
        "backpack", "red", "tall", "medium")


def test_answers_pass_the_checks() -> None:
    """Every schema the stand-in answers validates through the checks in one attempt."""
    vlm = OfflineVisionModel(BoxDetector(Detection("backpack", 0.9, (20.0, 20.0, 60.0, 80.0))))
    for prompt, schema in ((surveillance_prompt(), SurveillanceVerdict), (room_prompt(), RoomClassification),
                           (crop_match_prompt("grey backpack"), CropMatch),
                           (object_description_prompt("backpack"), ObjectDescription)):
        assert ask_checked(vlm, [scene()], prompt, schema).attempts == 1


def test_empty_image_names_provider_and_fix() -> None:
    """An empty image is refused with the provider's name and what to pass instead."""
    vlm = OfflineVisionModel(BoxDetector())
    with pytest.raises(ValueError, match="offline_vlm: expected a non-empty HxWx3 image.*robot.rgbd"):
        vlm.ask([np.zeros((0, 0, 3), np.uint8)], surveillance_prompt(), SurveillanceVerdict)


def test_no_images_is_an_error() -> None:
    """Asking about no image at all says so."""
    with pytest.raises(ModelError, match="expected at least one image"):
        OfflineVisionModel(BoxDetector()).ask([], "hi")


def test_unsupported_schema_names_what_it_answers() -> None:
    """A schema the stand-in cannot answer is refused, listing what it can and what to configure."""
    from missiontree.reasoning.schemas import IntentResolution

    with pytest.raises(ModelError, match="IntentResolution schema.*configure a VLM provider"):
        OfflineVisionModel(BoxDetector()).ask([scene()], "which?", IntentResolution)


def test_class_the_detector_cannot_see_is_no_match_with_zero_confidence() -> None:
    """A description naming no class the detector knows is not a match, with confidence 0 and why."""
    prompt = crop_match_prompt("red fire extinguisher")
    match = CropMatch.model_validate_json(OfflineVisionModel(BoxDetector()).ask([scene()], prompt, CropMatch))
    assert not match.matches and match.confidence == 0.0
    assert "knows no class in 'red fire extinguisher'" in match.reason


def test_non_finite_and_outside_detector_boxes_are_dropped_before_answering() -> None:
    """A detector answering NaN/inf boxes and a box far outside the image: only the real person is boxed."""
    vlm = OfflineVisionModel(BoxDetector(
        Detection("person", 0.95, (float("nan"), 10.0, 50.0, 90.0)),
        Detection("person", 0.95, (90000.0, 90000.0, 90010.0, 90010.0)),
        Detection("person", float("inf"), (1.0, 1.0, 5.0, 5.0)),
        Detection("person", 0.9, (80.0, 10.0, 130.0, 90.0)),  # reaches past the 120 px edge: clipped
    ))
    verdict = verdict_of(vlm)
    assert verdict.alarm and [p.box for p in verdict.people] == [(80.0, 10.0, 120.0, 90.0)]
