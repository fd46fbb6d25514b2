"""Where missiontree finds its shipped configuration (worlds, robots, models, backends, trees).

A name such as ``combined`` or ``turtlebot4`` is looked up as ``<dir>/<kind>/<name>.yaml`` in, in
order: the folders of ``$MISSIONTREE_CONFIG_PATH`` (``os.pathsep``-separated), ``./config`` and the
repository's ``config/`` folder. A value that is already a path to an existing file is used as is.
"""

from __future__ import annotations

import os
from pathlib import Path

from missiontree.errors import ConfigError

#: The repository root when installed from a checkout (src layout: src/missiontree/paths.py).
REPO_ROOT = Path(__file__).resolve().parents[2]


def config_dirs() -> list[Path]:
    """The configuration folders searched, most specific first."""
    dirs = [Path(p) for p in os.environ.get("MISSIONTREE_CONFIG_PATH", "").split(os.pathsep) if p]
    dirs += [Path.cwd() / "config", REPO_ROOT / "config"]
    seen: list[Path] = []
    for d in dirs:
        if d not in seen:
            seen.append(d)
    return seen


def available(kind: str) -> list[str]:
    """Names of every ``<kind>/*.yaml`` in the configuration folders."""
    names: set[str] = set()
    for d in config_dirs():
        names.update(p.stem for p in (d / kind).glob("*.yaml"))
    return sorted(names)


#: What one file of each kind is called in messages.
_NOUNS = {"worlds": "world", "robots": "robot profile", "models": "models config",
          "waypoints": "waypoint file", "backends": "run configuration"}


def find_config(kind: str, name: str | os.PathLike[str]) -> Path:
    """Resolve ``name`` (a path or a shipped name) to a file of ``kind`` (``worlds``, ``robots``, ...).

    Raises:
        ConfigError: Nothing found; the message lists the names that exist.
    """
    noun = _NOUNS.get(kind, kind[:-1] if kind.endswith("s") else kind)
    as_path = Path(name)
    if as_path.suffix in {".yaml", ".yml"} or as_path.is_file():
        if as_path.is_file():
            return as_path
        raise ConfigError(f"{noun}{'' if noun.endswith('file') else ' file'} {str(name)!r} does not exist")
    for d in config_dirs():
        candidate = d / kind / f"{name}.yaml"
        if candidate.is_file():
            return candidate
    known = ", ".join(available(kind)) or "none"
    raise ConfigError(f"unknown {noun} {str(name)!r}; known: {known} (or give a path to a .yaml file)")
