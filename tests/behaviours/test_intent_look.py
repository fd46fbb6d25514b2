"""The intent leaf's look on arrival: what the vision-language model is shown to confirm the object."""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from missiontree.behaviours import intent_look
from missiontree.behaviours.intent import GoToIntent
from missiontree.reasoning.calls import CallStatus
from missiontree.reasoning.intent import Candidate
from missiontree.types import Detection, Pose2D


class DoneCall:
    """A finished detector call returning fixed detections."""

    def __init__(self, detections: list[Detection]) -> None:
        self.detections = detections

    def status(self) -> CallStatus:
        return CallStatus.SUCCEEDED

    def result(self) -> list[Detection]:
        return self.detections


def test_a_lone_detection_is_confirmed_on_its_own_region_not_the_whole_frame(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The only chair the detector reports is asked about alone: a blue neighbour it missed cannot answer."""
    color = np.zeros((240, 320, 3), np.uint8)
    color[100:200, 20:60] = (20, 40, 220)    # a blue chair the detector scored below its threshold
    color[100:200, 200:240] = (220, 30, 30)  # the red chair it reports
    chair = Detection("chair", 0.9, (200.0, 100.0, 240.0, 200.0))
    asked: list[Any] = []

    def ask(role: str, images: list[np.ndarray], *args: Any, **kwargs: Any) -> object:
        asked.append(images)
        return SimpleNamespace()

    caller = SimpleNamespace(ask=ask)
    monkeypatch.setattr(intent_look, "model_caller", lambda context: caller)
    monkeypatch.setattr(intent_look, "match_detection", lambda dets, *a, **k: (dets[0], ""))
    leaf = GoToIntent("go", GoToIntent.Params(scene_graph=""))
    leaf._reset()
    leaf.wanted = "blue chair"
    leaf.target = Candidate("chair_3", "chair", (2.0, 0.0), Pose2D(1.0, 0.0, 0.0), 1.0, 1.0)
    leaf.frame = SimpleNamespace(color=color, stamp=1.0)  # type: ignore[assignment]
    leaf.call = DoneCall([chair])  # type: ignore[assignment]
    leaf.ctx = SimpleNamespace()  # type: ignore[assignment]
    leaf._detected()
    [images] = asked
    shown = images[0]
    assert (shown[150, 220] == color[150, 220]).all()   # the reported chair is shown
    assert not (shown[150, 40] == color[150, 40]).all()  # the missed blue one is painted out
