"""A small, safe expression language over blackboard keys, for conditions and scripts.

Conditions (``skip_if: battery < 0.2``) and assignments (``post: visits = visits + 1``) are parsed
with Python's :mod:`ast` (``ast.parse`` only builds a syntax tree; nothing is compiled to code or run)
and every node of the tree must be on a whitelist: literals (numbers, text, ``true``, ``false``,
``null``), blackboard keys (plain names), comparisons, ``and``/``or``/``not``, ``+ - * / // %``,
unary minus and ``a if cond else b``. Calls, attribute access, subscripts, lambdas, comprehensions,
``**`` and everything else are refused with an :class:`ExpressionError` (a ConfigError) that says
where. The parsed tree is then evaluated by :func:`_value`, a small interpreter of those node types;
Python's ``eval`` is never used.

Evaluation is strict: a key that is not set, ``not`` of a number, ``"a" < 3``, ``1 == "1"``, a
division by zero or a result that is not finite raise :class:`EvaluationError` (the node carrying the
condition then fails with a fault), never a silent ``false``.
"""

from __future__ import annotations

import ast
import io
import math
import tokenize
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from missiontree.errors import ConfigError

#: Names that are literals, not blackboard keys.
LITERALS: dict[str, Any] = {"true": True, "false": False, "null": None}
#: Longest expression or script text accepted, most syntax-tree nodes and deepest nesting.
MAX_CHARS = 2_000
MAX_NODES = 400
MAX_DEPTH = 48
#: Longest text an expression may build (``s = s + s`` in a post would otherwise double every tick).
MAX_TEXT = 10_000

_BIN_OPS: dict[type, str] = {ast.Add: "+", ast.Sub: "-", ast.Mult: "*", ast.Div: "/", ast.FloorDiv: "//",
                             ast.Mod: "%"}
_CMP_OPS: dict[type, str] = {ast.Eq: "==", ast.NotEq: "!=", ast.Lt: "<", ast.LtE: "<=", ast.Gt: ">",
                             ast.GtE: ">="}
_ALLOWED = (ast.Expression, ast.Module, ast.Expr, ast.Assign, ast.AugAssign, ast.BoolOp, ast.And, ast.Or,
            ast.UnaryOp, ast.Not, ast.USub, ast.UAdd, ast.BinOp, ast.Compare, ast.IfExp, ast.Constant,
            ast.Name, ast.Load, ast.Store, *_BIN_OPS, *_CMP_OPS)
_REFUSED_WORDS: dict[type, str] = {
    ast.Call: "a function call", ast.Attribute: "attribute access (a.b)", ast.Subscript: "a subscript (a[i])",
    ast.Lambda: "a lambda", ast.ListComp: "a comprehension", ast.SetComp: "a comprehension",
    ast.DictComp: "a comprehension", ast.GeneratorExp: "a comprehension", ast.Pow: "the power operator **",
    ast.NamedExpr: "an inline assignment (:=) inside an expression", ast.List: "a list",
    ast.Dict: "a mapping",
    ast.Tuple: "a tuple", ast.Set: "a set", ast.JoinedStr: "an f-string", ast.Starred: "unpacking (*)",
    ast.Await: "await", ast.Yield: "yield", ast.YieldFrom: "yield", ast.Slice: "a slice",
}


class ExpressionError(ConfigError):
    """An expression or script that is not in the language, with where in its text (1-based)."""

    def __init__(self, reason: str, line: int = 1, col: int = 1) -> None:
        self.reason = reason
        self.line = line
        self.col = col
        super().__init__(f"{reason} (line {line}, column {col} of the expression)" if line > 1
                         else f"{reason} (column {col} of the expression)")


class EvaluationError(Exception):
    """An expression that cannot be evaluated now: a key not set, a type mismatch, a division by zero."""


Reader = Callable[[str], Any]
Writer = Callable[[str, Any], None]


@dataclass(frozen=True)
class Expression:
    """A checked expression: its text, its syntax tree and the blackboard keys it reads."""

    text: str
    tree: ast.expr
    reads: frozenset[str]

    def evaluate(self, read: Reader) -> Any:
        """The value, reading keys with ``read`` (which raises KeyError for a key that is not set)."""
        return _value(self.tree, read)

    def truth(self, read: Reader) -> bool:
        """The value as a condition: it must be ``true`` or ``false``."""
        found = self.evaluate(read)
        if not isinstance(found, bool):
            raise EvaluationError(f"expected `{self.text}` to be true or false, found {_shown(found)}")
        return found


@dataclass(frozen=True)
class Assignment:
    """``key = value`` (or ``+=``, ``-=``, ``*=``, ``/=``)."""

    key: str
    op: str
    value: Expression


@dataclass(frozen=True)
class Script:
    """Assignments run in order, separated by ``;`` or new lines."""

    text: str
    assignments: tuple[Assignment, ...]

    @property
    def reads(self) -> frozenset[str]:
        """Keys read (an augmented assignment reads its target)."""
        keys = {k for a in self.assignments for k in a.value.reads}
        return frozenset(keys | {a.key for a in self.assignments if a.op != "="})

    @property
    def writes(self) -> frozenset[str]:
        """Keys written."""
        return frozenset(a.key for a in self.assignments)

    def run(self, read: Reader, write: Writer) -> None:
        """Run every assignment in order."""
        for a in self.assignments:
            value = a.value.evaluate(read)
            if a.op != "=":
                value = _arith(a.op[0], _read(read, a.key), value)
            write(a.key, value)


def parse_expression(text: Any) -> Expression:
    """Parse a condition or value expression, refusing anything off the whitelist."""
    source = _source(text)
    tree = _parse(source, "eval")
    assert isinstance(tree, ast.Expression)
    return Expression(source.strip(), tree.body, _reads(tree))


def parse_script(text: Any) -> Script:
    """Parse ``key = expr`` assignments (``:=`` accepted for ``=``), separated by ``;`` or new lines."""
    written = _source(text)
    source = _walrus_to_assign(written)
    tree = _parse(source, "exec")
    assert isinstance(tree, ast.Module)
    if not tree.body:
        raise ExpressionError("expected at least one assignment `key = expression`, found none")
    assignments = []
    for statement in tree.body:
        target, op, value = _assignment_parts(statement)
        segment = ast.get_source_segment(source, value) or ""
        assignments.append(Assignment(target, op, Expression(segment, value, _reads(value))))
    return Script(written.strip(), tuple(assignments))


def _source(text: Any) -> str:
    if isinstance(text, bool):  # `skip_if: true` in YAML, or a ${param} that is a boolean
        text = "true" if text else "false"
    if not isinstance(text, str | int | float):
        raise ExpressionError(f"expected an expression as text, found {_shown(text)}")
    source = str(text)
    if len(source) > MAX_CHARS:
        raise ExpressionError(f"expected an expression of at most {MAX_CHARS} characters, found "
                              f"{len(source)}")
    if not source.strip():
        raise ExpressionError("expected an expression, found empty text")
    return source


def _parse(source: str, mode: str) -> ast.AST:
    """``ast.parse`` (syntax tree only) and the whitelist check; every refusal an ExpressionError."""
    lines_before, col_before = _leading(source) if mode == "eval" else (0, 0)
    try:
        with warnings.catch_warnings():  # "invalid decimal literal" and the like: the text is refused anyway
            warnings.simplefilter("ignore")
            tree = ast.parse(source.strip() if mode == "eval" else source, mode=mode)
    except SyntaxError as exc:
        line, col = exc.lineno or 1, exc.offset or 1
        raise ExpressionError(f"expected an expression, found a syntax error: {exc.msg}", line + lines_before,
                              col + (col_before if line == 1 else 0)) from None
    except (ValueError, RecursionError, MemoryError) as exc:
        raise ExpressionError(f"expected an expression, found text that cannot be read: {exc}") from None
    if mode == "eval":  # positions are in the stripped text: shift back to the text as written
        _shift(tree, source)
    _check_whitelist(tree)
    return tree


def _leading(source: str) -> tuple[int, int]:
    """Lines and columns of the blank text before an expression (stripped before parsing)."""
    skipped = source[: len(source) - len(source.lstrip())]
    return skipped.count("\n"), len(skipped) - (skipped.rfind("\n") + 1)


def _shift(tree: ast.AST, source: str) -> None:
    lines_before, col_before = _leading(source)
    for node in ast.walk(tree):
        if isinstance(node, ast.expr):
            if node.lineno == 1:
                node.col_offset += col_before
            node.lineno += lines_before


def _check_whitelist(tree: ast.AST) -> None:
    count = 0
    stack: list[tuple[ast.AST, int]] = [(tree, 0)]
    while stack:
        node, depth = stack.pop()
        count += 1
        if count > MAX_NODES or depth > MAX_DEPTH:
            raise ExpressionError(f"expected a short expression (at most {MAX_NODES} parts, {MAX_DEPTH} "
                                  "deep), found a longer one", *_where(node))
        if not isinstance(node, _ALLOWED):
            what = _REFUSED_WORDS.get(type(node), f"`{type(node).__name__}`")
            raise ExpressionError(f"expected keys, literals, comparisons, and/or/not and arithmetic, found "
                                  f"{what}", *_where(node))
        if isinstance(node, ast.Constant) and (isinstance(node.value, bytes | complex)
                                               or node.value is Ellipsis):
            raise ExpressionError(f"expected a number or text, found {node.value!r}", *_where(node))
        if isinstance(node, ast.Name) and isinstance(node.ctx, ast.Store) and node.id in LITERALS:
            raise ExpressionError(f"expected a blackboard key to assign, found the literal {node.id}",
                                  *_where(node))
        stack.extend((child, depth + 1) for child in ast.iter_child_nodes(node))


def _where(node: ast.AST) -> tuple[int, int]:
    return getattr(node, "lineno", 1), getattr(node, "col_offset", 0) + 1


def _walrus_to_assign(source: str) -> str:
    """BT.CPP's ``key := value`` written as ``key  = value`` (same columns), outside text literals."""
    lines = source.splitlines(keepends=True)
    try:
        tokens = list(tokenize.generate_tokens(io.StringIO(source).readline))
    except (tokenize.TokenError, SyntaxError) as exc:
        raise ExpressionError(f"expected a script, found text that cannot be read: {exc}") from None
    for tok in tokens:
        if tok.type == tokenize.OP and tok.string == ":=":
            row, col = tok.start
            line = lines[row - 1]
            lines[row - 1] = line[:col] + " =" + line[col + 2:]
    return "".join(lines)


def _assignment_parts(statement: ast.stmt) -> tuple[str, str, ast.expr]:
    if isinstance(statement, ast.Assign) and len(statement.targets) == 1:
        target = statement.targets[0]
        if isinstance(target, ast.Name):
            return target.id, "=", statement.value
    if isinstance(statement, ast.AugAssign) and isinstance(statement.target, ast.Name):
        op = _BIN_OPS.get(type(statement.op))
        if op in ("+", "-", "*", "/"):
            return statement.target.id, f"{op}=", statement.value
    raise ExpressionError("expected an assignment `key = expression` (or +=, -=, *=, /=), found another "
                          "statement", *_where(statement))


def _reads(tree: ast.AST) -> frozenset[str]:
    return frozenset(n.id for n in ast.walk(tree)
                     if isinstance(n, ast.Name) and isinstance(n.ctx, ast.Load) and n.id not in LITERALS)


# -- evaluation -------------------------------------------------------------------------------


def _read(read: Reader, key: str) -> Any:
    try:
        return read(key)
    except KeyError:
        raise EvaluationError(f"blackboard key {key!r} is not set") from None


def _value(node: ast.AST, read: Reader) -> Any:
    """Evaluate one whitelisted node (recursion bounded by :data:`MAX_DEPTH`)."""
    if isinstance(node, ast.Constant):
        return node.value
    if isinstance(node, ast.Name):
        return LITERALS[node.id] if node.id in LITERALS else _read(read, node.id)
    if isinstance(node, ast.BoolOp):
        want = isinstance(node.op, ast.Or)
        for part in node.values:
            found = _boolean(_value(part, read), "and" if not want else "or")
            if found is want:
                return want
        return not want
    if isinstance(node, ast.UnaryOp):
        operand = _value(node.operand, read)
        if isinstance(node.op, ast.Not):
            return not _boolean(operand, "not")
        return _arith("-", 0, operand) if isinstance(node.op, ast.USub) else _arith("+", 0, operand)
    if isinstance(node, ast.BinOp):
        return _arith(_BIN_OPS[type(node.op)], _value(node.left, read), _value(node.right, read))
    if isinstance(node, ast.Compare):
        left = _value(node.left, read)
        for op, right_node in zip(node.ops, node.comparators, strict=True):
            right = _value(right_node, read)
            if not _compare(_CMP_OPS[type(op)], left, right):
                return False
            left = right
        return True
    if isinstance(node, ast.IfExp):
        chosen = node.body if _boolean(_value(node.test, read), "if") else node.orelse
        return _value(chosen, read)
    raise EvaluationError(f"cannot evaluate {type(node).__name__}")  # unreachable after the whitelist


def _boolean(value: Any, op: str) -> bool:
    if not isinstance(value, bool):
        raise EvaluationError(f"`{op}` expects true or false, found {_shown(value)}")
    return value


def _is_number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def _arith(op: str, left: Any, right: Any) -> Any:
    if op == "+" and isinstance(left, str) and isinstance(right, str):
        if len(left) + len(right) > MAX_TEXT:
            raise EvaluationError(f"text longer than {MAX_TEXT} characters")
        return left + right
    if not (_is_number(left) and _is_number(right)):
        raise EvaluationError(f"`{op}` expects two numbers (or, for +, two texts), found {_shown(left)} and "
                              f"{_shown(right)}")
    if op in ("/", "//", "%") and right == 0:
        raise EvaluationError(f"division by zero ({_shown(left)} {op} 0)")
    try:
        result = {"+": lambda: left + right, "-": lambda: left - right, "*": lambda: left * right,
                  "/": lambda: left / right, "//": lambda: left // right, "%": lambda: left % right}[op]()
    except OverflowError:
        raise EvaluationError(f"{_shown(left)} {op} {_shown(right)} is too large") from None
    if isinstance(result, float) and not math.isfinite(result):
        raise EvaluationError(f"{_shown(left)} {op} {_shown(right)} is not a finite number")
    return result


def _kind(value: Any) -> str:
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "bool"
    if _is_number(value):
        return "number"
    return type(value).__name__


def _compare(op: str, left: Any, right: Any) -> bool:
    kinds = {_kind(left), _kind(right)}
    if op in ("==", "!="):
        if len(kinds) > 1 and "null" not in kinds:
            raise EvaluationError(f"cannot compare {_shown(left)} with {_shown(right)} (a {_kind(left)} and "
                                  f"a {_kind(right)})")
        return (left == right) == (op == "==")
    if kinds not in ({"number"}, {"str"}):
        raise EvaluationError(f"`{op}` expects two numbers or two texts, found {_shown(left)} and "
                              f"{_shown(right)}")
    return {"<": left < right, "<=": left <= right, ">": left > right, ">=": left >= right}[op]


def _shown(value: Any) -> str:
    words = {None: "null", True: "true", False: "false"}
    text = words[value] if value is None or isinstance(value, bool) else repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


__all__ = ["Assignment", "EvaluationError", "Expression", "ExpressionError", "Script", "parse_expression",
           "parse_script"]
