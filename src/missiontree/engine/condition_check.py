"""Checking conditions and scripts before the run: syntax, the whitelist and unknown keys, at file:line:col.

Every node's ``skip_if`` ... ``post`` is parsed (:func:`missiontree.engine.conditions.parse_conditions`)
and kept on its :class:`~missiontree.engine.spec.NodeSpec`; a refused expression is reported at the
column of the offending part when the expression is written on one line (plain or quoted), else at
the value. Every key an expression reads must be one the mission knows: a ``blackboard:`` default, a
key of any node's port (read or written), or a key some assignment (a post-condition, a ``Script``)
writes.
"""

from __future__ import annotations

import difflib
import re
from typing import Any

from missiontree.engine.conditions import parse_conditions
from missiontree.engine.expressions import (
    EvaluationError,
    Expression,
    ExpressionError,
    parse_expression,
    parse_script,
)
from missiontree.engine.nodes.script import SCRIPT_TYPES
from missiontree.engine.ports import ports_of
from missiontree.engine.spec import MissionSpec, NodeSpec
from missiontree.errors import Problem

_HINT = ("write keys, literals (numbers, 'text', true, false, null), comparisons, and/or/not and + - * / % "
         "(docs/mission-format.md: Conditions and assignments on any node)")


def check_conditions(spec: MissionSpec) -> list[Problem]:
    """Parse every node's conditions and Script code; report syntax, whitelist and unknown-key problems."""
    problems: list[Problem] = []
    for node in spec.nodes():
        if not node.conditions:
            continue
        parsed, errors = parse_conditions(node.conditions)
        node.prepost = parsed if not errors else None
        problems += [_expression_problem(node, (key,), error) for key, error in errors.items()]
    known = known_keys(spec)
    for node in spec.nodes():
        for key_path, reads in _reads_of(node):
            for key in sorted(reads - known):
                near = difflib.get_close_matches(key, sorted(known), n=1)
                hint = (f"did you mean {near[0]}?" if near else
                        f"add `{key}: ...` under `blackboard:`, or let a node or an assignment write it")
                message = (f"{key_path[0]}: expected blackboard keys the mission sets or a node writes, "
                           f"found {key!r} which nothing writes")
                found = re.search(rf"\b{re.escape(key)}\b", _written(node, key_path[0]))
                col = found.start() + 1 if found else 0
                problems.append(_pinpoint(node, key_path, 1, col, message, message, hint))
    return problems + _fixed_type_problems(spec)


def _fixed_type_problems(spec: MissionSpec) -> list[Problem]:
    """Expressions that read only keys nothing writes after the start fail now as they would at run time.

    Such keys keep their ``blackboard:`` default for the whole run, so ``level < 0.2`` with
    ``level: low`` is a type mismatch that can be reported before the run.
    """
    changing = tree_written_keys(spec)
    fixed = {k.lstrip("/"): v for k, v in spec.blackboard.items() if k.lstrip("/") not in changing}
    problems: list[Problem] = []
    for node in spec.nodes():
        for key, expression, as_condition in _expressions_of(node):
            if not expression.reads <= set(fixed):
                continue
            try:
                value = expression.evaluate(fixed.__getitem__)
                if as_condition and not isinstance(value, bool):
                    raise EvaluationError(f"expected true or false, found {value!r}")
            except EvaluationError as error:
                message = (f"{key}: expected an expression that can be evaluated, found that with the "
                           f"blackboard defaults it cannot: {error}")
                problems.append(_at(node, (key,), message, "these keys keep their defaults (nothing writes "
                                    "them): fix the expression or the defaults under `blackboard:`"))
    return problems


def _expressions_of(node: NodeSpec) -> list[tuple[str, Expression, bool]]:
    """(written key, expression, whether it is a condition) for a node's conditions and Script code."""
    found: list[tuple[str, Expression, bool]] = []
    if node.prepost is not None:
        found += [(key, e, True) for key, e in node.prepost.pre.items()]
        found += [(key, a.value, False) for key, script in node.prepost.post.items()
                  for a in script.assignments if a.op == "="]
    field_name = SCRIPT_TYPES.get(node.type, "")
    text = node.raw.get(field_name) if field_name else None
    if isinstance(text, str):
        try:
            if node.type == "Script":
                found += [(field_name, a.value, False) for a in parse_script(text).assignments if a.op == "="]
            else:
                found.append((field_name, parse_expression(text), True))
        except ExpressionError:
            pass  # reported by the node's Params check
    return found


def known_keys(spec: MissionSpec) -> set[str]:
    """Keys an expression may read: blackboard defaults, every port's key, every assigned key."""
    return {k.lstrip("/") for k in spec.blackboard} | tree_written_keys(spec)


def tree_written_keys(spec: MissionSpec) -> set[str]:
    """Keys the tree may write while it runs: every port's key (a leaf may write any), every assigned key."""
    keys = assigned_keys(spec)
    for node in spec.nodes():
        if node.params is None:
            continue
        for field_name in ports_of(type(node.params)):
            value = getattr(node.params, field_name, None)
            if isinstance(value, str):
                keys.add(value.lstrip("/"))
    return keys


def assigned_keys(spec: MissionSpec) -> set[str]:
    """Keys written by post-conditions and ``Script`` leaves (those that parse)."""
    keys: set[str] = set()
    for node in spec.nodes():
        for key, text in node.conditions.items():
            if key in ("on_success", "on_failure", "on_halted", "post"):
                keys |= _script_writes(text)
        if node.type == "Script":
            keys |= _script_writes(node.raw.get(SCRIPT_TYPES["Script"]))
    return keys


def _script_writes(text: Any) -> set[str]:
    try:
        return set(parse_script(text).writes)
    except ExpressionError:
        return set()


def _reads_of(node: NodeSpec) -> list[tuple[tuple[str, ...], frozenset[str]]]:
    """(where, keys read) for each parsed condition of ``node`` and its Script code."""
    found: list[tuple[tuple[str, ...], frozenset[str]]] = []
    if node.prepost is not None:
        found += [((key,), e.reads) for key, e in node.prepost.pre.items()]
        found += [((key,), s.reads) for key, s in node.prepost.post.items()]
    field_name = SCRIPT_TYPES.get(node.type)
    if field_name is not None and isinstance(node.raw.get(field_name), str):
        try:
            text = node.raw[field_name]
            parsed = parse_script(text) if node.type == "Script" else parse_expression(text)
            found.append(((field_name,), parsed.reads))
        except ExpressionError:
            pass  # reported by the node's Params check
    return found


def _at(node: NodeSpec, key_path: tuple[str, ...], message: str, hint: str) -> Problem:
    located = node.condition_sites.get(key_path[0], node.located)
    if located is None:
        src = node.source
        return Problem(src.file, src.line, src.col, node.path, message, hint)
    return located.problem_at(key_path, message, hint, where=node.path)


def _written(node: NodeSpec, key: str) -> str:
    """The text of a condition or of a Script's code as written ("" when it is not text)."""
    text = node.conditions.get(key, node.raw.get(key) if key in SCRIPT_TYPES.values() else None)
    return text if isinstance(text, str) else ""


def _expression_problem(node: NodeSpec, key_path: tuple[str, ...], error: ExpressionError) -> Problem:
    return _pinpoint(node, key_path, error.line, error.col, f"{key_path[0]}: {error.reason}",
                     f"{key_path[0]}: {error}", _HINT)


def _pinpoint(node: NodeSpec, key_path: tuple[str, ...], line_in: int, col_in: int, exact: str, rough: str,
              hint: str) -> Problem:
    """A problem at column ``col_in`` of the expression if it sits on one line of the file, else at its value.

    ``exact`` is the message when the column could be found, ``rough`` (which says where in the
    expression) otherwise.
    """
    problem = _at(node, key_path, rough, hint)
    text = _written(node, key_path[0])
    if not text or "\n" in text or line_in != 1 or col_in < 1 or problem.line < 1:
        return problem
    line = _file_line(problem.file, problem.line)
    start = problem.col - 1
    if line[start:start + len(text)] == text:
        offset = 0
    elif line[start:start + 1] in ("'", '"') and line[start + 1:start + 1 + len(text)] == text:
        offset = 1  # a quoted scalar without escapes
    else:
        return problem
    return Problem(problem.file, problem.line, problem.col + offset + col_in - 1, problem.path, exact, hint)


def _file_line(file: str, line: int) -> str:
    """Line ``line`` of ``file`` as it is now ("" when it cannot be read)."""
    try:
        with open(file, encoding="utf-8") as handle:
            lines = handle.read(1_000_000).splitlines()
    except (OSError, UnicodeDecodeError, ValueError):
        return ""
    return lines[line - 1] if 0 < line <= len(lines) else ""
