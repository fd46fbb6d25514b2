"""``run --set key=value``: the command line's assignments, split into names and values.

The values stay as typed; :func:`missiontree.engine.loader.load_mission` (``params=``) reads and
checks each against the type of the mission's default while it loads the file
(:mod:`missiontree.engine.overrides`), reporting a bad one at ``params.<name>`` with ``file:line:col``.
"""

from __future__ import annotations

from missiontree.errors import ConfigError

__all__ = ["parse_assignment"]


def parse_assignment(text: str) -> tuple[str, str]:
    """Split ``key=value`` (the value may hold ``=``); raise ConfigError on anything else."""
    key, sep, value = text.partition("=")
    key = key.strip()
    if not sep or not key:
        raise ConfigError(f"--set expects key=value (e.g. --set laps=3), found {text!r}")
    return key, value
