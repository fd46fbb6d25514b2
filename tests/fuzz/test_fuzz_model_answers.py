"""Fuzzing every schema that reads a model's answer: a value that holds, or a clear rejection.

A model's answer is text from outside: malformed JSON, NaN and infinities (which Python's JSON
reader accepts), huge numbers, boxes far outside the image, ids that do not exist, deep nesting,
wrong types. Whatever it is, :func:`~missiontree.reasoning.checks.validate_answer` returns a value
that keeps the schema's promises (finite numbers, boxes inside the image asked about, only known
ids) or raises ValueError with the reason; the checked-answer helpers return a CheckedAnswer or
raise RejectedAnswerError; a detector's answer is filtered by ``checked_detections``; and the
Surveillance leaf, fed such answers, neither raises nor alarms at an impossible bearing.
Budget: the ``ci`` profile in CI, ``MISSIONTREE_FUZZ=nightly`` for 10,000 cases a test.
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path
from typing import Any

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from pydantic import BaseModel
from strategies import HOSTILE_NUMBERS, NUMBERS, SCALARS, mutations, values

from missiontree.perception.detectors import checked_detections
from missiontree.reasoning import schemas
from missiontree.reasoning.checks import CheckedAnswer, RejectedAnswerError, ask_checked, validate_answer
from missiontree.types import Detection

#: Every answer schema of the reasoning layer (any schema added later is fuzzed too).
SCHEMAS: list[type[schemas._Answer]] = sorted(
    (c for c in vars(schemas).values()
     if isinstance(c, type) and issubclass(c, schemas._Answer) and c is not schemas._Answer),
    key=lambda c: c.__name__)

#: A valid answer of each known schema, the base the mutations start from.
VALID: dict[str, dict[str, Any]] = {
    "PersonBox": {"box": [10, 20, 60, 200], "score": 0.9},
    "SurveillanceVerdict": {"verdict": "ALARM", "description": "a person on the left",
                            "people": [{"box": [10, 20, 60, 200], "score": 0.9},
                                       {"box": [200, 0, 320, 240], "score": 0.5}]},
    "CropMatch": {"matches": True, "confidence": 0.8, "reason": "a red backpack"},
    "RoomClassification": {"room_type": "kitchen", "confidence": 0.7, "evidence": ["sink", "cup"]},
    "ObjectDescription": {"label": "cup", "colour": "red", "size": "small", "shape": "round",
                          "description": "a red cup"},
    "ReferenceParse": {"label": "backpack", "attributes": ["grey"], "relation": "in_front_of",
                       "anchor": "sofa"},
    "IntentResolution": {"candidates": ["obj_1", "obj_2"], "reason": "both hold water",
                         "reference": {"label": "cup", "attributes": [], "relation": None, "anchor": None}},
}
BASES = [VALID.get(s.__name__, {}) for s in SCHEMAS]
VALID_IDS = ["obj_1", "obj_2", "obj_3"]
WIDTH, HEIGHT = 320, 240
KEYS = st.sampled_from(sorted({k for v in VALID.values() for k in v} | {"box", "score", "verdict"}))


def _dump(value: Any) -> str:
    """JSON text as a model might write it (NaN and Infinity included, as Python writes them)."""
    try:
        return json.dumps(value)
    except (TypeError, ValueError, OverflowError):
        return str(value)


#: Answer bodies: a mutated valid answer, random JSON, random text, known hostile answers (built once).
BODIES = st.one_of(
    mutations(BASES).map(_dump),
    values(keys=KEYS, depth=4).map(_dump),
    st.text(max_size=200),
    st.sampled_from(["", "{", "[]", "null", "NaN", "[" * 5000, '{"a": ' * 3000 + "1",
                     '{"verdict": "ALARM", "people": [{"box": [90000, 90000, 90050, 90100]}]}',
                     '{"verdict": "ALARM", "people": [{"box": [NaN, 0, 10, 10]}]}',
                     '{"verdict": "ALARM", "people": [{"box": [-Infinity, 0, 1e308, 10]}]}',
                     '{"matches": true, "confidence": NaN}',
                     '{"candidates": ["no_such_object"]}']),
)
WRAPS = st.sampled_from(["plain", "fence", "prose", "cut"])


@st.composite
def answer_texts(draw: Any) -> str:
    """Answer text: one of :data:`BODIES`, fenced, in prose or cut short."""
    body = draw(BODIES)
    wrap = draw(WRAPS)
    if wrap == "fence":
        return f"Here you go:\n```json\n{body}\n```"
    if wrap == "prose":
        return f"Sure! {body} Hope this helps."
    if wrap == "cut":
        return body[: draw(st.integers(0, max(0, len(body))))]
    return body


def _all_finite(value: Any) -> bool:
    if isinstance(value, float):
        return math.isfinite(value)
    if isinstance(value, dict):
        return all(_all_finite(v) for v in value.values())
    if isinstance(value, list | tuple):
        return all(_all_finite(v) for v in value)
    return True


def _keeps_its_promises(value: BaseModel, image_size: tuple[int, int] | None, ids: bool = True) -> None:
    data = value.model_dump()
    assert _all_finite(data), data
    for person in data.get("people", []) or []:
        x1, y1, x2, y2 = person["box"]
        assert x1 <= x2 and y1 <= y2
        if image_size is not None:
            assert 0 <= x1 <= WIDTH and 0 <= x2 <= WIDTH and 0 <= y1 <= HEIGHT and 0 <= y2 <= HEIGHT
    for text_field in ("description", "reason"):
        assert len(data.get(text_field, "") or "") <= schemas.MAX_TEXT
    if ids and isinstance(value, schemas.IntentResolution):
        assert set(value.candidates) <= set(VALID_IDS)


@given(answer_texts(), st.sampled_from(SCHEMAS), st.booleans(), st.booleans())
def test_every_answer_is_a_sound_value_or_a_clear_rejection(
        text: str, schema: type[BaseModel], with_ids: bool, with_image: bool) -> None:
    """validate_answer returns a value that keeps the schema's promises, or raises ValueError."""
    image_size = (WIDTH, HEIGHT) if with_image else None
    try:
        value = validate_answer(text, schema, VALID_IDS if with_ids else None, image_size)
    except ValueError as exc:
        assert str(exc)  # a reason that can be fed back to the model
        return
    assert isinstance(value, schema)
    _keeps_its_promises(value, image_size, ids=with_ids)


@given(st.text(max_size=300))
def test_free_text_verdicts_never_crash(text: str) -> None:
    """Seed 001's free-text form is read into a verdict whatever the text."""
    verdict = schemas.SurveillanceVerdict.from_text(text)
    assert verdict.verdict in ("ALARM", "SAFE")


class _Scripted:
    """A vision-language model answering from a list (the fuzzed answers)."""

    name = "fuzzed-vlm"

    def __init__(self, answers: list[str]) -> None:
        self.answers = list(answers)

    def ask(self, images: Any, prompt: str, schema: Any = None) -> str:
        return self.answers.pop(0) if self.answers else ""

    def check(self) -> str:
        return "scripted"


@given(st.lists(answer_texts(), min_size=2, max_size=2), st.sampled_from(SCHEMAS))
def test_checked_asking_ends_in_an_answer_or_a_rejection(answers: list[str], schema: type[BaseModel]) -> None:
    """ask_checked (retry once with the reason) returns a CheckedAnswer or raises RejectedAnswerError."""
    image = np.zeros((HEIGHT, WIDTH, 3), dtype=np.uint8)
    try:
        result = ask_checked(_Scripted(answers), [image], "question", schema, valid_ids=VALID_IDS)
    except RejectedAnswerError as exc:
        assert exc.attempts == 2 and len(exc.rejected) == 2
        return
    assert isinstance(result, CheckedAnswer) and result.attempts in (1, 2)
    _keeps_its_promises(result.value, (WIDTH, HEIGHT))


BOX_NUMBERS = st.one_of(NUMBERS, HOSTILE_NUMBERS, st.floats(-50, 400))
DETECTIONS = st.lists(st.one_of(
    st.builds(Detection, label=st.sampled_from(["person", "cup", ""]), score=BOX_NUMBERS,
              box=st.tuples(BOX_NUMBERS, BOX_NUMBERS, BOX_NUMBERS, BOX_NUMBERS)),
    SCALARS,
), max_size=8)


@given(st.one_of(DETECTIONS, SCALARS))
def test_a_detectors_answer_is_filtered_to_usable_boxes(answer: Any) -> None:
    """checked_detections keeps only finite boxes inside the image, with scores in [0, 1]."""
    kept, dropped = checked_detections(answer, WIDTH, HEIGHT, "fuzzed")
    for det in kept:
        x1, y1, x2, y2 = det.box
        assert all(math.isfinite(v) for v in det.box) and 0.0 <= det.score <= 1.0
        assert 0 <= x1 < x2 <= WIDTH and 0 <= y1 < y2 <= HEIGHT
    assert all(isinstance(reason, str) and reason for reason in dropped)


# -- the leaf that acts on the answers ---------------------------------------------------------------

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "behaviours"))  # the behaviour test doubles


@settings(max_examples=max(10, settings().max_examples // 10))
@given(st.lists(answer_texts(), min_size=1, max_size=4), st.lists(DETECTIONS, min_size=1, max_size=3))
def test_surveillance_fed_hostile_answers_never_crashes_nor_alarms_off_the_image(
        answers: list[str], detections: list[list[Any]]) -> None:
    """Fuzzed detector and VLM answers: no leaf error, no traceback, alarms only at real bearings."""
    from patrol_doubles import Events, FakeRobot, person_frame

    from missiontree.behaviours.surveillance import Surveillance
    from missiontree.engine.context import MissionContext
    from missiontree.engine.leaf import Status
    from missiontree.reasoning.calls import CALLER_KEY, ModelCaller

    class Detector:
        name, labels = "fuzzed-detector", ["person"]

        def __init__(self) -> None:
            self.calls = 0

        def detect(self, image: Any) -> Any:
            self.calls += 1
            return detections[self.calls % len(detections)]

    robot, events = FakeRobot(), Events()
    models: dict[str, Any] = {"detector": Detector(), "vlm": _Scripted(answers * 10)}
    caller = ModelCaller(robot.now, events, simulated=True, models=models)
    models[CALLER_KEY] = caller
    leaf = Surveillance("watch", Surveillance.Params(lidar_check=False, period=0.2, max_failed_calls=50))
    leaf.setup(context=MissionContext(robot=robot, models=models, events=events))
    try:
        for _ in range(8):
            robot.advance(0.2)
            robot.frame = person_frame(robot.time, robot.current, 0.1)
            leaf.tick_once()
    finally:
        leaf.stop(Status.INVALID)
        caller.close()
    assert events.of("error") == [], events.of("error")
    for alarm in events.of("alarm"):
        assert alarm["box"] is None or all(0 <= v <= WIDTH for v in alarm["box"])
        assert alarm["bearing"] is None or abs(alarm["bearing"]) <= math.radians(40)
