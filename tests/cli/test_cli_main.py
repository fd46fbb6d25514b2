"""Tests of the command's frame: subcommand list, exit codes for bad input and interrupts."""

from __future__ import annotations

import argparse
import io
import subprocess
import sys

import pytest

from missiontree.cli import log as log_command
from missiontree.cli import main as main_module
from missiontree.cli.main import SUBCOMMANDS, build_parser, main
from missiontree.errors import MissionFileError, Problem
from missiontree.testing import clean_state


@pytest.fixture(autouse=True)
def _clean() -> None:
    clean_state()


def test_every_listed_subcommand_registers_a_runnable_parser() -> None:
    """Each module in SUBCOMMANDS adds a subcommand whose parser sets func."""
    parser = build_parser()
    actions = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    assert {"run", "nodes", "plugins", "log"} <= set(actions.choices)
    assert len(SUBCOMMANDS) == len(set(SUBCOMMANDS))


def test_problems_are_printed_one_a_line_with_exit_two(monkeypatch: pytest.MonkeyPatch,
                                                         capsys: pytest.CaptureFixture[str]) -> None:
    """A ProblemsError anywhere prints every problem and a count on stderr and exits 2."""

    def broken(args: argparse.Namespace) -> int:
        raise MissionFileError([Problem("m.yaml", 3, 5, "root", "expected a mapping, found a list"),
                                Problem("m.yaml", 9, 1, "", "unknown key 'roto'", "did you mean 'root'?")])

    monkeypatch.setattr(log_command, "run", broken)
    assert main(["log", "summarize", "anything"]) == 2
    err = capsys.readouterr().err
    assert "m.yaml:3:5: root: expected a mapping, found a list" in err
    assert "m.yaml:9:1: unknown key 'roto' (hint: did you mean 'root'?)" in err
    assert "2 problems found" in err


def test_keyboard_interrupt_exits_130(monkeypatch: pytest.MonkeyPatch) -> None:
    """Ctrl-C while a subcommand runs exits with 130 and no traceback."""

    def interrupted(args: argparse.Namespace) -> int:
        raise KeyboardInterrupt

    monkeypatch.setattr(log_command, "run", interrupted)
    assert main(["log", "summarize", "x"]) == main_module.EXIT_INTERRUPTED == 130


def test_output_piped_into_a_closed_reader_exits_0(monkeypatch: pytest.MonkeyPatch) -> None:
    """Output piped into `head` (the reader gone: BrokenPipeError) ends quietly with exit 0."""

    def piped(args: argparse.Namespace) -> int:
        raise BrokenPipeError

    monkeypatch.setattr(log_command, "run", piped)
    monkeypatch.setattr(sys, "stderr", io.StringIO())  # the handler closes stderr
    assert main(["log", "summarize", "x"]) == 0


def test_console_script_runs_as_a_program() -> None:
    """`python -m missiontree.cli.main --version` prints the version and exits 0."""
    done = subprocess.run([sys.executable, "-m", "missiontree.cli.main", "--version"],
                          capture_output=True, text=True, timeout=60, check=False)
    assert done.returncode == 0
    assert done.stdout.startswith("missiontree ")


def test_unknown_subcommand_is_a_usage_error() -> None:
    """An unknown subcommand exits 2 (argparse's usage error)."""
    with pytest.raises(SystemExit) as caught:
        main(["fly"])
    assert caught.value.code == 2
