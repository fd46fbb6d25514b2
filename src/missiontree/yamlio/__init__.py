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

The parts: :mod:`~missiontree.yamlio.located` (the located data and the limits),
:mod:`~missiontree.yamlio.reader` (the bounded reader) and :mod:`~missiontree.yamlio.problems`
(pydantic's errors as located problems).
"""

from missiontree.yamlio.located import DEFAULT_LIMITS, KeyPath, Located, YamlLimits, format_path
from missiontree.yamlio.problems import (
    error_lines,
    error_message,
    expected_text,
    short_repr,
    validation_problems,
    written_loc,
)
from missiontree.yamlio.reader import load_yaml, parse_yaml

__all__ = ["DEFAULT_LIMITS", "KeyPath", "Located", "YamlLimits", "error_lines", "error_message",
           "expected_text", "format_path", "load_yaml", "parse_yaml", "short_repr", "validation_problems",
           "written_loc"]
