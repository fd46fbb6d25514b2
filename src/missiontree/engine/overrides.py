"""``--set key=value``: command-line values for a mission's ``params:``, checked while it loads.

Each value given as text is read as YAML (``3`` is a number, ``true`` a truth value, ``[1, 2]`` a
list) and then held to the type of the parameter's default in the mission file: a whole number for
``laps: 1``, a number for ``speed: 0.3`` (whole numbers too), true/false for a truth value, text for
text (any value is kept exactly as typed, so ``--set target=3`` gives the text ``"3"``), a list or a
mapping for those. A parameter whose default is ``null`` takes any value. The loader
(:mod:`missiontree.engine.loader`) reports an unknown name or a value of the wrong type at the
mission's ``params.<name>`` with ``file:line:col``, then checks every node parameter that reads the
value against that node's declared type.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import yaml

from missiontree.errors import ProblemsError
from missiontree.yamlio import parse_yaml

__all__ = ["OverrideError", "convert_override", "describe_params", "kind_of"]


class OverrideError(ValueError):
    """A ``--set`` value the parameter cannot take (the message says why)."""


def convert_override(name: str, given: Any, default: Any) -> Any:
    """``given`` (text read as YAML, or a value) held to the type of ``default``.

    Raises:
        OverrideError: The value cannot be read or is not of the default's type.
    """
    if isinstance(default, str):
        return given if isinstance(given, str) else str(given)
    value = _read(name, given)
    if default is None:
        return value
    expected = kind_of(default)
    ok = {
        "true/false": isinstance(value, bool),
        "whole number": isinstance(value, int) and not isinstance(value, bool),
        "number": isinstance(value, int | float) and not isinstance(value, bool),
        "list": isinstance(value, list),
        "mapping": isinstance(value, dict),
    }.get(expected, True)
    if not ok:
        raise OverrideError(f"--set {name}: expected a {expected} (the default is {default!r}), "
                            f"found {given!r}")
    if expected == "number":
        return float(value)
    return value


def describe_params(mission: Any, declared: Mapping[str, Any]) -> str:
    """One sentence listing a mission's parameters with their defaults and types (a problem's hint)."""
    if not declared:
        return f"{mission} declares no params: (add `params: {{name: default}}` to set values with --set)"
    shown = ", ".join(f"{k}={yaml.safe_dump(v, default_flow_style=True).strip().removesuffix('...').strip()}"
                      f" ({kind_of(v)})" for k, v in declared.items())
    return f"Parameters of {mission}: {shown}"


def _read(name: str, given: Any) -> Any:
    if not isinstance(given, str):
        return given
    if not given.strip():
        return ""
    try:  # the same reader as every file: plain values only, timestamps stay text
        return parse_yaml(given, f"--set {name}").data
    except ProblemsError as error:
        problem = error.problems[0].message if error.problems else "not a YAML value"
        raise OverrideError(f"--set {name}: cannot read {given!r} ({problem}); quote text values") from None


#: Each kind a parameter's default may have, as the messages name it: bool before int (a bool is an int).
KINDS: tuple[tuple[type, str], ...] = (
    (bool, "true/false"), (int, "whole number"), (float, "number"), (str, "text"), (list, "list"),
    (dict, "mapping"))


def kind_of(value: Any) -> str:
    """The kind of a parameter's default, as the messages name it."""
    return next((name for kind, name in KINDS if isinstance(value, kind)), "any value")
