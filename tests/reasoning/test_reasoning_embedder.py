"""Tests of the MiniLM embedder: real ONNX inference with the committed tokenizer."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from missiontree.errors import ModelConfigError
from missiontree.reasoning.embedder import MiniLMEmbedder, default_tokenizer_path, similarity
from missiontree.reasoning.providers.offline_llm import AFFORDANCES


@pytest.fixture(scope="module")
def embedder() -> MiniLMEmbedder:
    return MiniLMEmbedder()


def test_vectors_have_unit_length(embedder: MiniLMEmbedder) -> None:
    """Each text gives one 384-dimensional float32 row of unit length."""
    vectors = embedder.embed(["a cup", "a much longer sentence about a sofa in the living room"])
    assert vectors.shape == (2, 384) and vectors.dtype == np.float32
    assert np.allclose(np.linalg.norm(vectors, axis=1), 1.0, atol=1e-5)


def test_batch_equals_single(embedder: MiniLMEmbedder) -> None:
    """Padding in a batch does not change a text's vector (mean pooling honours the attention mask)."""
    alone = MiniLMEmbedder().embed(["cup"])[0]
    batched = MiniLMEmbedder().embed(["cup", "a long sentence that forces padding of the short one"])[0]
    assert np.allclose(alone, batched, atol=1e-5)


def test_paraphrases_closer_than_unrelated(embedder: MiniLMEmbedder) -> None:
    """A paraphrase scores higher than an unrelated sentence."""
    scores = similarity(embedder, "I want something to drink", ["a glass of water", "a car engine"])
    assert scores[0] > scores[1] + 0.2


def test_thirsty_ranks_bottle_and_cup_first_with_affordances(embedder: MiniLMEmbedder) -> None:
    """With affordance descriptions, "I am thirsty" ranks bottle and cup above every other label."""
    labels = ["bottle", "cup", "sink", "sofa", "chair", "bed", "tv", "book", "laptop", "backpack", "umbrella"]
    scores = similarity(embedder, "I am thirsty", [AFFORDANCES[label] for label in labels])
    ranked = [labels[i] for i in np.argsort(-scores)]
    assert set(ranked[:2]) == {"bottle", "cup"}


def test_bare_labels_rank_badly(embedder: MiniLMEmbedder) -> None:
    """Bare labels put something other than bottle/cup first (why affordances exist, ARCHITECTURE §8)."""
    labels = ["bottle", "cup", "sink", "sofa", "chair", "bed", "tv", "book", "laptop", "backpack", "umbrella"]
    scores = similarity(embedder, "I am thirsty", labels)
    assert labels[int(np.argmax(scores))] not in {"bottle", "cup"}


def test_committed_tokenizer_is_present() -> None:
    """The tokenizer ships inside the package with its notice and licence."""
    path = default_tokenizer_path()
    assert path.is_file() and path.stat().st_size == 466247
    assert (path.parent / "NOTICE.md").is_file() and (path.parent / "LICENSE-Apache-2.0.txt").is_file()


def test_missing_model_file_names_provider_and_fix(tmp_path: Path) -> None:
    """A model_path that does not exist is a ModelConfigError naming the provider, the file and the fix."""
    broken = MiniLMEmbedder(model_path=tmp_path / "nope.onnx")
    with pytest.raises(ModelConfigError, match=r"'minilm': the model file .*nope.onnx' does not exist"):
        broken.check()


def test_file_that_is_not_a_model_is_refused(tmp_path: Path) -> None:
    """A file onnxruntime cannot load gives an error that says what to point at."""
    junk = tmp_path / "junk.onnx"
    junk.write_bytes(b"not a model")
    with pytest.raises(ModelConfigError, match="onnxruntime cannot load .*all-MiniLM-L6-v2 ONNX export"):
        MiniLMEmbedder(model_path=junk).embed(["x"])


def test_unknown_option_is_refused() -> None:
    """A misspelt option lists the known ones."""
    with pytest.raises(ModelConfigError, match="unknown option.*max_token"):
        MiniLMEmbedder.from_options({"max_token": 3})
