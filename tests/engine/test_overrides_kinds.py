"""The kinds ``--set`` messages name for a parameter's default."""

from __future__ import annotations

from typing import Any

import pytest

from missiontree.engine.overrides import kind_of


@pytest.mark.parametrize(("value", "kind"), [
    (True, "true/false"), (3, "whole number"), (0.5, "number"), ("a", "text"), ([1], "list"),
    ({"a": 1}, "mapping"), (None, "any value")])
def test_kind_of_names_each_default_kind(value: Any, kind: str) -> None:
    """Each default gets its own kind's name (a bool is not called a whole number)."""
    assert kind_of(value) == kind
