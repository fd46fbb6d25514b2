"""``run --set`` values are read by the same YAML reader as every mission file."""

from __future__ import annotations

from pathlib import Path

import pytest

from missiontree.errors import ConfigError
from missiontree.session.params import parse_overrides


def _mission(tmp_path: Path) -> Path:
    path = tmp_path / "m.yaml"
    path.write_text("params: {laps: 1, anything: null}\nroot: {Wait: {duration: 1}}\n", encoding="utf-8")
    return path


def test_a_set_value_is_read_as_plain_yaml_with_timestamps_kept_as_text(tmp_path: Path) -> None:
    """A date-like value stays the text typed, as in a mission file (not a datetime object)."""
    assert parse_overrides(_mission(tmp_path), {"anything": "2024-01-01", "laps": "3"}) == {
        "anything": "2024-01-01", "laps": 3}


def test_a_set_value_that_is_not_yaml_says_why(tmp_path: Path) -> None:
    """An unreadable value is a ConfigError naming the parameter and the reader's reason."""
    with pytest.raises(ConfigError, match=r"--set anything: cannot read '\[1, 2' .*quote text values"):
        parse_overrides(_mission(tmp_path), {"anything": "[1, 2"})
