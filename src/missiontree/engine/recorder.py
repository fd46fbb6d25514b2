"""The run directory's files: ``ticks.jsonl``, ``summary.json`` and the backend's pictures.

The runner ticks; this recorder owns what a run leaves on disk::

    files = RunRecorder(Path("runs/patrol"))    # or RunRecorder(None, stream=sys.stdout)
    files.open(provisional_summary)             # ConfigError when the directory cannot be written
    TickLog(files.stream, ...)                  # the tick log writes its lines to files.stream
    ...
    files.finish(summary)                       # the summary, whole or not at all; the log closed

- ``summary.json`` is written whole or not at all (a temporary file renamed over it): at the start
  a provisional one marked ``"complete": false``, at the end the real one.
- ``ticks.jsonl`` is opened ``w+``: when the directory is deleted under the run, the open file
  still holds every line, and :meth:`RunRecorder.recover_log` makes the directory again and copies
  them back (``os.pread`` on the unlinked file).
- A failure to write (a full disk) is kept in :attr:`RunRecorder.write_failure` rather than raised
  at the end, so the runner can halt the tree and stop the robot first and say afterwards what was
  lost.

A stream given in place of the directory's log (``stream=``) is the caller's: it is flushed, never
closed. Tests inject faults that way (a stream whose writes fail as a full disk does).
"""

from __future__ import annotations

import contextlib
import io
import json
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any, TextIO

from missiontree.errors import ConfigError
from missiontree.redact import scrub_data
from missiontree.robot.interface import Drawable

#: The tick log's file name in a run directory.
TICKS_FILE = "ticks.jsonl"
#: The summary's file name in a run directory.
SUMMARY_FILE = "summary.json"

#: Largest summary.json read back (a run's summary is kilobytes).
SUMMARY_READ_LIMIT = 16 * 2**20

__all__ = ["SUMMARY_FILE", "SUMMARY_READ_LIMIT", "TICKS_FILE", "RunRecorder", "read_summary"]


def read_summary(run_path: Path) -> dict[str, Any]:
    """A run's ``summary.json``, from its run directory or the file itself, read bounded.

    Raises:
        ConfigError: No readable file, one over :data:`SUMMARY_READ_LIMIT`, or not a JSON object
            (the message names the file and what to give instead).
    """
    path = run_path / SUMMARY_FILE if run_path.is_dir() else run_path
    try:
        if path.stat().st_size > SUMMARY_READ_LIMIT:
            raise ConfigError(f"{path} is larger than {SUMMARY_READ_LIMIT // 2**20} MiB; not a run's summary")
        summary = json.loads(path.read_text(encoding="utf-8"))
    except OSError as error:
        raise ConfigError(f"cannot read {path}: {error.strerror or error}; give a run directory written "
                          f"by `missiontree run` (see its --out) or its summary.json") from error
    except ValueError as error:
        raise ConfigError(f"{path} is not JSON ({error}); give a run's summary.json") from error
    if not isinstance(summary, dict):
        raise ConfigError(f"{path}: expected a JSON object (a run's summary), found {type(summary).__name__}")
    return summary


class RunRecorder:
    """Writes one run's directory: the tick log's file, the summary and the pictures.

    Args:
        run_dir: The run directory; None writes nothing to disk (the log goes to ``stream``, or to
            memory).
        stream: Write the tick log here instead of ``run_dir/ticks.jsonl`` (the caller's stream:
            flushed at the end, not closed).
    """

    def __init__(self, run_dir: Path | None, stream: TextIO | None = None) -> None:
        self.run_dir = Path(run_dir) if run_dir is not None else None
        #: True when the log file is this recorder's own (``run_dir/ticks.jsonl``).
        self.owns_stream = stream is None and self.run_dir is not None
        #: Where the tick log's lines go (replaced by :meth:`open` and :meth:`recover_log`).
        self.stream: TextIO = stream if stream is not None else io.StringIO()
        #: The run directory was deleted during the run (the log is recovered from the open file).
        self.dir_lost = False
        #: Writing the summary or the log failed: (what, error).
        self.write_failure: tuple[str, OSError] | None = None

    def open(self, provisional: dict[str, Any]) -> None:
        """Make the directory, open the log file and write the provisional summary.

        Raises:
            ConfigError: The run directory cannot be made or written.
        """
        if self.run_dir is None:
            return
        try:
            self.run_dir.mkdir(parents=True, exist_ok=True)
            if self.owns_stream:  # w+: a deleted directory's log can be read back (recover_log)
                self.stream = (self.run_dir / TICKS_FILE).open("w+", encoding="utf-8", newline="\n")
            self.write_summary(provisional)
        except OSError as error:
            raise ConfigError(f"cannot write the run directory {self.run_dir}: "
                              f"{error.strerror or error}") from error

    def directory_deleted(self) -> bool:
        """True (and remembered) when the run directory was deleted under the open log file."""
        if self.owns_stream and os.fstat(self.stream.fileno()).st_nlink == 0:
            self.dir_lost = True
        return self.dir_lost

    def recover_log(self, redirect: Callable[[TextIO], None]) -> None:
        """Make the deleted directory again, copy the unlinked log into it and go on writing there.

        Args:
            redirect: Called with the new stream (the tick log's ``redirect``), so later lines go on
                in the recovered file.
        """
        assert self.run_dir is not None
        old = self.stream
        try:
            old.flush()
            self.run_dir.mkdir(parents=True, exist_ok=True)
            fd, offset = old.fileno(), 0
            with (self.run_dir / TICKS_FILE).open("wb") as copy:
                while chunk := os.pread(fd, 1 << 20, offset):
                    copy.write(chunk)
                    offset += len(chunk)
            self.stream = (self.run_dir / TICKS_FILE).open("a", encoding="utf-8", newline="\n")
        except OSError as error:
            self.write_failure = ("tick log (its directory was deleted)", error)
            return
        finally:
            with contextlib.suppress(OSError):
                old.close()
        redirect(self.stream)

    def write_summary(self, summary: dict[str, Any]) -> None:
        """Write summary.json whole or not at all (a temporary file renamed over it)."""
        assert self.run_dir is not None
        target = self.run_dir / SUMMARY_FILE
        temporary = self.run_dir / f".{SUMMARY_FILE}.tmp"
        try:
            text = json.dumps(scrub_data(summary), indent=2, sort_keys=True) + "\n"
            temporary.write_text(text, encoding="utf-8")
            os.replace(temporary, target)
        except OSError:
            with contextlib.suppress(OSError):
                temporary.unlink()
            raise

    def draw(self, robot: Any, markers: Any, on_error: Callable[[Exception], None]) -> list[str]:
        """The backend's pictures of the run, drawn into the directory: their file names.

        Nothing is drawn without a directory, for a backend that draws nothing, or after a write
        failed. A drawing that raises is handed to ``on_error`` (a failed picture must not lose the
        summary).
        """
        if self.run_dir is None or not isinstance(robot, Drawable) or self.write_failure is not None:
            return []
        try:
            return [p.name for p in robot.draw(self.run_dir, markers)]
        except Exception as error:  # noqa: BLE001 - a failed picture must not lose the summary
            on_error(error)
            return []

    def finish(self, summary: dict[str, Any], log_failed: bool) -> None:
        """Write the final summary and close (or flush) the log; failures are kept, not raised.

        Args:
            summary: The run's summary, as returned to the caller.
            log_failed: The tick log already failed to write (its error is the one to report).
        """
        if self.run_dir is not None and self.write_failure is None:
            try:
                self.run_dir.mkdir(parents=True, exist_ok=True)
                self.write_summary(summary)
            except OSError as error:
                self.write_failure = ("summary", error)
        try:
            if self.owns_stream:
                self.stream.close()
            else:
                self.stream.flush()
        except OSError as error:
            if self.write_failure is None and not log_failed:
                self.write_failure = ("tick log", error)
