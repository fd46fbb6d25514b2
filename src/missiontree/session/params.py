"""``run --set key=value``: command-line values for a mission's ``params:``, checked before loading.

Each value is read as YAML (``3`` is a number, ``true`` a truth value, ``[1, 2]`` a list) and then
held to the type of the parameter's default in the mission file: a whole number for ``laps: 1``,
a number for ``speed: 0.3`` (whole numbers too), true/false for a truth value, text for text (any
value is kept exactly as typed, so ``--set target=3`` gives the text ``"3"``), a list or a mapping
for those. A parameter whose default is ``null`` takes any value. The loader then substitutes the
values and checks every node parameter that reads them against that node's declared type, so a
value the port cannot take is reported at the line that reads it.
"""

from __future__ import annotations

import difflib
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import yaml

from missiontree.errors import ConfigError, ProblemsError
from missiontree.yamlio import load_yaml, parse_yaml

__all__ = ["declared_params", "parse_assignment", "parse_overrides"]


def parse_assignment(text: str) -> tuple[str, str]:
    """Split ``key=value`` (the value may hold ``=``); raise ConfigError on anything else."""
    key, sep, value = text.partition("=")
    key = key.strip()
    if not sep or not key:
        raise ConfigError(f"--set expects key=value (e.g. --set laps=3), found {text!r}")
    return key, value


def declared_params(mission: Path) -> dict[str, Any]:
    """The ``params:`` defaults a mission file declares (empty when it has none or cannot be read).

    A file that cannot be read or parsed is left to the loader, which reports it with its line.
    """
    try:
        data = load_yaml(mission).data
    except ProblemsError:
        return {}
    if not isinstance(data, dict) or not isinstance(data.get("params"), dict):
        return {}
    return {str(k): v for k, v in data["params"].items()}


def parse_overrides(mission: Path, raw: Mapping[str, Any] | None) -> dict[str, Any]:
    """Check and convert ``--set`` values against the mission's declared parameters.

    Args:
        mission: The mission file.
        raw: Parameter name → value; text values are read as YAML, others are taken as they are.

    Returns:
        Parameter name → typed value, for :func:`~missiontree.engine.loader.load_mission`.

    Raises:
        ConfigError: An unknown name or a value of the wrong type (lists the mission's params).
    """
    if not raw:
        return {}
    declared = declared_params(mission)
    values: dict[str, Any] = {}
    problems: list[str] = []
    for name, given in raw.items():
        if name not in declared:
            near = difflib.get_close_matches(name, list(declared), n=1)
            hint = f"; did you mean {near[0]!r}?" if near else ""
            problems.append(f"--set {name}: the mission declares no parameter {name!r}{hint}")
            continue
        try:
            values[name] = _convert(name, given, declared[name])
        except ConfigError as error:
            problems.append(str(error))
    if problems:
        raise ConfigError("; ".join(problems) + f"\n  {describe_params(mission, declared)}")
    return values


def describe_params(mission: Path, declared: Mapping[str, Any]) -> str:
    """One sentence listing a mission's parameters with their defaults and types."""
    if not declared:
        return f"{mission} declares no params: (add `params: {{name: default}}` to set values with --set)"
    shown = ", ".join(f"{k}={yaml.safe_dump(v, default_flow_style=True).strip().removesuffix('...').strip()}"
                      f" ({_kind(v)})" for k, v in declared.items())
    return f"Parameters of {mission}: {shown}"


def _convert(name: str, given: Any, default: Any) -> Any:
    if isinstance(default, str):
        return given if isinstance(given, str) else str(given)
    value = _read(name, given)
    if default is None:
        return value
    expected = _kind(default)
    ok = {
        "true/false": isinstance(value, bool),
        "whole number": isinstance(value, int) and not isinstance(value, bool),
        "number": isinstance(value, int | float) and not isinstance(value, bool),
        "list": isinstance(value, list),
        "mapping": isinstance(value, dict),
    }.get(expected, True)
    if not ok:
        raise ConfigError(f"--set {name}: expected a {expected} (the default is {default!r}), "
                          f"found {given!r}")
    if expected == "number":
        return float(value)
    return value


def _read(name: str, given: Any) -> Any:
    if not isinstance(given, str):
        return given
    if not given.strip():
        return ""
    try:  # the same reader as every file: plain values only, timestamps stay text
        return parse_yaml(given, f"--set {name}").data
    except ProblemsError as error:
        problem = error.problems[0].message if error.problems else "not a YAML value"
        raise ConfigError(f"--set {name}: cannot read {given!r} ({problem}); quote text values") from None


def _kind(value: Any) -> str:
    if isinstance(value, bool):
        return "true/false"
    if isinstance(value, int):
        return "whole number"
    if isinstance(value, float):
        return "number"
    if isinstance(value, str):
        return "text"
    if isinstance(value, list):
        return "list"
    if isinstance(value, dict):
        return "mapping"
    return "any value"
