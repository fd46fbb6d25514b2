"""Fuzzing the expression language: any text is parsed into the whitelist or refused, never executed."""

from __future__ import annotations

import ast
import builtins
import contextlib
from collections.abc import Iterator
from typing import Any

from hypothesis import given
from hypothesis import strategies as st
from strategies import SCALARS

from missiontree.engine import expressions
from missiontree.engine.expressions import EvaluationError, parse_expression, parse_script
from missiontree.errors import ConfigError

#: Pieces of Python that would run code if anything compiled or evaluated the text.
_PIECES = ["__import__('os')", "open('x')", "exec('1')", "eval('1')", "a.b", "a[0]", "lambda: 1",
           "[x for x in a]", "(y := 1)", "2 ** 99999", "a", "b", "1", "'t'", "true", "null", "not",
           "and", "or", "+", "-", "*", "/", "%", "==", "<", ">=", "(", ")", " ", ";", "=", ":=", "\n",
           "if", "else", "f(", "import os", "globals()", "().__class__", "\\", "'", '"', "#"]
TEXTS = st.one_of(st.text(max_size=80), st.lists(st.sampled_from(_PIECES), max_size=12).map("".join))
_ALLOWED_NODES = expressions._ALLOWED


@contextlib.contextmanager
def _no_execution() -> Iterator[None]:
    """Fail if eval/exec run, or compile is asked for anything but a syntax tree (ast.parse's flag).

    Only around missiontree's calls: Hypothesis itself compiles code between cases.
    """
    seen: list[str] = []
    real = (builtins.compile, builtins.eval, builtins.exec)

    def compile_ast_only(source: Any, filename: Any, mode: str, flags: int = 0, *args: Any, **kw: Any) -> Any:
        if not flags & ast.PyCF_ONLY_AST:
            seen.append(f"compile {mode}")
        return real[0](source, filename, mode, flags, *args, **kw)

    builtins.compile = compile_ast_only
    builtins.eval = lambda *a, **k: seen.append("eval")  # type: ignore[assignment]
    builtins.exec = lambda *a, **k: seen.append("exec")  # type: ignore[assignment]
    try:
        yield
    finally:
        builtins.compile, builtins.eval, builtins.exec = real
    assert seen == []


def _only_whitelisted(tree: ast.AST) -> None:
    for node in ast.walk(tree):
        assert isinstance(node, _ALLOWED_NODES), type(node).__name__


@given(text=TEXTS)
def test_any_text_is_a_whitelisted_expression_or_a_config_error(text: str) -> None:
    """An expression parses to whitelisted nodes only, or is refused with a ConfigError; nothing runs."""
    with _no_execution():
        try:
            parsed = parse_expression(text)
        except ConfigError:
            return
        _only_whitelisted(parsed.tree)
        values = dict.fromkeys(parsed.reads, 1)
        try:
            parsed.evaluate(values.__getitem__)
        except EvaluationError:
            pass


@given(text=TEXTS, value=SCALARS)
def test_any_text_is_a_whitelisted_script_or_a_config_error(text: str, value: object) -> None:
    """A script parses to whitelisted assignments only, or is refused; running it only writes its keys."""
    store: dict[str, object] = {}
    with _no_execution():
        try:
            script = parse_script(text)
        except ConfigError:
            return
        for assignment in script.assignments:
            _only_whitelisted(assignment.value.tree)
        store = dict.fromkeys(script.reads, value)
        try:
            script.run(store.__getitem__, store.__setitem__)
        except EvaluationError:
            return
    assert set(store) <= set(script.reads) | set(script.writes)
