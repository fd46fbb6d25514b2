"""Tests of `missiontree validate`."""

from __future__ import annotations

from pathlib import Path

import pytest

from missiontree.cli.main import main

REPO = Path(__file__).resolve().parents[2]


def test_valid_missions_exit_zero(capsys: pytest.CaptureFixture[str]) -> None:
    """Valid files print one ok line each and exit 0."""
    names = ("timer_and_blackboard.yaml", "subtree_include.yaml")
    files = [str(REPO / "trees/examples" / name) for name in names]
    assert main(["validate", "--no-plugins", *files]) == 0
    out = capsys.readouterr().out
    assert out.count("ok: ") == 2


def test_mixed_files_report_all_problems_and_exit_two(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A valid and two broken files: every problem of both broken files is listed, exit 2."""
    (tmp_path / "a.yaml").write_text("root:\n  Wait: {}\n")
    (tmp_path / "b.yaml").write_text("root: Nothing\n")
    good = REPO / "trees/examples/timer_and_blackboard.yaml"
    code = main(["validate", "--no-plugins", str(good), str(tmp_path / "a.yaml"), str(tmp_path / "b.yaml")])
    captured = capsys.readouterr()
    assert code == 2
    assert "a.yaml:2:3: root/Wait: expected parameter 'seconds'" in captured.err
    assert "b.yaml:1:7: root/Nothing: expected a known node type" in captured.err
    assert captured.err.strip().endswith("2 problems in 2 files")
    assert "ok: " in captured.out


def test_quiet_prints_nothing_for_valid_files(capsys: pytest.CaptureFixture[str]) -> None:
    """--quiet suppresses the ok lines."""
    assert main(["validate", "-q", "--no-plugins", str(REPO / "trees/examples/subtree_include.yaml")]) == 0
    assert capsys.readouterr().out == ""
