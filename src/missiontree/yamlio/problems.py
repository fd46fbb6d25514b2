"""Pydantic's validation errors as located problems: the one translation for every config file.

:func:`validation_problems` turns each error of a ``pydantic.ValidationError`` into a
:class:`~missiontree.errors.Problem` at its key's ``file:line:col`` in the
:class:`~missiontree.yamlio.located.Located` document; :func:`error_message` and
:func:`short_repr` word one error and one value for messages that are not located.
"""

from __future__ import annotations

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
    """
    problems: list[Problem] = []
    for err in exc.errors():
        loc = tuple(p for p in err["loc"] if isinstance(p, str | int))
        written = _written(doc.data, prefix, loc)
        problems.append(doc.problem_at(
            (*prefix, *written), error_message(err, model), _hint_for(err, docs),
            key=err["type"] == "extra_forbidden"))
    return problems


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
    for prefix in ("Value error, ", "Assertion failed, "):
        msg = msg.removeprefix(prefix)
    found = err.get("input")
    if err["type"] == "finite_number" or (isinstance(found, float) and found != found):  # NaN
        msg = "expected a finite number"
    elif msg.startswith("Input should be "):
        msg = "expected " + msg.removeprefix("Input should be ")
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


def _written(data: Any, prefix: KeyPath, loc: tuple[str | int, ...]) -> tuple[str | int, ...]:
    """The leading part of ``loc`` that names keys and indices present in the data (drops union tags)."""
    for part in prefix:
        try:
            data = data[part]
        except (KeyError, IndexError, TypeError):
            return ()
    kept: list[str | int] = []
    for i, part in enumerate(loc):
        if isinstance(data, dict) and part in data:
            data = data[part]
        elif isinstance(data, list) and isinstance(part, int) and 0 <= part < len(data):
            data = data[part]
        elif i == len(loc) - 1:
            kept.append(part)  # a missing or unknown key itself: position() falls back to its mapping
            break
        else:
            continue
        kept.append(part)
    return tuple(kept)


def _hint_for(err: Any, docs: str) -> str:
    where = f" ({docs} lists every key)" if docs else ""
    if err["type"] == "extra_forbidden":
        return f"check the spelling{where}"
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
