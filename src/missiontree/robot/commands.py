"""The robot's command channel: what a user tells the robot, one command at a time, with its stamp.

A backend that can hear users offers two methods beside the :class:`~missiontree.robot.interface.Robot`
protocol (see :class:`CommandChannel`): ``commands()`` returns the commands received since the last
call, oldest first, each stamped on the robot clock when it was received; ``commands_closed()`` tells
that no more will come (the simulator's stdin reached its end; a ROS 2 topic never closes). Leaves
that serve commands poll ``commands()`` every tick; it returns at once.

- Simulator: lines on stdin (:class:`LineCommands` over ``sys.stdin``), one command a line.
- ROS 2: ``std_msgs/String`` messages on ``/command`` (:mod:`missiontree.backends.ros2.commands`).
"""

from __future__ import annotations

import threading
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol, TextIO, runtime_checkable

#: Longest command kept (characters); longer text is cut, so a runaway stream cannot flood a prompt.
MAX_COMMAND_CHARS = 500
#: Longest line read from a stream (bytes); the rest of a longer line is skipped and the line refused,
#: so a stream without newlines cannot fill the memory.
MAX_LINE_BYTES = 64 * 1024


@dataclass(frozen=True)
class Command:
    """One user command.

    Attributes:
        stamp: Robot-clock time it was received.
        text: What the user said (stripped, at most :data:`MAX_COMMAND_CHARS`); empty when refused.
        source: Where it came from (``stdin``, ``/command``, ...).
        error: Why the input could not be read as a command (not UTF-8, too long); empty for a
            command. A refused input is still delivered, so it is reported, never dropped silently.
    """

    stamp: float
    text: str
    source: str = ""
    error: str = ""


@runtime_checkable
class CommandChannel(Protocol):
    """A robot that takes commands from users (an optional capability of a backend)."""

    def commands(self) -> list[Command]:
        """The commands received since the last call, oldest first (returns at once)."""
        ...

    def commands_closed(self) -> bool:
        """True when no command will come any more and none is waiting."""
        ...


def clean_command(text: str) -> str:
    """``text`` stripped of surrounding blanks and control characters, cut to :data:`MAX_COMMAND_CHARS`."""
    kept = "".join(ch if ch.isprintable() else " " for ch in text)
    return " ".join(kept.split())[:MAX_COMMAND_CHARS]


class CommandQueue:
    """Commands waiting to be collected, stamped when they arrive (thread-safe).

    Args:
        clock: The robot clock that stamps each command on arrival (None: stamped when polled).
        source: Name given to the commands.
    """

    def __init__(self, clock: Callable[[], float] | None = None, source: str = "") -> None:
        self.clock = clock
        self.source = source
        self._lock = threading.Lock()
        self._waiting: deque[tuple[float | None, str, str]] = deque()
        self._closed = False

    def push(self, text: str) -> bool:
        """Queue one command; blank text is ignored. Returns whether it was queued."""
        clean = clean_command(text)
        if not clean:
            return False
        stamp = self.clock() if self.clock is not None else None
        with self._lock:
            self._waiting.append((stamp, clean, ""))
        return True

    def refuse(self, error: str) -> None:
        """Queue an input that could not be read as a command, with why (delivered as an error)."""
        stamp = self.clock() if self.clock is not None else None
        with self._lock:
            self._waiting.append((stamp, "", error))

    def close(self) -> None:
        """No more commands will be pushed."""
        with self._lock:
            self._closed = True

    def poll(self, now: float) -> list[Command]:
        """Take every waiting command; those without a stamp get ``now``."""
        with self._lock:
            taken = list(self._waiting)
            self._waiting.clear()
        return [Command(now if stamp is None else stamp, text, self.source, error)
                for stamp, text, error in taken]

    @property
    def closed(self) -> bool:
        """Closed and nothing waiting."""
        with self._lock:
            return self._closed and not self._waiting


class LineCommands(CommandQueue):
    """Commands read line by line from a text stream (stdin) on a daemon thread, started on first poll.

    Reading starts only when a mission first asks for commands, so missions that never do leave stdin
    alone. At the end of the stream the channel closes. Lines are read as bytes and decoded one by one:
    a line that is not UTF-8 (or longer than :data:`MAX_LINE_BYTES`) is delivered as a refused
    command naming the line, and the lines after it are read as usual. A stream that fails to read
    is delivered as a refused command too before the channel closes.

    Args:
        stream: The text stream (default: ``sys.stdin`` at first poll).
        source: Name given to the commands.
    """

    def __init__(self, stream: TextIO | None = None, source: str = "stdin") -> None:
        super().__init__(clock=None, source=source)
        self._stream = stream
        self._reader: threading.Thread | None = None

    def poll(self, now: float) -> list[Command]:
        """Start reading on first use; take every line read so far, stamped ``now``."""
        self._start()
        return super().poll(now)

    @property
    def closed(self) -> bool:
        """The stream ended and every line was taken."""
        self._start()
        return super().closed

    def _start(self) -> None:
        if self._reader is not None:
            return
        import sys

        stream = self._stream if self._stream is not None else sys.stdin
        self._reader = threading.Thread(target=self._read, args=(stream,), name="commands-stdin", daemon=True)
        self._reader.start()

    def _read(self, stream: TextIO | None) -> None:
        number = 0
        try:
            if stream is None:
                return
            binary = getattr(stream, "buffer", None)
            if binary is None:  # a text stream of its own (tests): already decoded
                for number, line in enumerate(stream, start=1):  # noqa: B007 - kept for the error below
                    self.push(line)
                return
            while raw := binary.readline(MAX_LINE_BYTES):
                number += 1
                if len(raw) == MAX_LINE_BYTES and not raw.endswith(b"\n"):
                    while (rest := binary.readline(MAX_LINE_BYTES)) and not rest.endswith(b"\n"):
                        pass  # skip the rest of the long line
                    self.refuse(f"line {number} on {self.source} is longer than {MAX_LINE_BYTES:,} bytes; "
                                "not read as a command")
                    continue
                try:
                    text = raw.decode("utf-8")
                except UnicodeDecodeError as error:
                    self.refuse(f"line {number} on {self.source} is not UTF-8 text (byte "
                                f"0x{raw[error.start]:02x} at position {error.start + 1}); not read as a "
                                "command")
                    continue
                self.push(text)
        except (OSError, ValueError) as error:  # closed or unreadable stream: no more commands
            self.refuse(f"{self.source} could not be read after line {number}: "
                        f"{type(error).__name__}: {error}")
        finally:
            self.close()
