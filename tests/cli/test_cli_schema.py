"""Tests of `missiontree schema`."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from missiontree.cli.main import main


def test_schema_prints_json_with_every_node_type(capsys: pytest.CaptureFixture[str]) -> None:
    """The printed schema is JSON and has an entry per registered node type."""
    assert main(["schema", "--no-plugins"]) == 0
    schema = json.loads(capsys.readouterr().out)
    assert schema["required"] == ["root"]
    names = ("Sequence", "Selector", "Parallel", "Guard", "RateLimit", "Wait", "SetBlackboard", "Include")
    for name in names:
        assert f"node.{name}" in schema["$defs"]


def test_schema_out_writes_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """--out writes the schema to a file."""
    target = tmp_path / "mission.schema.json"
    assert main(["schema", "--no-plugins", "--out", str(target)]) == 0
    assert json.loads(target.read_text())["title"] == "missiontree mission"
