"""The intent leaf's files: the scene graph file it reads and the outcome of each command it writes.

:func:`find_scene_graph` finds a graph file by path or shipped name; :func:`record_outcome` adds one
command's outcome (served or not, which object, why, whether confirmed) to summary.json's
``outcome.intent`` and to ``<run_dir>/intent_served.json``, so that a user sees what was served.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from missiontree.engine.context import MissionContext

#: The run-directory file listing each command's outcome: served object, why, confirmed (or why not).
SERVED_FILE = "intent_served.json"


def find_scene_graph(name: str) -> Path:
    """A graph file: ``name`` itself when it is a file, else ``config/scene_graphs/<name>.json``.

    Raises:
        ConfigError: Neither exists (lists the shipped graphs).
    """
    from missiontree.errors import ConfigError
    from missiontree.paths import config_dirs

    path = Path(name).expanduser()
    if path.is_file():
        return path
    if path.suffix == "" and "/" not in name:
        for folder in config_dirs():
            candidate = folder / "scene_graphs" / f"{name}.json"
            if candidate.is_file():
                return candidate
    shipped = sorted({p.stem for d in config_dirs() for p in (d / "scene_graphs").glob("*.json")})
    raise ConfigError(
        f"scene graph {name!r} not found: expected a JSON file in the NAIS shape or a shipped "
        f"name ({', '.join(shipped) or 'none'}); give --set scene_graph=path/to/graph.json"
    )


def record_outcome(ctx: MissionContext | None, record: dict[str, Any]) -> dict[str, str]:
    """Add one command's outcome to summary.json's ``outcome.intent`` and ``intent_served.json``.

    The ``intent`` section lists every command of the run (``commands``) with counts, so that a user
    reading summary.json sees what was served, why and whether it was confirmed. Returns the path and
    error when the file could not be written (empty when it was, or when the run has no directory).
    """
    if ctx is None:
        return {}
    before = ctx.outcome.get("intent", {})
    commands = [*(before.get("commands", []) if isinstance(before, dict) else []), record]
    ctx.report("intent", {
        "served": sum(1 for c in commands if c.get("status") == "served"),
        "not_served": sum(1 for c in commands if c.get("status") != "served"),
        "commands": commands,
        "text": said(record),
    })
    if ctx.run_dir is None:
        return {}
    path = Path(ctx.run_dir) / SERVED_FILE
    try:
        fresh = ctx.starts(path) or not path.is_file()
        entries = [] if fresh else json.loads(path.read_text(encoding="utf-8"))
        path.write_text(json.dumps([*entries, record], indent=1, default=str) + "\n", encoding="utf-8")
    except (OSError, ValueError) as error:
        return {"path": str(path), "error": str(error)}
    return {}


def said(record: dict[str, Any]) -> str:
    """One command's outcome in the mission's words, for the terminal's result line."""
    command = record.get("command", "")
    if record.get("status") == "served":
        state = "confirmed" if record.get("confirmed") else "not confirmed"
        because = record.get("chosen_because") or "the model named it"
        return (f"{command!r}: served at {record.get('object')} ({record.get('label')}, {state}); "
                f"chosen because {because}")
    return f"{command!r}: not served: {record.get('reason', '')}"
