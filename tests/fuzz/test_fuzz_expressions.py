"""Fuzzing the expression language: any text is parsed into the whitelist or refused, never executed."""

from __future__ import annotations

import ast
import builtins
import contextlib
from collections.abc import Iterator
from typing import Any

import py_trees
import yaml
from hypothesis import event, given
from hypothesis import strategies as st
from strategies import SCALARS

from missiontree.engine import expressions
from missiontree.engine.build import build_tree, write_blackboard_defaults
from missiontree.engine.expressions import EvaluationError, parse_expression, parse_script
from missiontree.engine.loader import load_mission
from missiontree.engine.nodes import register_nodes
from missiontree.engine.registry import NodeRegistry
from missiontree.errors import ConfigError, ProblemsError

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


_KEYS = ["skip_if", "fail_if", "succeed_if", "while", "on_success", "on_failure", "on_halted", "post"]
_EXPRESSION_PIECES = st.lists(st.sampled_from(["a", "b", "n", "1", "0", "'t'", "true", "null", " < ", " == ",
                                               " and ", " or ", "not ", " + ", " / ", " = ", " := ", "; ",
                                               "(", ")", "f(a)", "a.b", "\n", '"', "'"]),
                              min_size=1, max_size=8).map("".join)
_VALID_PRE = st.sampled_from(["a == 1", "n > 2", "b == 't'", "not (a < 0)", "n / 0 > 1", "b < 1", "c == 1",
                              "true", "n + b", "a if n else b"])
_VALID_POST = st.sampled_from(["n = n + 1", "n := 'x'", "n += b", "b = null; n = 1", "n = n / 0", "n *= 2"])


def _entry(key: str) -> st.SearchStrategy[tuple[str, Any]]:
    valid = _VALID_PRE if key in _KEYS[:4] else _VALID_POST
    return st.tuples(st.just(key), st.one_of(valid, valid, valid, valid, _EXPRESSION_PIECES, SCALARS))


CONDITIONS = st.lists(st.sampled_from(_KEYS).flatmap(_entry), max_size=3).map(dict)


@given(first=CONDITIONS, second=CONDITIONS)
def test_missions_with_any_conditions_load_or_report_and_tick_safely(
        tmp_path_factory: Any, first: dict[str, Any], second: dict[str, Any]) -> None:
    """A mission with any condition texts loads or reports located problems; a loaded one ticks safely."""
    registry = NodeRegistry()
    register_nodes(registry)
    mission = {"blackboard": {"a": 1, "b": "t", "n": 0}, "root": {"Sequence": {"memory": False, "children": [
        {"Running": first}, {"Succeed": second}]}}}
    path = tmp_path_factory.mktemp("m") / "m.yaml"
    path.write_text(yaml.safe_dump(mission))
    py_trees.blackboard.Blackboard.clear()
    try:
        spec = load_mission(path, registry)
    except ProblemsError as exc:
        assert all(p.line >= 1 and p.col >= 1 for p in exc.problems)
        event("refused")
        return
    event("loaded")
    root = build_tree(spec, registry)
    write_blackboard_defaults(spec)
    root.setup()
    for _ in range(3):
        root.tick_once()
        assert root.status in (py_trees.common.Status.SUCCESS, py_trees.common.Status.FAILURE,
                               py_trees.common.Status.RUNNING)
