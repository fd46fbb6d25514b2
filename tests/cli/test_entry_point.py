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
