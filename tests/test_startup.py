"""Ctrl-C during start-up is recorded, so an interrupt an import swallowed still ends the command (130)."""

from __future__ import annotations

import signal
from pathlib import Path

import pytest

import missiontree.startup as startup
from missiontree.cli.main import main as cli_main

REPO = Path(__file__).resolve().parents[1]


def test_a_ctrl_c_whose_keyboard_interrupt_was_swallowed_is_still_seen(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setattr(startup, "_pending", False)
    previous = signal.getsignal(signal.SIGINT)
    try:
        startup.guard()
        assert signal.getsignal(signal.SIGINT) is startup._on_sigint
        assert not startup.interrupted()
        try:  # what a weakref callback of the import system does with it
            signal.raise_signal(signal.SIGINT)
        except KeyboardInterrupt:
            pass
        assert startup.interrupted()
    finally:
        signal.signal(signal.SIGINT, previous)


def test_the_command_line_exits_130_after_a_swallowed_ctrl_c(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    monkeypatch.setattr(startup, "_pending", True)
    code = cli_main(["run", str(REPO / "trees" / "patrol.yaml"), "--quiet", "--out", str(tmp_path / "run"),
                     "--max-duration", "5"])
    assert code == 130
    assert capsys.readouterr().err.strip() == "missiontree: interrupted"
    assert not (tmp_path / "run").exists()  # nothing ran
    monkeypatch.setattr(startup, "_pending", False)
    assert cli_main(["validate", str(REPO / "trees" / "patrol.yaml")]) == 0  # not pending: runs
