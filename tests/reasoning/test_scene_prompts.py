"""The crop verifier: the VLM asked whether the 20 % larger crop shows the detector's label."""

from __future__ import annotations

import numpy as np

from missiontree.errors import ModelError
from missiontree.reasoning.scene_prompts import crop_verifier
from missiontree.types import CameraIntrinsics, Detection, Pose2D, RGBDFrame

K = CameraIntrinsics(width=100, height=80, fx=70.0, fy=70.0, cx=49.5, cy=39.5)
FRAME = RGBDFrame(1.0, np.zeros((80, 100, 3), np.uint8), np.ones((80, 100), np.float32), K, Pose2D(0, 0, 0))


class Vlm:
    def __init__(self, answer: str | Exception) -> None:
        self.answer = answer
        self.calls: list[tuple[tuple[int, ...], str]] = []

    def ask(self, images, prompt, schema=None) -> str:
        self.calls.append((images[0].shape, prompt))
        if isinstance(self.answer, Exception):
            raise self.answer
        return self.answer


def test_the_answer_decides_on_a_crop_20_percent_larger() -> None:
    yes = Vlm('{"matches": true, "confidence": 0.9, "reason": "a cup"}')
    assert crop_verifier(yes)(FRAME, Detection("cup", 0.8, (40, 30, 60, 50))) is True
    shape, prompt = yes.calls[0]
    assert shape == (24, 24, 3) and '"cup"' in prompt
    no = Vlm('{"matches": false, "confidence": 0.9, "reason": "a sink"}')
    assert crop_verifier(no)(FRAME, Detection("chair", 0.8, (40, 30, 60, 50))) is False


def test_no_answer_leaves_it_to_the_detector() -> None:
    box = (40, 30, 60, 50)
    assert crop_verifier(Vlm(ModelError("down")))(FRAME, Detection("cup", 0.8, box)) is None
    assert crop_verifier(Vlm("not json"))(FRAME, Detection("cup", 0.8, box)) is None
    assert crop_verifier(Vlm("{}"))(FRAME, Detection("cup", 0.8, (200, 200, 220, 220))) is None
