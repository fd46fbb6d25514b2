"""The run directory's files: the log stream, the atomic summary, the recovery of a deleted directory."""

from __future__ import annotations

import io
import json
import shutil
from pathlib import Path

from missiontree.engine.recorder import SUMMARY_FILE, TICKS_FILE, RunRecorder


def test_a_callers_stream_is_flushed_and_left_open(tmp_path: Path) -> None:
    """A stream given in place of ticks.jsonl belongs to the caller: finish flushes it, never closes it."""
    stream = io.StringIO()
    files = RunRecorder(tmp_path, stream)
    files.open({"complete": False})
    files.stream.write("line\n")
    files.finish({"complete": True}, log_failed=False)
    assert not stream.closed and stream.getvalue() == "line\n"
    assert not (tmp_path / TICKS_FILE).exists()
    assert json.loads((tmp_path / SUMMARY_FILE).read_text())["complete"] is True


def test_a_deleted_directory_gets_its_log_back(tmp_path: Path) -> None:
    """The directory removed under the open log: it is made again holding every line written."""
    out = tmp_path / "run"
    files = RunRecorder(out)
    files.open({"complete": False})
    files.stream.write("first\n")
    shutil.rmtree(out)
    assert files.directory_deleted()
    redirected: list[object] = []
    files.recover_log(redirected.append)
    files.stream.write("second\n")
    files.finish({"complete": True}, log_failed=False)
    assert (out / TICKS_FILE).read_text() == "first\nsecond\n"
    assert redirected == [files.stream] and files.write_failure is None


def test_a_summary_is_read_back_bounded_and_checked(tmp_path: Path) -> None:
    """read_summary takes a run directory or its file; a non-object, non-JSON or missing one is refused."""
    import pytest

    from missiontree.engine.recorder import read_summary
    from missiontree.errors import ConfigError

    (tmp_path / "summary.json").write_text('{"mission": "m", "complete": true}', encoding="utf-8")
    expected = {"mission": "m", "complete": True}
    assert read_summary(tmp_path) == read_summary(tmp_path / "summary.json") == expected
    (tmp_path / "list.json").write_text("[1, 2]", encoding="utf-8")
    (tmp_path / "text.json").write_text("not json", encoding="utf-8")
    for name, message in (("list.json", "expected a JSON object"), ("text.json", "is not JSON"),
                          ("missing.json", "cannot read")):
        with pytest.raises(ConfigError, match=message):
            read_summary(tmp_path / name)
