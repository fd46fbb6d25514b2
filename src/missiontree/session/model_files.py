"""Files a models config names (ONNX models, labels, tokenizers): confined, size-bounded, never echoed.

A provider factory declares the options that name files with the attribute ``path_options``: option
name → :class:`FileOption` (what the file is, and its size limit). For every such option a models
config sets, :func:`model_file_problems` checks, before anything is built or read:

- the path, relative to the models config's folder (or the working directory for a config given as
  data), resolved with every symlink followed, lies inside that folder, inside the package's own
  data (``missiontree/data``, e.g. the shipped detector), or inside a folder listed in
  ``$MISSIONTREE_MODEL_PATH`` (folders separated by ``os.pathsep``, ``:`` on Linux);
- if the file exists, it is a regular file of at most its limit (:mod:`missiontree.file_limits`:
  512 MiB for an ONNX model, 64 MiB for a tokenizer, 1 MiB for a labels file), checked with ``stat``
  before a byte is read.

A file that does not exist is left to the provider, which reports it when it is built (its role is
then unusable with the reason). Problems are located (``file:line:col`` of the option) and name the
path as the config wrote it; they never show a byte of the file, and the resolved path only when it
is allowed. The checked options are handed to the factory as absolute paths, so the provider opens
the file that was checked.
"""

from __future__ import annotations

import os
import stat
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from missiontree.errors import MissionTreeError, Problem
from missiontree.file_limits import MODEL_PATH_ENV, PACKAGE_DATA, FileOption, model_dirs
from missiontree.yamlio import Located

#: Keys of a role's section that are the wiring's, not the provider's options.
_ROLE_KEYS = frozenset({"provider", "latency", "timeout"})


def config_base(models: Any, document: Located) -> Path:
    """The folder relative paths of a models config resolve against (its own; data: the working dir)."""
    if isinstance(models, Mapping):
        return Path.cwd()
    return Path(document.file).resolve().parent


def path_options(factory: Any) -> Mapping[str, FileOption]:
    """The file options a provider factory declares (``path_options``); empty when it declares none."""
    declared = getattr(factory, "path_options", None)
    return declared if isinstance(declared, Mapping) else {}


def model_file_problems(
    document: Located, roles: Mapping[str, Mapping[str, Any]], providers: Mapping[str, Any], base: Path
) -> tuple[list[Problem], dict[str, dict[str, str]]]:
    """Check every file a models config's roles name.

    Args:
        document: The models config (for positions).
        roles: Its role sections (from ``check_models_config``).
        providers: Provider name → factory.
        base: The folder relative paths resolve against (see :func:`config_base`).

    Returns:
        Every problem, and role → option → the resolved absolute path, for the files that passed.
    """
    from missiontree.plugins.builtin import resolve_factory

    problems: list[Problem] = []
    resolved: dict[str, dict[str, str]] = {}
    allowed = [base.resolve(), PACKAGE_DATA, *model_dirs()]
    for role, section in roles.items():
        name = section.get("provider")
        if not isinstance(name, str) or name not in providers:
            continue
        try:
            factory = resolve_factory("provider", name, providers[name])
        except (ImportError, MissionTreeError):
            continue  # the role is unusable; reported when the models are built
        for option, spec in path_options(factory).items():
            value = section.get(option)
            if isinstance(value, os.PathLike):  # a config given as data may hold Path objects
                value = os.fspath(value)
            if option in _ROLE_KEYS or not isinstance(value, str):
                continue  # absent, or not a string (the provider's options check reports that)
            key = ("roles", role, option)
            path, problem = _check_file(value, spec, base.resolve(), allowed)
            if problem is not None:
                message, hint = problem
                problems.append(document.problem_at(key, message, hint))
            elif path is not None:
                resolved.setdefault(role, {})[option] = str(path)
    return problems, resolved


def _check_file(value: str, spec: FileOption, base: Path, allowed: list[Path]
                ) -> tuple[Path | None, tuple[str, str] | None]:
    """The resolved path of one file option, or (None, (message, hint)) when it may not be read."""
    try:
        path = (base / Path(value).expanduser()).resolve()
    except (OSError, ValueError, RuntimeError):
        return None, (f"expected a path to {_a(spec.what)}, found {value!r}, which is not a valid path", "")
    if not any(path.is_relative_to(d) for d in allowed):
        return None, (f"expected {_a(spec.what)} inside {base} (the models config's folder), the "
                      f"package's data or ${MODEL_PATH_ENV}, found {value!r} outside them",
                      f"copy the file next to the models config, or add its folder to ${MODEL_PATH_ENV}")
    try:
        info = path.stat()
    except FileNotFoundError:
        return path, None  # the provider says it is missing when it is built
    except (OSError, ValueError):
        return None, (f"cannot examine the {spec.what} {value!r} (looked at {path})", "")
    if not stat.S_ISREG(info.st_mode):
        return None, (f"expected {_a(spec.what)}, found {value!r}, which is not a regular file "
                      f"(looked at {path})", "")
    if info.st_size > spec.max_bytes:
        return None, (f"expected {_a(spec.what)} of at most {_size(spec.max_bytes)}, found {value!r} of "
                      f"{_size(info.st_size)}", "is this the right file?")
    return path, None


def _a(what: str) -> str:
    return f"{'an' if what[:1].lower() in 'aeiou' else 'a'} {what}"


def _size(n: int) -> str:
    if n >= 2**20:
        return f"{n / 2**20:.0f} MiB" if n % 2**20 == 0 else f"{n / 2**20:.1f} MiB"
    if n >= 1024:
        return f"{n / 1024:.1f} KiB"
    return f"{n} bytes"
