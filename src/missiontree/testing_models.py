"""Conformance suites for model providers, as pytest tests: run them on your provider too.

One class per model protocol — :class:`DetectorConformance`, :class:`VisionLanguageModelConformance`,
:class:`LanguageModelConformance`, :class:`EmbedderConformance`. A provider's test module subclasses
the one for its protocol and gives the provider as a fixture; every built-in provider and the
example plugin's ``colour_blob`` run the same suites::

    from missiontree.testing_models import DetectorConformance

    class TestMyDetector(DetectorConformance):
        @pytest.fixture
        def detector(self):
            return create_my_detector({"colour": "red"})

What they check, on every provider:

- **Shapes and types**: the protocol is implemented (``name``, ``check()``, the call), detections are
  :class:`~missiontree.types.Detection` with labels the detector lists, finite scores in [0, 1] best
  first, boxes finite, ordered and *inside the image* whatever its size; embeddings are float32
  ``(n, dim)`` rows of unit length, the same text giving the same row; answers are text.
- **Schema-checked answers**: asked with a schema (the suite's ``schema`` and ``prompt``, which a
  provider that answers only some schemas overrides), the answer passes
  :func:`missiontree.reasoning.checks.validate_answer` — JSON of the schema, boxes inside the image.
- **Bad input**: an image that is not HxWx3 uint8 is a clear ``ValueError`` (``ModelConfigError``
  is one) naming the provider, never another exception from deep inside.
- **Timeouts honoured**: through :class:`~missiontree.reasoning.calls.ModelCaller` (how leaves call
  models) a call that outlives its timeout ends ``TIMED_OUT`` without holding the caller, and the
  provider answers the next call; a provider that takes a timeout itself (an HTTP client) raises
  within it when made slow (the ``slow`` fixture; skipped unless given).
- **Cancellation**: a cancelled call ends ``CANCELLED``, its result is dropped, and the provider
  keeps answering correctly afterwards.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable, Iterator
from typing import Any

import numpy as np
import pytest
from pydantic import BaseModel, Field

from missiontree.reasoning.calls import CallStatus, ModelCaller
from missiontree.types import Detection

#: Wall seconds a conformance call may take before the suite calls the provider too slow.
CALL_BUDGET = 60.0


def scene_image(height: int = 240, width: int = 320) -> np.ndarray:
    """A plain test scene: grey floor and wall, a red box, a blue cylinder-like bar, a person-ish figure."""
    image = np.full((height, width, 3), 170, np.uint8)
    image[: height // 2] = (200, 198, 190)
    h, w = height, width
    image[int(h * 0.45):int(h * 0.8), int(w * 0.1):int(w * 0.3)] = (200, 30, 30)
    image[int(h * 0.3):int(h * 0.85), int(w * 0.45):int(w * 0.52)] = (30, 50, 200)
    image[int(h * 0.25):int(h * 0.9), int(w * 0.7):int(w * 0.8)] = (60, 60, 70)
    image[int(h * 0.15):int(h * 0.27), int(w * 0.72):int(w * 0.78)] = (210, 170, 140)
    return image


def _wait(call: Any, budget: float = CALL_BUDGET) -> CallStatus:
    deadline = time.monotonic() + budget
    while not call.status().done:
        if time.monotonic() > deadline:
            pytest.fail(f"the call did not end within {budget:g} s")
        time.sleep(0.005)
    return call.status()  # type: ignore[no-any-return]


class _CallConformance:
    """Timeout and cancellation through the ModelCaller, shared by every protocol's suite."""

    @pytest.fixture
    def provider(self) -> Any:
        """The provider under test (each protocol's suite maps its own fixture onto this)."""
        raise NotImplementedError  # pragma: no cover

    def good_call(self, provider: Any) -> Callable[[], Any]:
        """A call the provider answers, and :meth:`check_answer` accepts."""
        raise NotImplementedError  # pragma: no cover

    def check_answer(self, answer: Any) -> None:
        """Assert that ``answer`` is a good answer to :meth:`good_call`."""
        raise NotImplementedError  # pragma: no cover

    @staticmethod
    def _caller() -> ModelCaller:
        return ModelCaller(time.monotonic, workers=1, default_timeout=None)

    def test_model_answers_within_the_call_budget(self, provider: Any) -> None:
        """Through the caller (as leaves call it), the provider answers well within the budget."""
        caller = self._caller()
        try:
            call = caller.submit("role", self.good_call(provider), timeout=CALL_BUDGET)
            assert _wait(call) is CallStatus.SUCCEEDED, call.error()
            self.check_answer(call.result())
        finally:
            caller.close()

    def test_model_timeout_ends_the_call_and_the_provider_still_answers(self, provider: Any) -> None:
        """A call that outlives its timeout ends TIMED_OUT at once; the provider answers the next one."""
        caller = self._caller()
        gate = threading.Event()
        try:
            blocker = caller.submit("role", gate.wait, 10.0, timeout=None)  # holds the only worker
            call = caller.submit("role", self.good_call(provider), timeout=0.05)
            time.sleep(0.1)
            started = time.monotonic()
            assert call.status() is CallStatus.TIMED_OUT
            assert time.monotonic() - started < 0.5, "polling a timed-out call held the caller"
            assert "timed out" in call.error() or "timeout" in call.error().lower()
            gate.set()
            _wait(blocker)
            again = caller.submit("role", self.good_call(provider), timeout=CALL_BUDGET)
            assert _wait(again) is CallStatus.SUCCEEDED, again.error()
            self.check_answer(again.result())
        finally:
            gate.set()
            caller.close()

    def test_model_cancelled_call_drops_its_result_and_the_provider_still_answers(self,
                                                                                 provider: Any) -> None:
        """cancel() ends the call CANCELLED (a running provider's result is dropped); later calls work."""
        caller = self._caller()
        try:
            running = caller.submit("role", self.good_call(provider), timeout=None)
            running.cancel()
            assert running.status() is CallStatus.CANCELLED and running.error() == "cancelled"
            running.cancel()  # idempotent
            assert running.status() is CallStatus.CANCELLED
            again = caller.submit("role", self.good_call(provider), timeout=CALL_BUDGET)
            assert _wait(again) is CallStatus.SUCCEEDED, again.error()
            self.check_answer(again.result())
        finally:
            caller.close()

    @pytest.fixture
    def slow(self) -> Iterator[tuple[Callable[[], Any], float]]:
        """A call to the provider made slow on purpose, and the timeout the provider was given.

        Override for providers that take a timeout (``factory.wants_timeout``); skipped otherwise.
        """
        pytest.skip("this provider takes no timeout of its own (the caller's applies)")
        yield  # pragma: no cover

    def test_model_own_timeout_is_honoured(self, slow: tuple[Callable[[], Any], float]) -> None:
        """A provider given a timeout raises within it (plus slack) when the model is slower."""
        from missiontree.errors import ModelError

        call, timeout = slow
        started = time.monotonic()
        with pytest.raises(ModelError):
            call()
        assert time.monotonic() - started < timeout * 2 + 1.0


class DetectorConformance(_CallConformance):
    """Tests every Detector provider passes. Override the ``detector`` fixture.

    Class attributes a subclass may change: ``expect_detections`` (the provider finds something in
    the ``image`` fixture, which it may override with a scene its model knows).
    """

    #: Whether the provider must find at least one object in the ``image`` fixture.
    expect_detections: bool = True

    @pytest.fixture
    def detector(self) -> Any:
        """The detector under test; subclasses override this."""
        raise NotImplementedError("a detector's conformance class must override the `detector` fixture")

    @pytest.fixture
    def provider(self, detector: Any) -> Any:
        """The detector, for the shared call tests."""
        return detector

    @pytest.fixture
    def image(self) -> np.ndarray:
        """An image the detector should find something in (override with a scene its model knows)."""
        return scene_image()

    def good_call(self, provider: Any) -> Callable[[], Any]:
        """detect() on the plain scene."""
        return lambda: provider.detect(scene_image())

    def check_answer(self, answer: Any) -> None:
        """A list of Detection."""
        assert isinstance(answer, list) and all(isinstance(d, Detection) for d in answer)

    def _check(self, detector: Any, found: Any, height: int, width: int) -> None:
        assert isinstance(found, list), f"detect() returned {type(found).__name__}, not a list"
        labels = set(detector.labels)
        scores = []
        for d in found:
            assert isinstance(d, Detection), f"detect() returned a {type(d).__name__}, not a Detection"
            assert d.label in labels, f"label {d.label!r} is not in the detector's labels"
            assert isinstance(d.score, float | int) and math.isfinite(d.score) and 0.0 <= d.score <= 1.0, d
            assert len(d.box) == 4 and all(math.isfinite(v) for v in d.box), f"box not finite: {d.box}"
            x1, y1, x2, y2 = d.box
            assert 0.0 <= x1 < x2 <= width and 0.0 <= y1 < y2 <= height, \
                f"box {d.box} is not inside the {width}x{height} image"
            if d.mask is not None:
                assert d.mask.shape == (height, width) and d.mask.dtype == bool
            scores.append(float(d.score))
        assert scores == sorted(scores, reverse=True), "detections are not best score first"

    def test_detector_implements_the_protocol(self, detector: Any) -> None:
        """A Detector: a name, a non-empty list of labels, check() says what it is."""
        from missiontree.perception.detectors import Detector

        assert isinstance(detector, Detector)
        assert isinstance(detector.name, str) and detector.name
        labels = detector.labels
        assert isinstance(labels, list) and labels and all(isinstance(x, str) and x for x in labels)
        assert isinstance(detector.check(), str) if hasattr(detector, "check") else True

    def test_detector_finds_objects_with_boxes_inside_the_image(self, detector: Any,
                                                                image: np.ndarray) -> None:
        """Detections in the test image are well formed; some are found when expected."""
        found = detector.detect(image)
        self._check(detector, found, image.shape[0], image.shape[1])
        if self.expect_detections:
            assert found, "nothing detected in the test image (override `image` with a scene the model knows)"

    @pytest.mark.parametrize("shape", [(97, 211), (480, 64), (16, 16)])
    def test_detector_boxes_stay_inside_images_of_any_size(self, detector: Any, image: np.ndarray,
                                                           shape: tuple[int, int]) -> None:
        """Boxes stay inside non-square, tall and tiny images."""
        import cv2

        resized = cv2.resize(image, (shape[1], shape[0]), interpolation=cv2.INTER_NEAREST)
        self._check(detector, detector.detect(resized), shape[0], shape[1])

    def test_detector_on_a_blank_image_answers_a_list(self, detector: Any) -> None:
        """A blank image gets a list (usually empty) of well-formed detections."""
        blank = np.zeros((120, 160, 3), np.uint8)
        self._check(detector, detector.detect(blank), 120, 160)

    def test_detector_is_repeatable(self, detector: Any, image: np.ndarray) -> None:
        """The same image gives the same detections."""
        def key(found: list[Detection]) -> list[tuple[Any, ...]]:
            return [(d.label, round(float(d.score), 4), tuple(round(v, 2) for v in d.box)) for d in found]

        assert key(detector.detect(image)) == key(detector.detect(image))

    @pytest.mark.parametrize("bad", ["not an image", "grey", "float", "empty"])
    def test_detector_rejects_bad_images_with_a_clear_error(self, detector: Any, bad: str) -> None:
        """A bad image is a ValueError naming the provider."""
        images = {"not an image": [[1, 2, 3]], "grey": np.zeros((10, 10), np.uint8),
                  "float": np.zeros((10, 10, 3), np.float64), "empty": np.zeros((0, 10, 3), np.uint8)}
        with pytest.raises(ValueError) as caught:
            detector.detect(images[bad])
        assert detector.name in str(caught.value), f"the error does not name the provider: {caught.value}"


class ConformanceAnswer(BaseModel):
    """The default schema the suites ask for: a short structured answer."""

    answer: str = Field(description="The answer in a few words.")
    confidence: float = Field(ge=0, le=1, description="How sure, 0-1.")


class VisionLanguageModelConformance(_CallConformance):
    """Tests every VisionLanguageModel provider passes. Override the ``vlm`` fixture.

    ``schema`` and ``prompt`` are what the schema test asks; a provider that answers only some
    schemas (the offline stand-in) sets one it answers.
    """

    schema: type[BaseModel] = ConformanceAnswer
    prompt: str = "What is the largest object in the image? Answer in JSON."

    @pytest.fixture
    def vlm(self) -> Any:
        """The vision-language model under test; subclasses override this."""
        raise NotImplementedError("a VLM's conformance class must override the `vlm` fixture")

    @pytest.fixture
    def provider(self, vlm: Any) -> Any:
        """The VLM, for the shared call tests."""
        return vlm

    def good_call(self, provider: Any) -> Callable[[], Any]:
        """A free-text question about the plain scene."""
        return lambda: provider.ask([scene_image()], "Describe the image in one sentence.")

    def check_answer(self, answer: Any) -> None:
        """Text."""
        assert isinstance(answer, str)

    def test_vlm_implements_the_protocol(self, vlm: Any) -> None:
        """A VisionLanguageModel: a name, check() says what it is."""
        from missiontree.reasoning.protocols import VisionLanguageModel

        assert isinstance(vlm, VisionLanguageModel)
        assert isinstance(vlm.name, str) and vlm.name
        assert isinstance(vlm.check(), str)

    def test_vlm_answers_text(self, vlm: Any) -> None:
        """A free-text question gets text."""
        answer = vlm.ask([scene_image()], "Describe the image in one sentence.")
        assert isinstance(answer, str)

    def test_vlm_schema_answer_is_checked_json_inside_the_image(self, vlm: Any) -> None:
        """Asked with a schema, the answer validates against it, boxes inside the image."""
        from missiontree.reasoning.checks import validate_answer

        image = scene_image(200, 300)
        text = vlm.ask([image], self.prompt, self.schema)
        assert isinstance(text, str)
        value = validate_answer(text, self.schema, None, (image.shape[1], image.shape[0]))
        assert isinstance(value, self.schema)

    @pytest.mark.parametrize("bad", ["grey-4d", "empty", "not an image"])
    def test_vlm_rejects_bad_images_with_a_clear_error(self, vlm: Any, bad: str) -> None:
        """A bad image is a ValueError naming the provider."""
        images = {"grey-4d": np.zeros((2, 10, 10, 3), np.uint8), "empty": np.zeros((0, 10, 3), np.uint8),
                  "not an image": "picture.png"}
        with pytest.raises(ValueError) as caught:
            vlm.ask([images[bad]], "What is this?")
        assert vlm.name in str(caught.value), f"the error does not name the provider: {caught.value}"


class LanguageModelConformance(_CallConformance):
    """Tests every LanguageModel provider passes. Override the ``llm`` fixture (``schema``, ``messages``)."""

    schema: type[BaseModel] = ConformanceAnswer

    @pytest.fixture
    def llm(self) -> Any:
        """The language model under test; subclasses override this."""
        raise NotImplementedError("an LLM's conformance class must override the `llm` fixture")

    @pytest.fixture
    def provider(self, llm: Any) -> Any:
        """The LLM, for the shared call tests."""
        return llm

    def messages(self) -> list[Any]:
        """The conversation the schema test sends (override with one the provider answers)."""
        from missiontree.reasoning.protocols import Message

        return [Message("system", "You answer in JSON."), Message("user", "Where do people keep milk?")]

    def good_call(self, provider: Any) -> Callable[[], Any]:
        """The suite's conversation, asked with its schema."""
        return lambda: provider.chat(self.messages(), self.schema)

    def check_answer(self, answer: Any) -> None:
        """Text."""
        assert isinstance(answer, str)

    def test_llm_implements_the_protocol(self, llm: Any) -> None:
        """A LanguageModel: a name, check() says what it is."""
        from missiontree.reasoning.protocols import LanguageModel

        assert isinstance(llm, LanguageModel)
        assert isinstance(llm.name, str) and llm.name
        assert isinstance(llm.check(), str)

    def test_llm_schema_answer_is_checked_json(self, llm: Any) -> None:
        """Asked with a schema, the answer validates against it."""
        from missiontree.reasoning.checks import validate_answer

        text = llm.chat(self.messages(), self.schema)
        assert isinstance(text, str)
        assert isinstance(validate_answer(text, self.schema), self.schema)


class EmbedderConformance(_CallConformance):
    """Tests every Embedder provider passes. Override the ``embedder`` fixture."""

    texts: tuple[str, ...] = ("a red chair", "a chair that is red", "the kitchen sink", "")

    @pytest.fixture
    def embedder(self) -> Any:
        """The embedder under test; subclasses override this."""
        raise NotImplementedError("an embedder's conformance class must override the `embedder` fixture")

    @pytest.fixture
    def provider(self, embedder: Any) -> Any:
        """The embedder, for the shared call tests."""
        return embedder

    def good_call(self, provider: Any) -> Callable[[], Any]:
        """Embed two texts."""
        return lambda: provider.embed(["a cup", "a mug"])

    def check_answer(self, answer: Any) -> None:
        """Two unit rows."""
        assert isinstance(answer, np.ndarray) and answer.shape[0] == 2

    def test_embedder_implements_the_protocol(self, embedder: Any) -> None:
        """An Embedder: a name, check() says what it is."""
        from missiontree.reasoning.protocols import Embedder

        assert isinstance(embedder, Embedder)
        assert isinstance(embedder.name, str) and embedder.name
        assert isinstance(embedder.check(), str)

    def test_embedder_rows_are_float32_unit_vectors(self, embedder: Any) -> None:
        """(n, dim) float32, finite, rows of unit length."""
        vectors = embedder.embed(list(self.texts))
        assert isinstance(vectors, np.ndarray) and vectors.dtype == np.float32
        assert vectors.ndim == 2 and vectors.shape[0] == len(self.texts) and vectors.shape[1] > 0
        assert np.isfinite(vectors).all()
        norms = np.linalg.norm(vectors[:3], axis=1)  # the empty text may embed to anything finite
        assert np.allclose(norms, 1.0, atol=1e-3), norms

    def test_embedder_is_deterministic_and_batch_independent(self, embedder: Any) -> None:
        """A text embeds the same alone and in a batch."""
        together = embedder.embed(list(self.texts[:3]))
        alone = np.vstack([embedder.embed([t]) for t in self.texts[:3]])
        assert np.allclose(together, alone, atol=1e-4)

    def test_embedder_similar_texts_are_closer(self, embedder: Any) -> None:
        """A paraphrase is closer than an unrelated text."""
        v = embedder.embed(list(self.texts[:3]))
        assert float(v[0] @ v[1]) > float(v[0] @ v[2])

    def test_embedder_of_nothing_is_an_empty_matrix(self, embedder: Any) -> None:
        """No texts give no rows."""
        vectors = embedder.embed([])
        assert isinstance(vectors, np.ndarray) and vectors.shape[0] == 0
