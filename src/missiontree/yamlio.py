"""A safe, bounded YAML loader that remembers where every key and value came from.

Mission files, world files and configs are read with :func:`load_yaml` (or :func:`parse_yaml` for
text already in memory). The result is a :class:`Located`: the plain data (dicts, lists, str, int,
float, bool, None) plus the line and column of every mapping key and every value, so a later check
can say ``file:line:col`` for any key path::

    doc = load_yaml("trees/patrol.yaml", error=MissionFileError)
    doc.data["root"]                                        # plain data
    doc.position(("root", "Sequence", "children", 2))       # (line, col), 1-based
    raise MissionFileError([doc.problem_at(("run", "tick_hz"), "expected a number, found 'fast'")])

What it refuses, each as a :class:`~missiontree.errors.Problem` with line and column, raised
together through the ``error`` class (a :class:`~missiontree.errors.ProblemsError` subclass):

- empty files, binary files (NUL bytes, not UTF-8), files larger than ``limits.max_bytes``;
- tabs in indentation (every such line is reported), YAML syntax errors, several documents;
- duplicate keys in one mapping, keys that are not scalars;
- tags that would build objects (anything but the standard ``!!str``/``!!int``/... tags);
- nesting deeper than ``limits.max_depth`` (checked while composing, before Python recursion);
- more than ``limits.max_nodes`` values after alias expansion, so a "billion laughs" alias bomb
  stops after ``max_nodes`` steps in bounded memory.

Mapping keys are always strings (``on:`` stays ``"on"``); scalar values follow YAML 1.1 as PyYAML's
safe loader reads them, except timestamps, which stay strings. Merge keys (``<<: *base``) work.
"""

from __future__ import annotations

import os
import re
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml
from yaml.composer import Composer
from yaml.constructor import SafeConstructor
from yaml.nodes import MappingNode, Node, ScalarNode, SequenceNode
from yaml.resolver import Resolver

from missiontree.errors import Problem, ProblemsError

#: A key path into the data: mapping keys (str) and sequence indices (int).
KeyPath = tuple[str | int, ...]

_STANDARD_TAGS = {
    "tag:yaml.org,2002:str", "tag:yaml.org,2002:int", "tag:yaml.org,2002:float",
    "tag:yaml.org,2002:bool", "tag:yaml.org,2002:null", "tag:yaml.org,2002:timestamp",
    "tag:yaml.org,2002:seq", "tag:yaml.org,2002:map", "tag:yaml.org,2002:merge",
}
_MERGE_TAG = "tag:yaml.org,2002:merge"
_MAX_TAB_REPORTS = 20
_CONTROL = re.compile("[\x01-\x08\x0b\x0c\x0e-\x1f\x7f]")


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


# -- pydantic errors as located problems -----------------------------------------------------------


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
