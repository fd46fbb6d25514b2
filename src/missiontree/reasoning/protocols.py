"""The model protocols: what a vision-language model, a language model and an embedder provide.

Providers are plain synchronous objects: ``ask`` blocks until the answer is there. They never
run on the tick thread; leaves submit them through :class:`missiontree.reasoning.calls.ModelCaller`,
which runs them on a worker pool and hands back a handle to poll.

An answer is the model's text. When a pydantic ``schema`` is given the provider asks for
structured output and the text should be JSON of that schema; :mod:`missiontree.reasoning.checks`
validates it (a provider does not have to), so a malformed answer can be retried with the
validation error fed back.

Every provider has a ``name`` (shown in tick-log events and errors) and a ``check()`` that
``missiontree models`` calls: it loads the model or pings the server and raises a
:class:`~missiontree.errors.ModelError` / :class:`~missiontree.errors.ModelConfigError` naming
the provider and the fix when the provider is unusable.

The detector protocol lives with the detectors in :mod:`missiontree.perception.detectors`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal, Protocol, runtime_checkable

import numpy as np
from pydantic import BaseModel

Role = Literal["system", "user", "assistant"]


@dataclass(frozen=True)
class Message:
    """One chat message.

    Attributes:
        role: ``system``, ``user`` or ``assistant``.
        content: The text.
        images: HxWx3 uint8 RGB images attached to a user message (vision models only).
    """

    role: Role
    content: str
    images: tuple[np.ndarray, ...] = ()


@runtime_checkable
class VisionLanguageModel(Protocol):
    """Answers a prompt about one or more images."""

    name: str

    def ask(self, images: Sequence[np.ndarray], prompt: str, schema: type[BaseModel] | None = None) -> str:
        """Answer ``prompt`` about ``images`` (HxWx3 uint8 RGB).

        Args:
            images: One or more RGB images.
            prompt: The question.
            schema: When given, answer with JSON of this pydantic model.

        Returns:
            The answer text (JSON when ``schema`` is given).

        Raises:
            ModelError: The model could not answer (unreachable, rejected, crashed).
            ValueError: An image is empty or not HxWx3 uint8 (the message names the provider).
        """
        ...

    def check(self) -> str:
        """Load the model or ping the server; return a one-line description or raise ModelError."""
        ...


@runtime_checkable
class LanguageModel(Protocol):
    """Answers a conversation."""

    name: str

    def chat(self, messages: Sequence[Message], schema: type[BaseModel] | None = None) -> str:
        """Answer the last message of ``messages``.

        Args:
            messages: The conversation, oldest first.
            schema: When given, answer with JSON of this pydantic model.

        Returns:
            The answer text (JSON when ``schema`` is given).

        Raises:
            ModelError: The model could not answer.
        """
        ...

    def check(self) -> str:
        """Load the model or ping the server; return a one-line description or raise ModelError."""
        ...


@runtime_checkable
class Embedder(Protocol):
    """Turns texts into unit-length vectors whose dot product is their cosine similarity."""

    name: str

    def embed(self, texts: Sequence[str]) -> np.ndarray:
        """Return a float32 array of shape (len(texts), dim) with rows of unit length."""
        ...

    def check(self) -> str:
        """Load the model; return a one-line description or raise ModelError."""
        ...


def provider_name(provider: object) -> str:
    """The name a provider reports in events and errors (its ``name``, else its class name)."""
    name = getattr(provider, "name", None)
    return name if isinstance(name, str) and name else type(provider).__name__


def check_image(image: object, provider: str) -> np.ndarray:
    """Return ``image`` as an HxWx3 uint8 array or raise a ValueError naming ``provider`` and the fix.

    Accepts HxW grey images (stacked to three channels) and HxWx4 (alpha dropped).
    """
    if not isinstance(image, np.ndarray):
        raise ValueError(
            f"{provider}: expected an image as a numpy array (HxWx3 uint8 RGB), "
            f"found {type(image).__name__}; "
            "pass the colour image of an RGBDFrame (frame.color)")
    if image.size == 0 or image.ndim < 2 or image.shape[0] == 0 or image.shape[1] == 0:
        raise ValueError(
            f"{provider}: expected a non-empty HxWx3 image, found an empty array of shape {image.shape}; "
            "check that the camera has produced a frame (robot.rgbd() is not None) and the crop is inside it")
    if image.ndim == 2:
        image = np.stack([image] * 3, axis=-1)
    if image.ndim != 3 or image.shape[2] not in (3, 4):
        raise ValueError(
            f"{provider}: expected an HxWx3 RGB image, found shape {image.shape}; "
            "pass a colour image with 3 channels last")
    if image.shape[2] == 4:
        image = image[:, :, :3]
    if image.dtype != np.uint8:
        if np.issubdtype(image.dtype, np.floating) and image.size and float(np.nanmax(image)) <= 1.0:
            image = np.clip(np.nan_to_num(image) * 255.0, 0, 255)
        image = np.clip(image, 0, 255).astype(np.uint8)
    return np.ascontiguousarray(image)
