"""Checked answers: validate structured answers, retry once with the error fed back, ground object ids.

A model's structured answer steers a robot, so it is checked before use (the patrol-robot thesis §2.3,
"hallucination management"):

1. The text must be JSON (a fenced ```json block is accepted) of the pydantic schema asked for.
2. Every object id the answer names (``schema.named_ids()``) must exist in the caller's map or
   scene graph (``valid_ids``); an answer naming anything else is rejected.
3. Its numbers are finite (the schemas refuse NaN and infinity) and, for a question about an
   image, its boxes lie in that image (``image_problems``): a box at (90000, 90000) in a 320x240
   frame is rejected; one reaching past the border is clipped (``fit_to_image``).
4. A rejected answer is retried once, with the reason fed back to the model; if the second answer
   fails too, :class:`~missiontree.errors.ModelAnswerError` is raised with the reason, which the
   call handle reports and the leaf turns into FAILURE.

Rejections are logged (structlog, ``model_answer_rejected``) and travel with the result
(:attr:`CheckedAnswer.rejected`) or the error, so the ``model_call`` tick-log event lists them.

The helpers block; submit them through :class:`~missiontree.reasoning.calls.ModelCaller`::

    call = caller.submit("llm", chat_checked, llm, messages, IntentResolution, valid_ids=ids)
"""

from __future__ import annotations

import json
import re
from collections.abc import Collection, Sequence
from dataclasses import dataclass
from typing import Any, Generic, TypeVar

import numpy as np
import structlog
from pydantic import BaseModel, ValidationError

from missiontree.errors import ModelAnswerError
from missiontree.reasoning.protocols import LanguageModel, Message, VisionLanguageModel, provider_name

T = TypeVar("T", bound=BaseModel)

log = structlog.get_logger("missiontree.reasoning")

_FENCE = re.compile(r"```(?:json|JSON)?\s*(.*?)```", re.DOTALL)
_MAX_IDS_SHOWN = 20
_MAX_ANSWER_ECHO = 600
#: Longest answer read (characters); a longer one is rejected unread.
MAX_ANSWER_CHARS = 200_000


@dataclass(frozen=True)
class CheckedAnswer(Generic[T]):
    """An answer that passed the checks.

    Attributes:
        value: The validated answer.
        text: The model's text it came from.
        attempts: How many answers were asked for (1, or 2 after a retry).
        rejected: Why earlier answers were rejected (empty when the first passed).
    """

    value: T
    text: str
    attempts: int
    rejected: tuple[str, ...] = ()


class RejectedAnswerError(ModelAnswerError):
    """Every attempt failed the checks; ``rejected`` holds each reason, ``attempts`` their number."""

    def __init__(self, message: str, rejected: Sequence[str], attempts: int) -> None:
        super().__init__(message)
        self.rejected = tuple(rejected)
        self.attempts = attempts


def extract_json(text: str) -> Any:
    """Parse the JSON in a model's answer (bare, or in the first fenced code block).

    Raises:
        ValueError: No JSON could be parsed; the message quotes the parser's complaint.
    """
    if not isinstance(text, str):
        raise ValueError(f"expected the answer as text, found {type(text).__name__}")
    if len(text) > MAX_ANSWER_CHARS:
        raise ValueError(f"expected a short JSON object, found an answer of {len(text)} characters")
    stripped = text.strip()
    match = _FENCE.search(stripped)
    if match:
        stripped = match.group(1).strip()
    if not stripped:
        raise ValueError("expected a JSON object, found an empty answer")
    try:
        return json.loads(stripped)
    except RecursionError:
        raise ValueError("expected a JSON object, found JSON nested too deeply to read") from None
    except json.JSONDecodeError as exc:
        start, end = stripped.find("{"), stripped.rfind("}")
        if 0 <= start < end:
            try:
                return json.loads(stripped[start:end + 1])
            except (json.JSONDecodeError, RecursionError):
                pass
        raise ValueError(f"expected a JSON object, found text that is not JSON ({exc.msg} at "
                         f"line {exc.lineno} column {exc.colno})") from None


def validate_answer(text: str, schema: type[T], valid_ids: Collection[str] | None = None,
                    image_size: tuple[int, int] | None = None) -> T:
    """Check one answer: JSON of ``schema`` naming only ids in ``valid_ids`` (when given).

    Args:
        text: The model's answer.
        schema: The pydantic schema it must match.
        valid_ids: The object ids it may name (None: not checked).
        image_size: (width, height) of the image the question was about: boxes must lie in it
            and are clipped to it.

    Raises:
        ValueError: The reason the answer is rejected, ready to be fed back to the model.
    """
    data = extract_json(text)
    try:
        value = schema.model_validate(data)
    except ValidationError as exc:
        problems = "; ".join(
            f"{'.'.join(str(p) for p in err['loc']) or '<root>'}: {err['msg']}" for err in exc.errors()[:8])
        raise ValueError(f"the JSON does not match the {schema.__name__} schema: {problems}") from None
    except RecursionError:
        raise ValueError(f"the JSON is nested too deeply for the {schema.__name__} schema") from None
    if image_size is not None:
        check = getattr(value, "image_problems", None)
        outside = check(*image_size) if callable(check) else []
        if outside:
            raise ValueError("; ".join(outside[:4]) + "; give boxes in pixels of the image asked about")
        fit = getattr(value, "fit_to_image", None)
        value = fit(*image_size) if callable(fit) else value
    if valid_ids is not None:
        known = set(valid_ids)
        unknown = [i for i in _named_ids(value) if i not in known]
        if unknown:
            shown = sorted(known)[:_MAX_IDS_SHOWN]
            more = f" and {len(known) - len(shown)} more" if len(known) > len(shown) else ""
            raise ValueError(
                f"the answer names object ids that do not exist: {unknown}; "
                f"the only valid ids are {shown}{more}")
    return value


def _named_ids(value: BaseModel) -> list[str]:
    named = getattr(value, "named_ids", None)
    return [str(i) for i in named()] if callable(named) else []


def ask_checked(
    vlm: VisionLanguageModel,
    images: Sequence[np.ndarray],
    prompt: str,
    schema: type[T],
    *,
    valid_ids: Collection[str] | None = None,
    retries: int = 1,
) -> CheckedAnswer[T]:
    """Ask a vision-language model for a structured answer and check it (blocking).

    Raises:
        RejectedAnswerError: Every attempt was rejected; the message names the provider and the reason.
        ModelError: The provider itself failed.
    """
    current = prompt
    rejected: list[str] = []
    size = _size_of(images)
    for attempt in range(1, retries + 2):
        text = vlm.ask(images, current, schema)
        try:
            value = validate_answer(text, schema, valid_ids, size)
            return CheckedAnswer(value, text, attempt, tuple(rejected))
        except ValueError as exc:
            rejected.append(_reject(vlm, schema, str(exc), text, attempt))
            current = f"{prompt}\n\n{_feedback(str(exc), text)}"
    raise _exhausted(vlm, schema, rejected)


def chat_checked(
    llm: LanguageModel,
    messages: Sequence[Message],
    schema: type[T],
    *,
    valid_ids: Collection[str] | None = None,
    retries: int = 1,
) -> CheckedAnswer[T]:
    """Ask a language model for a structured answer and check it (blocking).

    A rejected answer is appended to the conversation with the reason, and asked again.

    Raises:
        RejectedAnswerError: Every attempt was rejected; the message names the provider and the reason.
        ModelError: The provider itself failed.
    """
    conversation = list(messages)
    rejected: list[str] = []
    for attempt in range(1, retries + 2):
        text = llm.chat(conversation, schema)
        try:
            return CheckedAnswer(validate_answer(text, schema, valid_ids), text, attempt, tuple(rejected))
        except ValueError as exc:
            rejected.append(_reject(llm, schema, str(exc), text, attempt))
            conversation += [Message("assistant", text), Message("user", _feedback(str(exc), None))]
    raise _exhausted(llm, schema, rejected)


def _size_of(images: Sequence[np.ndarray]) -> tuple[int, int] | None:
    """(width, height) of the first image, the one boxes refer to; None when there is none."""
    first = images[0] if isinstance(images, Sequence) and len(images) else images
    shape = getattr(first, "shape", None)
    if shape is None or len(shape) < 2:
        return None
    return int(shape[1]), int(shape[0])


def _feedback(reason: str, previous: str | None) -> str:
    echo = f"\nYour previous answer was: {str(previous)[:_MAX_ANSWER_ECHO]}" if previous is not None else ""
    return (f"Your previous answer was rejected: {reason}.{echo}\n"
            "Answer again with only a JSON object that matches the schema.")


def _reject(provider: object, schema: type[BaseModel], reason: str, text: str, attempt: int) -> str:
    log.warning("model_answer_rejected", provider=provider_name(provider), schema=schema.__name__,
                attempt=attempt, reason=reason, answer=str(text)[:_MAX_ANSWER_ECHO])
    return reason


def _exhausted(provider: object, schema: type[BaseModel], rejected: list[str]) -> RejectedAnswerError:
    name = provider_name(provider)
    return RejectedAnswerError(
        f"{name}: the {schema.__name__} answer was rejected {len(rejected)} times "
        f"(retried once with the error fed back); last reason: {rejected[-1]}",
        rejected, len(rejected))
