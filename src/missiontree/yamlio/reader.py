"""The safe, bounded YAML reader: text or a file in, a :class:`~missiontree.yamlio.located.Located` out.

Refuses, each as a located :class:`~missiontree.errors.Problem`: binary or non-UTF-8 input, control
characters, tabs in indentation, syntax errors, several documents, duplicate or non-scalar keys,
object-building tags, nesting deeper than the limit and more values than the limit after alias
expansion (checked while composing and building, so an alias bomb stops in bounded memory).
"""

from __future__ import annotations

import os
import re
from pathlib import Path
from typing import Any

import yaml
from yaml.composer import Composer
from yaml.constructor import SafeConstructor
from yaml.nodes import MappingNode, Node, ScalarNode, SequenceNode
from yaml.resolver import Resolver

from missiontree.errors import Problem, ProblemsError
from missiontree.yamlio.located import DEFAULT_LIMITS, KeyPath, Located, YamlLimits, format_path

_STANDARD_TAGS = {
    "tag:yaml.org,2002:str", "tag:yaml.org,2002:int", "tag:yaml.org,2002:float",
    "tag:yaml.org,2002:bool", "tag:yaml.org,2002:null", "tag:yaml.org,2002:timestamp",
    "tag:yaml.org,2002:seq", "tag:yaml.org,2002:map", "tag:yaml.org,2002:merge",
}
_MERGE_TAG = "tag:yaml.org,2002:merge"
_MAX_TAB_REPORTS = 20
_CONTROL = re.compile("[\x01-\x08\x0b\x0c\x0e-\x1f\x7f]")



def load_yaml(
    path: str | os.PathLike[str],
    *,
    limits: YamlLimits = DEFAULT_LIMITS,
    error: type[ProblemsError] = ProblemsError,
    display_name: str | None = None,
) -> Located:
    """Read and parse one YAML file safely.

    Args:
        path: The file to read.
        limits: Bounds on size, depth and node count.
        error: The ProblemsError subclass raised (MissionFileError, WorldFileError, ...).
        display_name: The file name used in problems (default: ``path`` as given).

    Raises:
        ProblemsError: (of class ``error``) the file is missing, too large or not valid YAML.
    """
    name = display_name if display_name is not None else str(path)
    file = Path(path)
    try:
        size = file.stat().st_size
        if size > limits.max_bytes:
            raise error([Problem(
                name, 1, 1, "", f"expected a file of at most {limits.max_bytes} bytes, found {size} bytes",
                "split the file into subtrees, or raise the limit if this size is intended",
            )])
        with file.open("rb") as handle:
            raw = handle.read(limits.max_bytes + 1)
    except IsADirectoryError:
        raise error([Problem(name, 0, 0, "", "expected a YAML file, found a directory")]) from None
    except FileNotFoundError:
        raise error([Problem(name, 0, 0, "", "file not found", "check the path")]) from None
    except OSError as exc:
        raise error([Problem(name, 0, 0, "", f"cannot read the file: {exc.strerror or exc}")]) from None
    return parse_yaml(raw, name, limits=limits, error=error)


def parse_yaml(
    source: str | bytes,
    file: str = "<string>",
    *,
    limits: YamlLimits = DEFAULT_LIMITS,
    error: type[ProblemsError] = ProblemsError,
) -> Located:
    """Parse YAML text (or bytes) safely; see :func:`load_yaml`."""
    text = _decode(source, file, limits, error)
    tab_problems = _tab_problems(text, file)
    if tab_problems:
        raise error(tab_problems)
    if not text.strip() or all(not ln.strip() or ln.lstrip().startswith("#") for ln in text.splitlines()):
        raise error([Problem(
            file, 1, 1, "", "expected a YAML document, found an empty file",
            "write the document (a mission starts with `root:`)",
        )])
    loader = _BoundedLoader(text, limits)
    try:
        try:
            node = loader.get_single_node()
        finally:
            loader.dispose()
    except _LimitExceeded as exc:
        raise error([Problem(file, exc.line, exc.col, "", exc.message, exc.hint)]) from None
    except yaml.MarkedYAMLError as exc:
        if "maximum nesting depth" in str(exc.problem):
            # PyYAML 6.0.4+ stops its scanner at 1,000 levels: in a flow collection it scans that
            # far ahead before the composer's own limit (above) sees the 65th level.
            mark = exc.problem_mark or exc.context_mark
            raise error([Problem(
                file, mark.line + 1 if mark else 1, mark.column + 1 if mark else 1, "",
                f"expected nesting of at most {limits.max_depth} levels, found deeper",
                "flatten the document or move parts into subtrees",
            )]) from None
        raise error([_syntax_problem(file, exc)]) from None
    except yaml.YAMLError as exc:
        raise error([Problem(file, 1, 1, "", f"not valid YAML: {exc}")]) from None
    if node is None:
        raise error([Problem(file, 1, 1, "", "expected a YAML document, found an empty file")])
    builder = _Builder(file, limits)
    try:
        data = builder.build(node, ())
    except _LimitExceededError as exc:
        raise error(exc.problems) from None
    if builder.problems:
        raise error(builder.problems)
    return Located(data, file, builder.values, builder.keys)


# -- reading ---------------------------------------------------------------------------------------


def _decode(source: str | bytes, file: str, limits: YamlLimits, error: type[ProblemsError]) -> str:
    if isinstance(source, str):
        if len(source) > limits.max_bytes:
            raise error([Problem(
                file, 1, 1, "", f"expected at most {limits.max_bytes} characters, found {len(source)}")])
        if "\x00" in source:
            raise error([_binary_problem(file, source.index("\x00"), source)])
        return _check_printable(source, file, error)
    if len(source) > limits.max_bytes:
        raise error([Problem(file, 1, 1, "", f"expected at most {limits.max_bytes} bytes, found more")])
    if b"\x00" in source:
        raise error([_binary_problem(file, source.index(b"\x00"), source)])
    try:
        text = source.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = source.count(b"\n", 0, exc.start) + 1
        col = exc.start - (source.rfind(b"\n", 0, exc.start) + 1) + 1
        raise error([Problem(
            file, line, col, "", f"expected UTF-8 text, found the byte 0x{source[exc.start]:02x}",
            "this looks like a binary file or another encoding; save it as UTF-8 YAML",
        )]) from None
    return _check_printable(text.removeprefix("\ufeff"), file, error)


def _check_printable(text: str, file: str, error: type[ProblemsError]) -> str:
    """Refuse control characters (YAML forbids them) with their line and column."""
    found = _CONTROL.search(text)
    if found is None:
        return text
    index = found.start()
    line = text.count("\n", 0, index) + 1
    col = index - (text.rfind("\n", 0, index) + 1) + 1
    raise error([Problem(
        file, line, col, "", f"expected printable text, found the control character {found.group()!r}",
        "remove it (YAML allows only tabs, line breaks and printable characters)",
    )])


def _binary_problem(file: str, index: int, source: str | bytes) -> Problem:
    newline: Any = "\n" if isinstance(source, str) else b"\n"
    line = source.count(newline, 0, index) + 1
    col = index - (source.rfind(newline, 0, index) + 1) + 1
    return Problem(
        file, line, col, "", "expected YAML text, found a NUL byte (a binary file)",
        "point at the YAML file itself, not a compiled or compressed one",
    )


def _tab_problems(text: str, file: str) -> list[Problem]:
    problems: list[Problem] = []
    for number, line in enumerate(text.splitlines(), start=1):
        indent = line[: len(line) - len(line.lstrip(" \t"))]
        if "\t" in indent and line.strip():
            if len(problems) == _MAX_TAB_REPORTS:
                problems.append(Problem(file, number, 1, "", "more lines are indented with tabs"))
                break
            problems.append(Problem(
                file, number, indent.index("\t") + 1, "", "expected spaces for indentation, found a tab",
                "YAML forbids tabs in indentation; replace them with spaces",
            ))
    return problems


def _syntax_problem(file: str, exc: yaml.MarkedYAMLError) -> Problem:
    mark = exc.problem_mark or exc.context_mark
    line, col = (mark.line + 1, mark.column + 1) if mark is not None else (1, 1)
    what = exc.problem or "invalid YAML"
    context = f" ({exc.context}" + (
        f" at line {exc.context_mark.line + 1})" if exc.context_mark is not None else ")"
    ) if exc.context else ""
    hint = "check indentation, colons and quoting on this line and the one before"
    if "found character '\\t'" in what or "found character '\t'" in what:
        hint = "replace the tab with spaces"
    elif "anchor" in what + str(exc.context) or "found undefined alias" in what:
        hint = "define the anchor (&name) before using the alias (*name), once"
    elif "expected a single document" in what or "but found another document" in what:
        what, hint = "expected one YAML document, found several", "remove the `---` separators"
    return Problem(file, line, col, "", f"YAML syntax error: {what}{context}", hint)


class _LimitExceeded(Exception):
    def __init__(self, line: int, col: int, message: str, hint: str) -> None:
        super().__init__(message)
        self.line, self.col, self.message, self.hint = line, col, message, hint


try:  # libyaml's event parser is about 7x faster than PyYAML's; composing stays in Python (below)
    from yaml.cyaml import CParser as _EventSource
except ImportError:  # pragma: no cover - PyYAML built without libyaml
    _EventSource = yaml.SafeLoader  # type: ignore[assignment, misc]


class _BoundedLoader(_EventSource, Composer, Resolver):  # type: ignore[misc, valid-type]
    """Events from libyaml (when present), composed in Python with a depth bound.

    The composer is Python's so the depth is checked before each nested node is composed, long
    before Python's recursion limit; aliases stay shared nodes here, so a bomb costs nothing yet.
    """

    def __init__(self, stream: str, limits: YamlLimits) -> None:
        _EventSource.__init__(self, stream)
        Composer.__init__(self)
        Resolver.__init__(self)
        self._limits = limits
        self._depth = 0

    get_single_node = Composer.get_single_node
    compose_document = Composer.compose_document
    check_node = Composer.check_node
    get_node = Composer.get_node

    def compose_node(self, parent: Node | None, index: Any) -> Node | None:
        self._depth += 1
        try:
            if self._depth > self._limits.max_depth:
                mark = self.peek_event().start_mark
                raise _LimitExceeded(
                    mark.line + 1, mark.column + 1,
                    f"expected nesting of at most {self._limits.max_depth} levels, found deeper",
                    "flatten the document or move parts into subtrees",
                )
            return Composer.compose_node(self, parent, index)
        finally:
            self._depth -= 1

    def dispose(self) -> None:
        """Release the parser's state (libyaml has nothing to release from Python)."""
        if hasattr(_EventSource, "dispose"):
            _EventSource.dispose(self)


# -- building plain data with positions ------------------------------------------------------------


class _Builder:
    """Turns a composed node graph into plain data, recording positions and counting nodes."""

    def __init__(self, file: str, limits: YamlLimits) -> None:
        self.file = file
        self.limits = limits
        self.values: dict[KeyPath, tuple[int, int]] = {}
        self.keys: dict[KeyPath, tuple[int, int]] = {}
        self.problems: list[Problem] = []
        self._count = 0
        self._constructor = SafeConstructor()

    def build(self, node: Node, path: KeyPath) -> Any:
        self._count += 1
        if self._count > self.limits.max_nodes:
            raise self._too_many(node)
        if len(path) > self.limits.max_depth:  # aliases can nest (or recurse) past the composer's check
            raise _LimitExceededError([Problem(
                self.file, *_pos(node), "",
                f"expected nesting of at most {self.limits.max_depth} levels, found deeper (through aliases)",
                "an alias refers to a mapping or list that contains it; remove the recursion",
            )])
        self.values[path] = _pos(node)
        if node.tag not in _STANDARD_TAGS or node.tag == _MERGE_TAG:
            self.problems.append(Problem(
                self.file, *_pos(node), format_path(path), f"expected plain YAML, found the tag {node.tag!r}",
                "remove the tag; tags that build objects are not allowed",
            ))
            return None
        if isinstance(node, ScalarNode):
            return self._scalar(node)
        if isinstance(node, SequenceNode):
            return [self.build(item, (*path, i)) for i, item in enumerate(node.value)]
        return self._mapping(node, path)

    def _too_many(self, node: Node) -> _LimitExceededError:
        line, col = _pos(node)
        return _LimitExceededError([Problem(
            self.file, line, col, "",
            f"expected at most {self.limits.max_nodes} values after expanding aliases, found more",
            "this looks like an alias bomb (aliases that expand exponentially); remove the nested aliases",
        )])

    def _scalar(self, node: ScalarNode) -> Any:
        if node.tag == "tag:yaml.org,2002:timestamp":
            return node.value
        try:
            return self._constructor.construct_object(node, deep=True)
        except yaml.YAMLError as exc:
            self.problems.append(Problem(self.file, *_pos(node), "", f"invalid scalar: {exc}"))
            return None

    def _mapping(self, node: MappingNode, path: KeyPath) -> dict[str, Any]:
        result: dict[str, Any] = {}
        first_seen: dict[str, int] = {}
        merges: list[Node] = []
        for key_node, value_node in node.value:
            if key_node.tag == _MERGE_TAG:
                merges.append(value_node)
                continue
            if not isinstance(key_node, ScalarNode):
                self.problems.append(Problem(
                    self.file, *_pos(key_node), format_path(path),
                    "expected a plain key, found a mapping or list used as a key",
                    "use a plain word as the key",
                ))
                continue
            key = str(key_node.value)
            line, col = _pos(key_node)
            if key in first_seen:
                self.problems.append(Problem(
                    self.file, line, col, format_path((*path, key)),
                    f"duplicate key {key!r} (first at line {first_seen[key]})",
                    "remove one of them; YAML would silently keep only the last",
                ))
                continue
            first_seen[key] = line
            self.keys[(*path, key)] = (line, col)
            result[key] = self.build(value_node, (*path, key))
        for merge in merges:
            self._merge_into(result, merge, path)
        return result

    def _merge_into(self, result: dict[str, Any], node: Node, path: KeyPath) -> None:
        """Apply `<<: *base` (or a list of them): keys written explicitly win over merged ones."""
        sources = node.value if isinstance(node, SequenceNode) else [node]
        for source in sources:
            self._count += 1
            if self._count > self.limits.max_nodes:
                raise self._too_many(source)
            if not isinstance(source, MappingNode):
                self.problems.append(Problem(
                    self.file, *_pos(source), format_path(path),
                    "expected a mapping after `<<:`, found another value",
                    "merge keys take an alias of a mapping: `<<: *defaults`",
                ))
                continue
            nested: list[Node] = []
            for key_node, value_node in source.value:
                if key_node.tag == _MERGE_TAG:
                    nested.append(value_node)
                elif isinstance(key_node, ScalarNode) and str(key_node.value) not in result:
                    key = str(key_node.value)
                    self.keys[(*path, key)] = _pos(key_node)
                    result[key] = self.build(value_node, (*path, key))
            for inner in nested:
                self._merge_into(result, inner, path)


class _LimitExceededError(ProblemsError):
    """Internal: a node-count limit hit while building (re-raised as the caller's error class)."""


def _pos(node: Node) -> tuple[int, int]:
    return node.start_mark.line + 1, node.start_mark.column + 1
