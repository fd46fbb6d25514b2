"""Tests of the safe, bounded, position-keeping YAML loader."""

from __future__ import annotations

import time
from pathlib import Path

import pytest

from missiontree.errors import ProblemsError, WorldFileError
from missiontree.yamlio import YamlLimits, format_path, load_yaml, parse_yaml


def problems_of(source: str | bytes, **kwargs: object) -> list[str]:
    with pytest.raises(ProblemsError) as info:
        parse_yaml(source, "f.yaml", **kwargs)  # type: ignore[arg-type]
    return [str(p) for p in info.value.problems]


def test_positions_of_keys_and_values_are_one_based() -> None:
    """Every key and value remembers its 1-based line and column."""
    doc = parse_yaml("root:\n  Wait:\n    seconds: 2\n", "m.yaml")
    assert doc.data == {"root": {"Wait": {"seconds": 2}}}
    assert doc.position(("root", "Wait", "seconds")) == (3, 14)
    assert doc.position(("root", "Wait", "seconds"), key=True) == (3, 5)


def test_missing_path_falls_back_to_nearest_ancestor() -> None:
    """A path that is not in the file is located at its nearest existing parent."""
    doc = parse_yaml("a:\n  b: 1\n", "m.yaml")
    assert doc.position(("a", "missing", "deeper")) == doc.position(("a",))


def test_problem_at_formats_file_line_col_and_path() -> None:
    """problem_at builds a Problem that prints file:line:col: path: message (hint: ...)."""
    doc = parse_yaml("a:\n  - x: 1\n", "m.yaml")
    text = str(doc.problem_at(("a", 0, "x"), "expected a string, found 1", "quote it"))
    assert text == "m.yaml:2:8: a[0].x: expected a string, found 1 (hint: quote it)"


def test_child_view_is_relative() -> None:
    """A child view reads positions relative to its root but reports the full path."""
    doc = parse_yaml("a:\n  b:\n    c: 3\n", "m.yaml")
    sub = doc.child(("a", "b"))
    assert sub.data == {"c": 3}
    assert sub.position(("c",)) == (3, 8)
    assert sub.problem_at(("c",), "bad").path == "a.b.c"


def test_keys_stay_strings() -> None:
    """YAML 1.1 boolean-looking keys (on, yes) stay strings; values follow YAML."""
    assert parse_yaml("on: yes\n", "f").data == {"on": True}


def test_duplicate_keys_are_all_reported() -> None:
    """Each duplicate key is reported with the line of its first occurrence."""
    lines = problems_of("a: 1\na: 2\nb:\n  c: 1\n  c: 2\n")
    assert lines[0].startswith("f.yaml:2:1: a: duplicate key 'a' (first at line 1)")
    assert lines[1].startswith("f.yaml:5:3: b.c: duplicate key 'c' (first at line 4)")


def test_tabs_in_indentation_are_reported_per_line() -> None:
    """Every line indented with a tab is reported."""
    lines = problems_of("a:\n\tb: 1\n\tc: 2\n")
    assert [ln.split(": ")[0] for ln in lines] == ["f.yaml:2:1", "f.yaml:3:1"]
    assert "found a tab" in lines[0]


def test_syntax_error_names_line() -> None:
    """A YAML syntax error is reported with its line and column."""
    (line,) = problems_of("a: [1, 2\nb: 3\n")
    assert line.startswith("f.yaml:2:") and "YAML syntax error" in line


@pytest.mark.parametrize("source", ["", "   \n", "# nothing\n"])
def test_empty_files_are_refused(source: str) -> None:
    """Empty and comment-only files are refused."""
    assert "found an empty file" in problems_of(source)[0]


def test_binary_file_is_refused() -> None:
    """A NUL byte marks a binary file."""
    assert "binary file" in problems_of(b"PK\x03\x04\x00\x00")[0]


def test_invalid_utf8_is_refused_with_position() -> None:
    """A byte that is not UTF-8 is named with its position."""
    (line,) = problems_of(b"a: 1\nb: \xff\n")
    assert line.startswith("f.yaml:2:4: expected UTF-8 text, found the byte 0xff")


def test_object_building_tags_are_refused() -> None:
    """Python object tags are refused, never constructed."""
    (line,) = problems_of("a: !!python/object/apply:os.system [echo hi]\n")
    assert "found the tag" in line and line.startswith("f.yaml:1:4: a:")


def test_several_documents_are_refused() -> None:
    """A file holds one document."""
    assert "found several" in problems_of("a: 1\n---\nb: 2\n")[0]


def test_alias_bomb_is_refused_fast() -> None:
    """Aliases that expand exponentially stop at the node limit within a second."""
    names = "abcdefghij"
    bomb = "a: &a [" + ",".join(["lol"] * 10) + "]\n" + "".join(
        f"{names[i + 1]}: &{names[i + 1]} [" + ",".join([f"*{names[i]}"] * 10) + "]\n" for i in range(9)
    )
    start = time.process_time()  # CPU time: what the bomb would cost, not how loaded the machine is
    lines = problems_of(bomb)
    assert time.process_time() - start < 2.0
    assert "alias bomb" in lines[0]


def test_recursive_alias_is_refused() -> None:
    """An anchor that contains its own alias is refused, not followed forever."""
    assert "through aliases" in problems_of("a: &a [*a]\n")[0]


def test_deep_nesting_is_refused_before_recursion_limit() -> None:
    """Nesting beyond the limit is refused while composing."""
    (line,) = problems_of("[" * 5000 + "]" * 5000)
    assert "nesting of at most 64 levels" in line


def test_size_limit_applies_before_parsing(tmp_path: Path) -> None:
    """A file larger than the limit is refused without being parsed."""
    path = tmp_path / "big.yaml"
    path.write_text("a: " + "x" * 2000 + "\n")
    with pytest.raises(WorldFileError) as info:
        load_yaml(path, limits=YamlLimits(max_bytes=1000), error=WorldFileError)
    assert "at most 1000 bytes" in str(info.value)


def test_missing_file_names_it(tmp_path: Path) -> None:
    """A missing file is a problem naming the file, not an OSError."""
    with pytest.raises(ProblemsError) as info:
        load_yaml(tmp_path / "nope.yaml")
    assert "nope.yaml" in str(info.value) and "file not found" in str(info.value)


def test_merge_keys_apply_with_explicit_keys_winning() -> None:
    """`<<: *base` merges a mapping; keys written beside it win."""
    doc = parse_yaml("base: &b {x: 1, y: 2}\nd:\n  <<: *b\n  y: 3\n", "f")
    assert doc.data["d"] == {"x": 1, "y": 3}
    assert doc.position(("d", "y")) == (4, 6)


def test_timestamps_stay_strings() -> None:
    """Dates are kept as written (plain, JSON-safe data)."""
    assert parse_yaml("d: 2024-01-01\n", "f").data == {"d": "2024-01-01"}


def test_format_path() -> None:
    """Key paths render as dotted names with [index]."""
    assert format_path(("root", "children", 2, "Wait")) == "root.children[2].Wait"


def test_control_characters_are_refused_with_position() -> None:
    """A control character (other than tab and line breaks) is named with its line and column."""
    (line,) = problems_of("a: 1\nb: x\x07\n")
    assert line.startswith("f.yaml:2:5: expected printable text, found the control character '\\x07'")


# -- the one translation of pydantic errors ----------------------------------------------------------


def test_a_misspelt_key_is_located_with_the_nearest_known_one() -> None:
    """validation_problems points at an unknown key and suggests the closest field name."""
    from pydantic import BaseModel, ConfigDict, ValidationError

    from missiontree.yamlio import validation_problems

    class Section(BaseModel):
        model_config = ConfigDict(extra="forbid")
        backend: str = "sim"
        seed: int = 0

    doc = parse_yaml("run:\n  backnd: sim\n  seed: x\n", "m.yaml")
    with pytest.raises(ValidationError) as caught:
        Section.model_validate(doc.data["run"])
    problems = {p.path: p for p in validation_problems(caught.value, doc, Section, prefix=("run",))}
    assert (problems["run.backnd"].line, problems["run.backnd"].hint) == (2, "did you mean 'backend'?")
    assert problems["run.backnd"].message.startswith("unknown key 'backnd'; expected one of: backend, seed")
    assert problems["run.seed"].message.startswith("expected a valid integer") and "found 'x'" in \
        problems["run.seed"].message


def test_a_union_member_tag_is_not_shown_as_a_key() -> None:
    """written_loc keeps the written keys and a missing key, and drops pydantic's union tags."""
    from missiontree.yamlio import written_loc

    data = {"a": {"b": 1}}
    assert written_loc(data, ("a", "b", "int"), "int_parsing") == ("a", "b")
    assert written_loc(data, ("a", "c"), "missing") == ("a", "c")
