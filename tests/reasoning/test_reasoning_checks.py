"""Tests of checked answers: JSON extraction, schema validation, id grounding, retry once then fail."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pytest
from pydantic import BaseModel

from missiontree.reasoning.checks import (
    RejectedAnswerError,
    ask_checked,
    chat_checked,
    extract_json,
    validate_answer,
)
from missiontree.reasoning.protocols import Message
from missiontree.reasoning.schemas import CropMatch, IntentResolution, SurveillanceVerdict


class ScriptedVLM:
    """A VLM that answers from a script and records the prompts it got."""

    name = "scripted"

    def __init__(self, *answers: str) -> None:
        self.answers = list(answers)
        self.prompts: list[str] = []

    def ask(self, images: Sequence[np.ndarray], prompt: str, schema: type[BaseModel] | None = None) -> str:
        self.prompts.append(prompt)
        return self.answers.pop(0)


class ScriptedLLM:
    name = "scripted_llm"

    def __init__(self, *answers: str) -> None:
        self.answers = list(answers)
        self.conversations: list[list[Message]] = []

    def chat(self, messages: Sequence[Message], schema: type[BaseModel] | None = None) -> str:
        self.conversations.append(list(messages))
        return self.answers.pop(0)


def test_json_found_in_a_fenced_block() -> None:
    """A ```json fenced answer with chatter around it is parsed."""
    assert extract_json('Sure!\n```json\n{"a": 1}\n```\nDone.') == {"a": 1}


def test_json_found_inside_chatter() -> None:
    """An object embedded in a sentence is found between its outer braces."""
    assert extract_json('Here it is: {"matches": true} hope that helps') == {"matches": True}


def test_extra_keys_are_rejected() -> None:
    """A key the schema does not have is a rejection (a wrong schema cannot pass as a right one)."""
    with pytest.raises(ValueError, match="does not match the CropMatch schema: color: Extra inputs"):
        validate_answer('{"matches": true, "confidence": 0.5, "color": "red"}', CropMatch)


def test_out_of_range_value_is_rejected() -> None:
    """A confidence above 1 is rejected naming the field."""
    with pytest.raises(ValueError, match="confidence"):
        validate_answer('{"matches": true, "confidence": 7}', CropMatch)


def test_unknown_ids_rejected_with_the_valid_ones_listed() -> None:
    """Ids outside the caller's map are rejected and the message lists the valid ids."""
    with pytest.raises(ValueError, match=r"do not exist: \['ghost'\]; the only valid ids are \['a', 'b'\]"):
        validate_answer('{"candidates": ["a", "ghost"]}', IntentResolution, valid_ids=["b", "a"])


def test_known_ids_pass() -> None:
    """Ids that exist pass the grounding check."""
    value = validate_answer('{"candidates": ["b"], "reason": "x"}', IntentResolution, valid_ids={"a", "b"})
    assert value.candidates == ["b"]


def test_first_valid_answer_needs_one_attempt() -> None:
    """A valid first answer is used as is, with no retry."""
    vlm = ScriptedVLM('{"verdict": "SAFE"}')
    answer = ask_checked(vlm, [np.zeros((2, 2, 3), np.uint8)], "look", SurveillanceVerdict)
    assert answer.attempts == 1 and answer.rejected == () and not answer.value.alarm


def test_retry_prompt_carries_the_validation_error() -> None:
    """The retry prompt holds the original prompt, the reason and the rejected answer."""
    vlm = ScriptedVLM('{"verdict": "PERSON"}', '{"verdict": "ALARM"}')
    answer = ask_checked(vlm, [np.zeros((2, 2, 3), np.uint8)], "look", SurveillanceVerdict)
    assert answer.value.alarm and answer.attempts == 2
    assert vlm.prompts[1].startswith("look\n\nYour previous answer was rejected:")
    assert "verdict" in vlm.prompts[1] and '{"verdict": "PERSON"}' in vlm.prompts[1]


def test_second_bad_answer_fails_with_reason_and_no_third_try() -> None:
    """Two rejected answers raise RejectedAnswerError naming the provider; no third request is made."""
    llm = ScriptedLLM("not json", '{"candidates": ["nope"]}', '{"candidates": ["a"]}')
    with pytest.raises(RejectedAnswerError, match=r"scripted_llm: the IntentResolution answer was rejected"):
        chat_checked(llm, [Message("user", "Request: x")], IntentResolution, valid_ids={"a"})
    assert len(llm.conversations) == 2
    assert len(llm.answers) == 1


def test_llm_retry_appends_answer_and_correction() -> None:
    """An LLM retry sees its rejected answer as an assistant turn and the reason as a user turn."""
    llm = ScriptedLLM('{"candidates": ["zz"]}', '{"candidates": ["a"]}')
    answer = chat_checked(llm, [Message("user", "Request: x")], IntentResolution, valid_ids={"a"})
    retry = llm.conversations[1]
    assert [m.role for m in retry] == ["user", "assistant", "user"]
    assert retry[1].content == '{"candidates": ["zz"]}'
    assert "['zz']" in retry[2].content
    assert answer.rejected and "zz" in answer.rejected[0]
