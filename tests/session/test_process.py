"""Process settings for long runs: applied only when the application asks."""

from __future__ import annotations

import gc

import pytest

from missiontree.session import process


def test_run_span_freezes_the_heap_only_in_a_tuned_process(monkeypatch: pytest.MonkeyPatch) -> None:
    """Untuned: nothing frozen; tuned: frozen inside the span and unfrozen after it."""
    before = gc.get_freeze_count()
    monkeypatch.setattr(process, "_tuned", False)
    with process.run_span():
        assert gc.get_freeze_count() == before
    monkeypatch.setattr(process, "_tuned", True)
    with process.run_span():
        assert gc.get_freeze_count() > before
    assert gc.get_freeze_count() == before


def test_the_command_line_tunes_its_process(monkeypatch: pytest.MonkeyPatch) -> None:
    """``missiontree`` (any subcommand) applies the settings before running the command."""
    from missiontree.cli.main import main

    monkeypatch.setattr(process, "_tuned", False)
    assert main(["schema"]) == 0
    assert process.process_tuned()
