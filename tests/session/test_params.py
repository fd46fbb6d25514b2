"""``run --set`` values are read by the same YAML reader as every mission file, while the mission loads."""

from __future__ import annotations

from pathlib import Path

import pytest

from missiontree.engine.loader import load_mission
from missiontree.errors import MissionFileError
from missiontree.plugins.manager import load_plugins
from missiontree.session.params import parse_assignment

MISSION = """\
version: 1
params: {laps: 1, anything: null}
root:
  SetBlackboard: {key: x, value: "${anything}"}
"""


def _load(tmp_path: Path, given: dict[str, str]) -> object:
    path = tmp_path / "m.yaml"
    path.write_text(MISSION, encoding="utf-8")
    return load_mission(path, load_plugins(autoload=False).nodes, params=given)


def test_a_set_value_is_read_as_plain_yaml_with_timestamps_kept_as_text(tmp_path: Path) -> None:
    """A date-like value stays the text typed, as in a mission file (not a datetime object)."""
    spec = _load(tmp_path, {"anything": "2024-01-01", "laps": "3"})
    assert spec.root.raw["value"] == "2024-01-01"  # type: ignore[attr-defined]


def test_a_set_value_that_is_not_yaml_says_why_at_the_param(tmp_path: Path) -> None:
    """An unreadable value is a problem at params.anything naming the reader's reason."""
    with pytest.raises(MissionFileError, match=r"m.yaml:2:\d+: params.anything: --set anything: cannot read "
                       r"'\[1, 2' .*quote text values"):
        _load(tmp_path, {"anything": "[1, 2"})


def test_an_assignment_splits_at_the_first_equals() -> None:
    """``key=a=b`` is the key and the value ``a=b``."""
    assert parse_assignment("key=a=b") == ("key", "a=b")
