"""The batch's progress bar on stderr: done/total, a bar, rate, ETA and the outcomes so far.

Redrawn in place on a terminal; elsewhere (CI logs, a pipe) one plain line every 10 s and at the end.
"""

from __future__ import annotations

import sys
import time
from typing import TextIO

from missiontree.evaluation.batch import RunRecord

__all__ = ["BatchProgress"]

PLAIN_EVERY = 10.0
BAR_WIDTH = 24


class BatchProgress:
    """Counts records as they arrive and draws the bar (call it with each :class:`RunRecord`)."""

    def __init__(self, total: int, stream: TextIO | None = None, label: str = "batch") -> None:
        self.total = total
        self.stream = stream if stream is not None else sys.stderr
        self.label = label
        self.done = self.passed = self.failed = self.infra = self.skipped = 0
        self._start = time.monotonic()
        self._last_plain = 0.0
        self._tty = bool(getattr(self.stream, "isatty", lambda: False)())

    def __call__(self, record: RunRecord, skipped: bool = False) -> None:
        """Count one record (``skipped``: complete already, not run now) and redraw."""
        self.done += 1
        self.skipped += skipped
        if record.infra:
            self.infra += 1
        elif record.passed:
            self.passed += 1
        else:
            self.failed += 1
        self.draw()

    def line(self) -> str:
        """The progress line."""
        elapsed = time.monotonic() - self._start
        ran = self.done - self.skipped
        rate = ran / elapsed if elapsed > 0 else 0.0
        left = self.total - self.done
        eta = _duration(left / rate) if rate > 0 else "?"
        filled = int(BAR_WIDTH * self.done / self.total) if self.total else BAR_WIDTH
        bar = "#" * filled + "." * (BAR_WIDTH - filled)
        infra = f" infra {self.infra}" if self.infra else ""
        return (f"{self.label} {self.done}/{self.total} [{bar}] {rate:.2f} runs/s ETA {eta} "
                f"ok {self.passed} failed {self.failed}{infra}")

    def draw(self, final: bool = False) -> None:
        """Redraw (terminal) or print a plain line when due."""
        now = time.monotonic()
        if self._tty:
            self.stream.write("\r" + self.line() + ("\n" if final else "\x1b[K"))
        elif final or now - self._last_plain >= PLAIN_EVERY or self.done == self.total:
            self._last_plain = now
            self.stream.write(self.line() + "\n")
        self.stream.flush()

    def close(self) -> None:
        """End the bar (a newline on a terminal)."""
        if self._tty:
            self.stream.write("\n")
            self.stream.flush()


def _duration(seconds: float) -> str:
    seconds = int(round(seconds))
    if seconds >= 3600:
        return f"{seconds // 3600}h{seconds % 3600 // 60:02d}m"
    if seconds >= 60:
        return f"{seconds // 60}m{seconds % 60:02d}s"
    return f"{seconds}s"
