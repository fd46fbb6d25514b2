"""The model conformance suites (missiontree.testing_models) on every built-in reasoning provider.

``openai`` runs against the scripted loopback server (as a VLM and as an LLM, and with a slow reply
to check that its own HTTP timeout is honoured); ``offline_vlm`` on the shipped simulator detector;
``offline_llm`` and ``minilm`` as shipped. A plugin author runs the same classes on their provider.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Iterator
from typing import Any

import pytest
from fake_openai_server import FakeOpenAIServer as Fake
from fake_openai_server import Reply

from missiontree.perception.providers import create_sim_detector
from missiontree.reasoning.prompts import intent_messages, surveillance_prompt
from missiontree.reasoning.providers import (
    create_minilm,
    create_offline_llm,
    create_offline_vlm,
    create_openai,
)
from missiontree.reasoning.schemas import IntentResolution, SurveillanceVerdict
from missiontree.testing_models import (
    EmbedderConformance,
    LanguageModelConformance,
    VisionLanguageModelConformance,
)

KEY = "sk-conformance-0123456789"
SCENE = [{"id": "cup_1", "label": "cup", "room": "kitchen"},
         {"id": "sofa_1", "label": "sofa", "room": "lounge"}]
ANSWER = json.dumps({"answer": "a red box", "confidence": 0.8})


@pytest.fixture(scope="module")
def minilm() -> Any:
    """One MiniLM embedder for the module (loading it is the slow part)."""
    return create_minilm({})


@pytest.fixture
def server(monkeypatch: pytest.MonkeyPatch) -> Iterator[Fake]:
    monkeypatch.setenv("MT_CONFORMANCE_KEY", KEY)
    with Fake(api_key=KEY, default=Reply.text(ANSWER)) as fake:
        yield fake


def _openai(server: Fake, timeout: float = 5.0) -> Any:
    return create_openai({"model": "test-model", "base_url": server.url, "api_key_env": "MT_CONFORMANCE_KEY",
                          "backoff": 0.01}, timeout=timeout)


def _slow(server: Fake, call: Callable[[Any], Any]) -> tuple[Callable[[], Any], float]:
    server.default = Reply.text(ANSWER, delay=3.0)
    provider = _openai(server, timeout=0.5)
    provider.sleep = lambda seconds: None  # no back-off pauses between retries
    return (lambda: call(provider)), 0.5


class TestOpenAIAsVLM(VisionLanguageModelConformance):
    @pytest.fixture
    def vlm(self, server: Fake) -> Any:
        return _openai(server)

    @pytest.fixture
    def slow(self, server: Fake) -> tuple[Callable[[], Any], float]:
        from missiontree.testing_models import scene_image

        return _slow(server, lambda p: p.ask([scene_image()], "What is this?"))


class TestOpenAIAsLLM(LanguageModelConformance):
    @pytest.fixture
    def llm(self, server: Fake) -> Any:
        return _openai(server)

    @pytest.fixture
    def slow(self, server: Fake) -> tuple[Callable[[], Any], float]:
        return _slow(server, lambda p: p.chat(self.messages()))


class TestOfflineVLM(VisionLanguageModelConformance):
    schema = SurveillanceVerdict
    prompt = surveillance_prompt()

    @pytest.fixture
    def vlm(self) -> Any:
        return create_offline_vlm({}, models={"detector": create_sim_detector({})})


class TestOfflineLLM(LanguageModelConformance):
    schema = IntentResolution

    def messages(self) -> list[Any]:
        return intent_messages("I am thirsty", SCENE)

    @pytest.fixture
    def llm(self, minilm: Any) -> Any:
        return create_offline_llm({}, models={"embedder": minilm})


class TestMiniLM(EmbedderConformance):
    @pytest.fixture
    def embedder(self, minilm: Any) -> Any:
        return minilm
