"""Tests of provider option checking shared by every model provider."""

from __future__ import annotations

import pytest
from pydantic import BaseModel, ConfigDict

from missiontree.errors import ModelConfigError
from missiontree.options import parse_provider_options


class Options(BaseModel):
    model_config = ConfigDict(extra="forbid")

    threshold: float = 0.5
    name: str = "x"


def test_valid_options_are_returned_as_the_model() -> None:
    """Good options come back as the validated model."""
    assert parse_provider_options(Options, {"threshold": 0.7}, "demo").threshold == 0.7


def test_every_bad_option_is_named_with_the_known_ones() -> None:
    """Unknown and mistyped options are reported together, with the provider and the known options."""
    with pytest.raises(ModelConfigError) as info:
        parse_provider_options(Options, {"threshold": "high", "colour": 1}, "demo")
    message = str(info.value)
    assert "model provider 'demo'" in message
    assert "threshold" in message and "colour" in message
    assert "known options: threshold, name" in message
    # worded as the config files' problems are (yamlio's one translation of pydantic errors)
    assert "colour: unknown key 'colour'" in message
    assert "threshold: expected a valid number" in message and "found 'high'" in message

