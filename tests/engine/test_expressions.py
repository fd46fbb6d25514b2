"""Tests of the expression language: what it accepts, what it refuses, and strict evaluation."""

from __future__ import annotations

from typing import Any

import pytest

from missiontree.engine.expressions import (
    EvaluationError,
    ExpressionError,
    parse_expression,
    parse_script,
)
from missiontree.errors import ConfigError


def _reader(values: dict[str, Any]) -> Any:
    return values.__getitem__


@pytest.mark.parametrize("text, refused", [
    ("len(route)", "function call"),
    ("robot.battery", "attribute access"),
    ("route[0]", "subscript"),
    ("lambda: 1", "lambda"),
    ("[x for x in route]", "comprehension"),
    ("{k: 1 for k in route}", "comprehension"),
    ("(x for x in route)", "comprehension"),
    ("2 ** 1000", "power operator"),
    ("(y := 3)", "inline assignment"),
    ("__import__('os')", "function call"),
    ("f'{x}'", "f-string"),
    ("[1, 2]", "a list"),
])
def test_refuses_what_is_off_the_whitelist(text: str, refused: str) -> None:
    """Calls, attribute access, subscripts, lambdas, comprehensions and more are refused, with what."""
    with pytest.raises(ExpressionError, match=refused):
        parse_expression(text)


def test_refusal_is_a_config_error_with_a_column() -> None:
    """A refused part is located at its column in the expression text."""
    with pytest.raises(ConfigError) as caught:
        parse_expression("battery < 0.2 and f(x)")
    assert isinstance(caught.value, ExpressionError) and caught.value.col == 19


def test_syntax_error_is_refused() -> None:
    """Text that is not an expression is a ConfigError, not a crash."""
    with pytest.raises(ExpressionError, match="syntax error"):
        parse_expression("battery <")


def test_keys_literals_and_operators_evaluate() -> None:
    """Keys, true/false/null, comparisons, and/or/not, arithmetic and if/else evaluate as written."""
    text = "not docked and (battery * 100 >= 20 or name == 'kitchen') and goal != null"
    expression = parse_expression(text)
    assert expression.reads == {"docked", "battery", "name", "goal"}
    values = {"docked": False, "battery": 0.1, "name": "kitchen", "goal": 3}
    assert expression.truth(_reader(values)) is True
    assert parse_expression("1 if a > 2 else 'low'").evaluate(_reader({"a": 1})) == "low"


def test_missing_key_is_an_error_not_false() -> None:
    """A key that is not set raises EvaluationError naming it."""
    with pytest.raises(EvaluationError, match="'battery' is not set"):
        parse_expression("battery < 0.2").truth(_reader({}))


@pytest.mark.parametrize("text, values", [
    ("a < 3", {"a": "low"}),
    ("a == 1", {"a": "1"}),
    ("not a", {"a": 1}),
    ("a / 0", {"a": 1}),
    ("a + 1", {"a": True}),
    ("a", {"a": 3}),
    ("a * 10.0", {"a": 1e308}),
])
def test_type_mismatches_are_errors(text: str, values: dict[str, Any]) -> None:
    """Comparing text with numbers, not of a number, division by zero, overflow: errors, never False."""
    with pytest.raises(EvaluationError):
        parse_expression(text).truth(_reader(values))


def test_script_assigns_in_order_with_both_assignment_forms() -> None:
    """`=` and BT.CPP's `:=` assign, `+=` updates, `;` and new lines separate."""
    script = parse_script("a := 1; b = a + 2\nb += 10; s = 'x:=y'")
    store: dict[str, Any] = {}
    script.run(store.__getitem__, store.__setitem__)
    assert store == {"a": 1, "b": 13, "s": "x:=y"}
    assert script.writes == {"a", "b", "s"}
    assert script.text == "a := 1; b = a + 2\nb += 10; s = 'x:=y'"  # as written, for the tick log


@pytest.mark.parametrize("text", ["a + 1", "a = f()", "true = 1", "a, b = 1, 2", "a = b = 1", "a **= 2",
                                  "import os", "del a", "a.b = 1", "a[0] = 1"])
def test_script_refuses_non_assignments(text: str) -> None:
    """Only `key = expression` statements are scripts."""
    with pytest.raises(ExpressionError):
        parse_script(text)


def test_yaml_boolean_is_a_constant_condition() -> None:
    """`skip_if: true` (a YAML boolean) reads as the literal true."""
    assert parse_expression(True).truth(_reader({})) is True
