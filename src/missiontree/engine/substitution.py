"""Subtree parameters: ``${name}`` in a mission or subtree file replaced by the parameter's value.

- A value that is exactly ``"${name}"`` becomes the parameter's value with its type (a number, a
  list, a mapping, a ``{bb: key}`` reference).
- ``${name}`` inside longer text is interpolated; a mapping or list there is a problem.
- ``$${`` writes a literal ``${``.

An unknown name is a problem naming the declared parameters; problems are collected, not raised,
so the loader reports every one at once.
"""

from __future__ import annotations

import copy
import difflib
import re
from typing import Any

from missiontree.errors import Problem
from missiontree.yamlio import Located
from missiontree.yamlio import short_repr as shown

_PARAM_RE = re.compile(r"\$\{([^}]*)\}")


def substitute(value: Any, values: dict[str, Any], doc: Located, key_path: tuple[str | int, ...], where: str,
               problems: list[Problem]) -> Any:
    """``value`` (nested) with every ``${name}`` replaced from ``values``; problems go to ``problems``."""
    if isinstance(value, dict):
        return {k: substitute(v, values, doc, (*key_path, k), where, problems) for k, v in value.items()}
    if isinstance(value, list):
        return [substitute(v, values, doc, (*key_path, i), where, problems) for i, v in enumerate(value)]
    if not isinstance(value, str) or "${" not in value:
        return value
    whole = _PARAM_RE.fullmatch(value)
    if whole and not value.startswith("$${"):
        name = whole.group(1)
        if _check_param(name, values, doc, key_path, problems):
            return copy.deepcopy(values[name])
        return value

    def replace(match: re.Match[str]) -> str:
        name = match.group(1)
        if match.start() > 0 and value[match.start() - 1] == "$":
            return match.group(0)
        if not _check_param(name, values, doc, key_path, problems):
            return match.group(0)
        found = values[name]
        if isinstance(found, dict | list):
            problems.append(doc.problem_at(
                key_path, f"expected a plain value for ${{{name}}} inside text, found {kind(found)}",
                f"use `${{{name}}}` alone as the whole value to pass a mapping or list", where=where))
            return match.group(0)
        return str(found)

    return _PARAM_RE.sub(replace, value).replace("$${", "${")


def _check_param(name: str, values: dict[str, Any], doc: Located, key_path: tuple[str | int, ...],
                 problems: list[Problem]) -> bool:
    if name in values:
        return True
    known = sorted(values)
    near = difflib.get_close_matches(name, known, n=1)
    problems.append(doc.problem_at(
        key_path, f"expected a reference to a declared parameter ({', '.join(known) or 'none'}), "
        f"found ${{{name}}}",
        f"did you mean ${{{near[0]}}}?" if near else "declare it under `params:` at the top of the file "
        "(write $${ for a literal ${)"))
    return False


def kind(value: Any) -> str:
    """How a value reads in a problem: ``a mapping``, ``a list``, ``nothing``, ``int 3``."""
    if isinstance(value, dict):
        return "a mapping"
    if isinstance(value, list):
        return "a list"
    if value is None:
        return "nothing"
    return f"{type(value).__name__} {shown(value)}"
