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


def test_an_error_raised_while_a_ctrl_c_is_recorded_is_the_interrupt(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """A KeyboardInterrupt in a class body's __set_name__ surfaces as a RuntimeError: still exit 130."""
    import argparse

    ctrl_c = {"pressed": False}

    def wrapped(args: argparse.Namespace) -> int:
        startup._pending = ctrl_c["pressed"]  # the Ctrl-C comes while the command imports
        raise RuntimeError("Error calling __set_name__ on 'Field' instance 'blackboard' in '_File'")

    monkeypatch.setattr(startup, "_pending", False)
    monkeypatch.setattr("missiontree.cli.main.build_parser", lambda: _parser(wrapped))
    with pytest.raises(RuntimeError):  # no Ctrl-C recorded: the error is the error
        cli_main(["run"])
    ctrl_c["pressed"] = True
    assert cli_main(["run"]) == 130
    assert capsys.readouterr().err.strip() == "missiontree run: interrupted"


def _parser(func):  # noqa: ANN001, ANN202
    import argparse

    parser = argparse.ArgumentParser(prog="missiontree")
    sub = parser.add_subparsers(dest="command", required=True)
    sub.add_parser("run").set_defaults(func=func)
    return parser


def test_a_swallowed_ctrl_c_prints_no_exception_ignored_traceback(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """An interrupt Python swallows in a weakref callback is recorded, not printed as a traceback."""
    import sys
    import weakref

    monkeypatch.setattr(startup, "_pending", False)
    monkeypatch.setattr(sys, "unraisablehook", sys.__unraisablehook__)
    previous = signal.getsignal(signal.SIGINT)

    class Target:
        pass

    def callback(_ref: object) -> None:  # as the import system's module-lock callback meets it
        signal.raise_signal(signal.SIGINT)

    try:
        startup.guard()
        target = Target()
        ref = weakref.ref(target, callback)
        del target  # the callback runs, raises KeyboardInterrupt, and Python swallows it
        assert ref() is None
        assert startup.interrupted()
        assert "Traceback" not in capsys.readouterr().err
        other = Target()
        other_ref = weakref.ref(other, _raise_value_error)
        del other  # anything else Python swallows is still printed
        assert other_ref() is None
        assert "ValueError" in capsys.readouterr().err
    finally:
        signal.signal(signal.SIGINT, previous)


def _raise_value_error(_ref: object) -> None:
    raise ValueError("other")
