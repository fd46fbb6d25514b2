"""The ``missiontree`` entry point: a Ctrl-C during start-up exits 130 whatever error it surfaces as."""

from __future__ import annotations

import signal
import sys
from collections.abc import Iterator

import pytest

from missiontree import __main__ as entry
from missiontree import startup


@pytest.fixture
def guarded(monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    """The start-up guard may install its handlers; they are put back after the test."""
    previous = signal.getsignal(signal.SIGINT)
    monkeypatch.setattr(sys, "unraisablehook", sys.unraisablehook)
    monkeypatch.setitem(sys.modules, "missiontree.cli.main", None)  # its import fails: ImportError
    yield
    signal.signal(signal.SIGINT, previous)


@pytest.mark.usefixtures("guarded")
def test_an_import_error_after_a_recorded_ctrl_c_is_the_interrupt(monkeypatch: pytest.MonkeyPatch,
                                                                  capsys: pytest.CaptureFixture[str]) -> None:
    """An error escaping the imports while a Ctrl-C is recorded: exit 130 and one line, no traceback."""
    monkeypatch.setattr(startup, "_pending", True)
    assert entry.main() == entry.EXIT_INTERRUPTED
    assert capsys.readouterr().err == "missiontree: interrupted\n"


@pytest.mark.usefixtures("guarded")
def test_an_import_error_without_a_ctrl_c_is_raised(monkeypatch: pytest.MonkeyPatch) -> None:
    """Without a recorded Ctrl-C the error is a real one and is not hidden."""
    monkeypatch.setattr(startup, "_pending", False)
    with pytest.raises(ImportError):
        entry.main()


class _InterruptedImport:
    """A module whose ``main`` fails as a class body hit by Ctrl-C does: a RuntimeError from it."""

    def __getattr__(self, name: str) -> object:
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt as interrupt:
            raise RuntimeError("Error calling __set_name__") from interrupt


@pytest.mark.usefixtures("guarded")
def test_an_error_caused_by_a_ctrl_c_before_the_guard_is_the_interrupt(
        monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    """A Ctrl-C the guard never saw, behind an import's error: exit 130 and one line, no traceback."""
    monkeypatch.setattr(startup, "_pending", False)
    monkeypatch.setitem(sys.modules, "missiontree.cli.main", _InterruptedImport())
    assert entry.main() == entry.EXIT_INTERRUPTED
    assert capsys.readouterr().err == "missiontree: interrupted\n"
