"""Tests of reading a need by embedding when the knowledge's words do not cover it."""

from __future__ import annotations

import numpy as np
import pytest

from missiontree.reasoning.embedder import MiniLMEmbedder
from missiontree.reasoning.knowledge import STRONG, Reading, knowledge
from missiontree.reasoning.need_embedding import (
    NEED_MATCH,
    by_embedding,
    embedded_need,
    embedded_reading,
    need_heads,
)
from missiontree.reasoning.providers.offline_llm import OfflineLanguageModel


class TableEmbedder:
    """Unit vectors from a fixed table: each text is a mix of need directions (deterministic)."""

    def __init__(self, table: dict[str, list[float]]) -> None:
        self.table = table

    def embed(self, texts: list[str]) -> np.ndarray:
        rows = [np.asarray(self.table.get(t, [0.0, 0.0, 1.0]), dtype=np.float32) for t in texts]
        return np.stack([r / np.linalg.norm(r) for r in rows])

    def check(self) -> str:
        return "table"


@pytest.fixture(scope="module")
def minilm() -> MiniLMEmbedder:
    return MiniLMEmbedder()


def test_a_clear_match_reaches_the_strong_threshold() -> None:
    """A word as near a need's word as a synonym reads at least STRONG, so a full server is a candidate."""
    embedder = TableEmbedder(
        {
            "zonk": [1.0, 0.1, 0.0],
            "nap": [1.0, 0.0, 0.0],
            "cook": [0.0, 1.0, 0.0],
            "I feel zonk": [1.0, 0.2, 0.3],
            "sleepy": [1.0, 0.0, 0.2],
            "food": [0.0, 1.0, 0.2],
        }
    )
    found = embedded_need(
        embedder,
        "I feel zonk",
        ["zonk"],
        {"sleep": "sleepy", "eat": "food"},
        {"sleep": ("nap",), "eat": ("cook",)},
    )
    assert found is not None and found[0] == "sleep" and found[1] >= STRONG


def test_a_word_near_two_needs_says_neither() -> None:
    """An unknown word about as near two needs gives no reading (the margin)."""
    embedder = TableEmbedder(
        {
            "blah": [1.0, 1.0, 0.0],
            "nap": [1.0, 0.0, 0.0],
            "cook": [0.0, 1.0, 0.0],
            "so blah": [1.0, 1.0, 0.1],
            "sleepy": [1.0, 0.0, 0.0],
            "food": [0.0, 1.0, 0.0],
        }
    )
    assert (
        embedded_need(
            embedder,
            "so blah",
            ["blah"],
            {"sleep": "sleepy", "eat": "food"},
            {"sleep": ("nap",), "eat": ("cook",)},
        )
        is None
    )


def test_a_word_match_the_request_does_not_lean_to_is_not_read() -> None:
    """A word near a need's word by its letters counts only when the whole request leans that way too."""
    embedder = TableEmbedder(
        {
            "potation": [1.0, 0.0, 0.0],
            "pot": [1.0, 0.0, 0.0],
            "cook": [0.0, 1.0, 0.0],
            "some potation": [0.0, 0.0, 1.0],
            "toilet": [1.0, 0.0, 0.0],
            "food": [0.0, 1.0, 0.0],
        }
    )
    assert (
        embedded_need(
            embedder,
            "some potation",
            ["potation"],
            {"toilet": "toilet", "eat": "food"},
            {"toilet": ("pot",), "eat": ("cook",)},
        )
        is None
    )


def test_films_by_a_word_the_knowledge_lacks_go_to_the_tv(minilm: MiniLMEmbedder) -> None:
    """'I'd enjoy a photoplay tonight' (no listed word) reads as entertainment strongly enough for the TV."""
    kb = knowledge()
    known = kb.read("I'd enjoy a photoplay tonight.")
    assert known.empty
    reading = embedded_reading(minilm, "I'd enjoy a photoplay tonight.", known, kb)
    assert by_embedding(reading) and kb.score("tv", reading)[0] >= STRONG
    assert kb.score("refrigerator", reading)[0] < STRONG


def test_the_stand_in_offers_the_tv_for_an_embedded_reading(minilm: MiniLMEmbedder) -> None:
    """The offline model names candidates for a request understood only by embedding (it never did)."""
    llm = OfflineLanguageModel(minilm)
    scene = [
        {"id": "tv_1", "label": "tv", "x": 1.0, "y": 0.0},
        {"id": "cup_1", "label": "cup", "x": 2.0, "y": 0.0},
    ]
    answer = llm.resolve("I'd enjoy a cinema tonight.", scene)
    assert answer.candidates == ["tv_1"] and "embedding" in answer.reason


@pytest.mark.parametrize(
    "request_", ["bring me a unicorn", "Time for a chiller, I think.", "Some potation would be nice."]
)
def test_unrelated_requests_get_no_embedded_need(minilm: MiniLMEmbedder, request_: str) -> None:
    """Requests about nothing the needs cover are not matched by likeness of words."""
    kb = knowledge()
    known = kb.read(request_)
    assert embedded_reading(minilm, request_, known, kb) == known


def test_heads_are_each_needs_own_words() -> None:
    """The words an unknown word is compared with are words of exactly one need at full weight."""
    heads = need_heads(knowledge())
    assert "thirsty" in heads["drink"] and NEED_MATCH < 1.0
    assert not by_embedding(Reading(needs={"drink": (1.0, "thirsty")}))


def test_a_need_word_that_names_another_object_is_no_head() -> None:
    """'stool' names a seat as well as the toilet's word: an unknown word near it says no need."""
    heads = need_heads(knowledge())
    assert "stool" not in heads["toilet"] and "toilet" in heads["toilet"]


def test_pooped_is_not_read_as_the_toilet(minilm: MiniLMEmbedder) -> None:
    """'I feel pooped' (tired; WordNet lacks it) is not matched to the toilet by its nearness to 'stool'."""
    kb, request = knowledge(), "I feel pooped after today."
    reading = embedded_reading(minilm, request, kb.read(request), kb)
    assert "toilet" not in reading.needs


def test_a_need_said_met_is_not_read_back_by_embedding(minilm: MiniLMEmbedder) -> None:
    """'I'm rested' is not matched to rest by its nearness to 'rest': the embedding reads no need into it."""
    kb, request = knowledge(), "I'm rested"
    assert embedded_reading(minilm, request, kb.read(request), kb).needs == {}
