"""Pydantic's validation errors as located problems: the one translation for every config file.

:func:`validation_problems` turns each error of a ``pydantic.ValidationError`` into a
:class:`~missiontree.errors.Problem` at its key's ``file:line:col`` in the
:class:`~missiontree.yamlio.located.Located` document (worlds, robot profiles, map yamls, the
mission's ``run:`` section); :func:`error_message` and :func:`short_repr` word one error and one
value for messages that are not located (a provider's options); :func:`expected_text` is the
"what was expected" of one error, which the node-parameter checks build their messages on. No other
module reads pydantic's error dictionaries.
"""

from __future__ import annotations

import difflib
from typing import Any

from missiontree.errors import Problem
from missiontree.yamlio.located import KeyPath, Located


def validation_problems(
    exc: Any,
    doc: Located,
    model: Any = None,
    *,
    prefix: KeyPath = (),
    docs: str = "",
    where: str | None = None,
) -> list[Problem]:
    """Every error of a pydantic ``ValidationError`` as a :class:`Problem` at its key in ``doc``.

    The one place where a config file's schema errors become ``file:line:col`` problems (worlds,
    robot profiles, map yamls, models configs). Unknown keys point at the key and list the known
    ones; missing keys point at the mapping that lacks them; a wrong value shows what was found,
    shortened, never a whole nested value (so a file read by mistake is not echoed back).

    Args:
        exc: The ``pydantic.ValidationError`` raised by validating ``doc.data`` (or a part of it).
        doc: The located document.
        model: The pydantic model validated, to list the known keys of an unknown key's mapping.
        prefix: Where the validated data sits in ``doc`` (empty when it is the whole document).
        docs: The document that describes the format, named in hints (e.g. ``docs/worlds.md``).
        where: The node path shown with each problem (default: the key path).
    """
    problems: list[Problem] = []
    for err in exc.errors():
        loc = tuple(p for p in err["loc"] if isinstance(p, str | int))
        written = _written(doc.data, prefix, loc, err["type"])
        problems.append(doc.problem_at(
            (*prefix, *written), error_message(err, model), _hint_for(err, docs, model),
            key=err["type"] == "extra_forbidden", where=where))
    return problems


def expected_text(err: Any) -> str:
    """What one pydantic error expected, in words: its message without pydantic's prefixes."""
    msg = str(err.get("msg", ""))
    for prefix in ("Input should be ", "Value error, ", "Assertion failed, "):
        msg = msg.removeprefix(prefix)
    return msg


def error_lines(exc: Any, model: Any = None, whole: str = "options") -> list[str]:
    """Every error of a ``ValidationError`` as ``key.path: what was expected, what was found``.

    For messages that are not located in a file (``whole`` names the value when the error is about
    all of it).
    """
    return [f"{'.'.join(str(p) for p in err['loc']) or whole}: {error_message(err, model)}"
            for err in exc.errors()]


def error_message(err: Any, model: Any = None) -> str:
    """One pydantic error as "what was expected, what was found" (short; values are truncated)."""
    loc = tuple(err["loc"])
    if err["type"] == "extra_forbidden":
        allowed = _allowed_keys(model, loc[:-1]) if model is not None else []
        known = f"; expected one of: {', '.join(allowed)}" if allowed else ""
        return f"unknown key {str(loc[-1])!r}{known}"
    if err["type"] == "missing":
        return f"missing required key {str(loc[-1])!r}"
    msg = str(err.get("msg", "invalid value"))
    found = err.get("input")
    if err["type"] == "finite_number" or (isinstance(found, float) and found != found):  # NaN
        msg = "expected a finite number"
    elif msg.startswith("Input should be "):
        msg = "expected " + expected_text(err)
    else:
        msg = expected_text(err) or "invalid value"
    return f"{msg}, found {short_repr(found)}"


def short_repr(value: Any, limit: int = 60) -> str:
    """``repr(value)`` when short; else its kind ("a mapping", "a list", "text of 1,234 characters")."""
    if isinstance(value, dict):
        text = repr(value)
        return text if len(text) <= limit else f"a mapping of {len(value)} keys"
    if isinstance(value, list | tuple):
        text = repr(value)
        return text if len(text) <= limit else f"a list of {len(value)} values"
    if isinstance(value, str) and len(value) > limit:
        return f"text of {len(value):,} characters"
    text = repr(value)
    return text if len(text) <= limit else f"a {type(value).__name__}"


def _written(data: Any, prefix: KeyPath, loc: tuple[str | int, ...], kind: str) -> tuple[str | int, ...]:
    """:func:`written_loc` of the value at ``prefix`` in ``data``."""
    for part in prefix:
        try:
            data = data[part]
        except (KeyError, IndexError, TypeError):
            return ()
    return written_loc(data, loc, kind)


def written_loc(data: Any, loc: tuple[Any, ...], kind: str) -> tuple[str | int, ...]:
    """The part of a pydantic ``loc`` that names keys and indices present in the written ``data``.

    pydantic puts union-member tags (``int``, ``str``, a model's name) in ``loc``: they are dropped.
    A missing or unknown key (``kind`` ``missing`` or ``extra_forbidden``) is kept as the last part.
    """
    kept: list[str | int] = []
    for part in loc:
        if isinstance(data, dict) and part in data:
            data = data[part]
        elif isinstance(data, list) and isinstance(part, int) and 0 <= part < len(data):
            data = data[part]
        elif kind in ("missing", "extra_forbidden") and not isinstance(part, int) and part == loc[-1]:
            pass  # the missing/extra key itself is kept below
        else:
            continue
        kept.append(part)
    return tuple(kept)


def _hint_for(err: Any, docs: str, model: Any = None) -> str:
    where = f" ({docs} lists every key)" if docs else ""
    if err["type"] == "extra_forbidden":
        loc = tuple(err["loc"])
        allowed = _allowed_keys(model, loc[:-1]) if model is not None and loc else []
        near = difflib.get_close_matches(str(loc[-1]), allowed, n=1) if allowed else []
        return f"did you mean {near[0]!r}?" if near else f"check the spelling{where}"
    if err["type"] == "missing":
        return f"add the key{where}"
    return ""


def _allowed_keys(model: Any, loc: tuple[Any, ...]) -> list[str]:
    """Field names of the model reached by following ``loc`` through nested models and lists."""
    import types
    import typing

    current: Any = model
    for part in loc:
        if isinstance(part, int):
            continue
        fields = getattr(current, "model_fields", None)
        if not fields or part not in fields:
            return []
        current = fields[part].annotation
        for _ in range(3):  # unwrap Optional[...] / list[...] down to a model
            origin = typing.get_origin(current)
            if origin in (list, typing.Union, types.UnionType):
                args = [a for a in typing.get_args(current) if a is not type(None)]
                current = args[0] if args else current
    fields = getattr(current, "model_fields", None)
    return list(fields) if fields else []
