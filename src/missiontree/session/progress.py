"""The live progress line of ``missiontree run`` on stderr.

On a terminal one line is redrawn in place (at most every :data:`TTY_INTERVAL` seconds of wall
time); elsewhere (a log file, a CI job) a plain line is written every :data:`PLAIN_INTERVAL`
seconds. Each shows the robot time, the real-time factor (robot seconds per wall second), the
root's status and the last event a leaf emitted::

    patrol  t=123.4 s  42.1x real time  root RUNNING  tick 1234  last: goal_sent (patrol)
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from typing import Any, TextIO

__all__ = ["PLAIN_INTERVAL", "TTY_INTERVAL", "ProgressLine"]

#: Wall seconds between plain lines when stderr is not a terminal.
PLAIN_INTERVAL = 10.0
#: Wall seconds between redraws on a terminal.
TTY_INTERVAL = 0.2


class ProgressLine:
    """Reports a run's progress; call :meth:`update` after every tick and :meth:`close` at the end.

    Args:
        mission: The mission's name, first on the line.
        stream: Where to write (default ``sys.stderr``).
        tty: Redraw in place; default: whether ``stream`` is a terminal.
        interval: Wall seconds between lines (default by ``tty``).
        wall: The wall clock (tests give their own).
    """

    def __init__(self, mission: str, stream: TextIO | None = None, tty: bool | None = None,
                 interval: float | None = None, wall: Callable[[], float] = time.monotonic) -> None:
        self.mission = mission
        self.stream = stream if stream is not None else sys.stderr
        if tty is None:
            isatty = getattr(self.stream, "isatty", None)
            tty = bool(isatty()) if callable(isatty) else False
        self.tty = tty
        self.interval = interval if interval is not None else (TTY_INTERVAL if tty else PLAIN_INTERVAL)
        self.wall = wall
        self._wall_start: float | None = None
        self._robot_start = 0.0
        self._last = 0.0
        self._width = 0
        self.lines = 0

    def update(self, runner: Any) -> None:
        """Write a line when the interval has passed (a Runner ``on_tick`` callback)."""
        now = self.wall()
        if self._wall_start is None:
            self._wall_start = now
            self._last = now
            self._robot_start = runner.robot.now()
            if not self.tty:
                return
        if now - self._last < self.interval:
            return
        self._last = now
        self._write(self.text(runner, now))

    def text(self, runner: Any, now: float | None = None) -> str:
        """The progress line for ``runner`` now."""
        now = self.wall() if now is None else now
        robot_t = runner.robot.now()
        elapsed_wall = now - (self._wall_start if self._wall_start is not None else now)
        elapsed = robot_t - self._robot_start
        factor = f"{elapsed / elapsed_wall:.1f}x real time" if elapsed_wall > 0 else "-x real time"
        ticks = runner.recorder.ticks if runner.recorder is not None else 0
        last = getattr(runner.log, "last_event", "") if runner.log is not None else ""
        return (f"{self.mission}  t={elapsed:.1f} s  {factor}  root {runner.root.status.name}  "
                f"tick {ticks}" + (f"  last: {last}" if last else ""))

    def _write(self, line: str) -> None:
        if self.tty:
            pad = max(0, self._width - len(line))
            self.stream.write("\r" + line + " " * pad)
            self._width = len(line)
        else:
            self.stream.write(line + "\n")
        self.stream.flush()
        self.lines += 1

    def close(self) -> None:
        """End the redrawn line (a terminal gets its newline back)."""
        if self.tty and self._width:
            self.stream.write("\r" + " " * self._width + "\r")
            self.stream.flush()
            self._width = 0
