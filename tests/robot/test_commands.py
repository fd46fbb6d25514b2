"""The command channel's pieces: lines read from a stream, cleaned, stamped, and the end of the stream."""

from __future__ import annotations

import io
import time

from missiontree.robot.commands import MAX_COMMAND_CHARS, CommandQueue, LineCommands, clean_command


def _drain(channel: LineCommands, now: float, timeout: float = 2.0) -> list:
    got: list = []
    deadline = time.monotonic() + timeout
    while not channel.closed and time.monotonic() < deadline:
        got += channel.poll(now)
        time.sleep(0.005)
    return got + channel.poll(now)


def test_lines_become_commands_stamped_when_taken_and_the_stream_end_closes_it() -> None:
    """Each non-blank line is one command, stamped with the clock at poll; EOF closes the channel."""
    channel = LineCommands(io.StringIO("I'm thirsty\n\n   \nthe grey backpack\n"))
    got = _drain(channel, now=12.5)
    assert [(c.text, c.stamp, c.source) for c in got] == [("I'm thirsty", 12.5, "stdin"),
                                                           ("the grey backpack", 12.5, "stdin")]
    assert channel.closed and channel.poll(13.0) == []


def test_control_characters_and_runaway_length_are_cleaned() -> None:
    """Control characters become spaces, runs of blanks one space, and text is cut to the limit."""
    assert clean_command("go\x1b[2J  to\tthe\x00 sofa\r\n") == "go [2J to the sofa"
    assert len(clean_command("a" * 5000)) == MAX_COMMAND_CHARS


def test_a_queue_stamps_on_arrival_and_reports_closed_only_when_drained() -> None:
    """With a clock, commands keep their arrival stamp; closed waits until every command was taken."""
    t = [1.0]
    queue = CommandQueue(lambda: t[0], source="/command")
    queue.push("first")
    t[0] = 2.0
    queue.close()
    assert not queue.closed
    [command] = queue.poll(now=5.0)
    assert (command.text, command.stamp, command.source) == ("first", 1.0, "/command")
    assert queue.closed


def _binary(data: bytes) -> io.TextIOWrapper:
    return io.TextIOWrapper(io.BytesIO(data), encoding="utf-8", errors="strict")


def test_a_line_that_is_not_utf8_is_refused_and_reading_goes_on() -> None:
    """A line with an undecodable byte arrives as a refused command naming it; the next lines still come."""
    got = _drain(LineCommands(_binary(b"one\n\xfe\xff\ntwo\n")), now=1.0)
    assert [(c.text, c.error[:30]) for c in got] == [("one", ""), ("", "line 2 on stdin is not UTF-8 t"),
                                                      ("two", "")]


def test_a_line_longer_than_the_limit_is_refused_without_being_held() -> None:
    """A line past MAX_LINE_BYTES is skipped to its end and refused; the line after it is a command."""
    from missiontree.robot.commands import MAX_LINE_BYTES

    got = _drain(LineCommands(_binary(b"x" * (3 * MAX_LINE_BYTES) + b"\nnext\n")), now=1.0)
    assert [c.text for c in got] == ["", "next"] and "longer than" in got[0].error
