"""Plain YAML data with the source position of every key and value, and the reader's limits.

:class:`Located` is what :func:`~missiontree.yamlio.load_yaml` returns: ``doc.data`` is the
document as plain Python data, ``doc.position(path)`` the 1-based line and column of any key path,
``doc.problem_at(path, message)`` a :class:`~missiontree.errors.Problem` located there.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

from missiontree.errors import Problem

#: A key path into the data: mapping keys (str) and sequence indices (int).
KeyPath = tuple[str | int, ...]


@dataclass(frozen=True)
class YamlLimits:
    """What one file may cost to read.

    Attributes:
        max_bytes: Largest file accepted, in bytes.
        max_depth: Deepest nesting of mappings and sequences.
        max_nodes: Most values (after alias expansion) in the whole document.
    """

    max_bytes: int = 256 * 1024
    max_depth: int = 64
    max_nodes: int = 100_000


DEFAULT_LIMITS = YamlLimits()


class Located:
    """Plain YAML data plus the source position of every key and value.

    Attributes:
        data: The document as plain Python data.
        file: The file name used in problems (as the user named it).
    """

    def __init__(
        self,
        data: Any,
        file: str,
        values: dict[KeyPath, tuple[int, int]],
        keys: dict[KeyPath, tuple[int, int]],
        prefix: KeyPath = (),
    ) -> None:
        self.data = data
        self.file = file
        self._values = values
        self._keys = keys
        self._prefix = prefix

    def position(self, path: Iterable[str | int], *, key: bool = False) -> tuple[int, int]:
        """The 1-based (line, col) of the value at ``path`` (or of its key when ``key=True``).

        A path that does not exist (a missing key) falls back to its nearest existing ancestor,
        so "missing parameter" problems point at the mapping that lacks it.
        """
        full = self._prefix + tuple(path)
        if key and full in self._keys:
            return self._keys[full]
        while full:
            if full in self._values:
                return self._values[full]
            full = full[:-1]
        return self._values.get((), (1, 1))

    def has(self, path: Iterable[str | int]) -> bool:
        """Whether ``path`` names a value that was in the file."""
        return self._prefix + tuple(path) in self._values

    def problem_at(
        self,
        path: Iterable[str | int],
        message: str,
        hint: str = "",
        *,
        key: bool = False,
        where: str | None = None,
    ) -> Problem:
        """A Problem located at ``path``; ``where`` is the path shown (default: the key path)."""
        path = tuple(path)
        line, col = self.position(path, key=key)
        shown = format_path(self._prefix + path) if where is None else where
        return Problem(self.file, line, col, shown, message, hint)

    def child(self, path: Iterable[str | int]) -> Located:
        """A view of the value at ``path`` whose positions and paths are relative to it."""
        path = tuple(path)
        data = self.data
        for part in path:
            data = data[part]
        return Located(data, self.file, self._values, self._keys, self._prefix + path)


    def view(self, path: Iterable[str | int], data: Any) -> Located:
        """Like :meth:`child`, but with ``data`` given (e.g. after substitution changed the value)."""
        return Located(data, self.file, self._values, self._keys, self._prefix + tuple(path))


def format_path(path: Iterable[str | int]) -> str:
    """Render a key path as ``root.children[2].Wait``."""
    text = ""
    for part in path:
        text += f"[{part}]" if isinstance(part, int) else (f".{part}" if text else str(part))
    return text
