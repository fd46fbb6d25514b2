"""Stable JSON lines: values made JSON-ready, and a writer that keeps a failed write out of the tick.

:func:`plain` turns a leaf's values (dataclasses, pydantic models, enums, numpy values, paths) into
JSON with floats rounded to :data:`FLOAT_DIGITS` decimals, so the same seed gives the same file byte
for byte; :class:`LineWriter` is the final logger under the tick log's structlog chain.
"""

from __future__ import annotations

import dataclasses
import enum
import json
import math
import time
from pathlib import Path
from typing import Any, TextIO

from pydantic import BaseModel
from structlog.typing import EventDict

from missiontree.redact import has_secrets, scrub, scrub_data

FLOAT_DIGITS = 6
#: Arrays up to this many elements are logged whole; larger ones by shape and dtype.
MAX_ARRAY_ITEMS = 16


def plain(value: Any) -> Any:
    """A JSON-ready copy of ``value`` with floats rounded, stable across runs.

    Dataclasses, pydantic models, enums, numpy values and paths are converted; anything else
    becomes ``"<TypeName>"`` (never ``repr``, which may hold a memory address).
    """
    if value is None or isinstance(value, (bool, int, str)):  # noqa: UP038 - a tuple is faster here
        return value
    if isinstance(value, float):
        if math.isfinite(value):
            return round(value, FLOAT_DIGITS)
        return str(value)
    if isinstance(value, dict):
        return {str(k): plain(v) for k, v in value.items()}
    if isinstance(value, list | tuple | set | frozenset):
        items = sorted(value, key=repr) if isinstance(value, set | frozenset) else value
        return [plain(v) for v in items]
    if isinstance(value, enum.Enum):
        return value.name
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: plain(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if isinstance(value, BaseModel):
        return plain(value.model_dump())
    if isinstance(value, Path):
        return str(value)
    item = getattr(value, "item", None)
    shape = getattr(value, "shape", None)
    if shape is not None and hasattr(value, "tolist"):
        if shape == () and item is not None:
            return plain(item())
        if getattr(value, "size", MAX_ARRAY_ITEMS + 1) <= MAX_ARRAY_ITEMS:
            return plain(value.tolist())
        return {"array": list(shape), "dtype": str(getattr(value, "dtype", ""))}
    return f"<{type(value).__name__}>"


def plain_event(logger: Any, method: str, event_dict: EventDict) -> EventDict:
    """Structlog processor: make every field JSON-ready and stable."""
    return {k: plain(v) for k, v in event_dict.items()}


def add_wall_time(logger: Any, method: str, event_dict: EventDict) -> EventDict:
    """Structlog processor for real robots: the wall-clock time, to the millisecond."""
    event_dict["wall"] = round(time.time(), 3)
    return event_dict


#: One encoder for every line (``json.dumps`` with options would build a new one per call).
ENCODE = json.JSONEncoder(separators=(",", ":"), ensure_ascii=False, sort_keys=True).encode


def dumps(obj: Any, **kwargs: Any) -> str:
    """Serialise one line (structlog's serializer: its keyword arguments are ignored)."""
    return ENCODE(obj)


class LineWriter:
    """structlog's final logger: writes rendered lines, flushing only when asked to.

    structlog's ``WriteLogger`` flushes every line, a system call per tick; a simulated run
    needs the file only at the end, a real robot's run flushes each line (``flush_each_line``).

    A write that fails (a full disk, a vanished file system) is kept in :attr:`error` instead of
    raised into the tick, and every later line is dropped, so the file stays whole lines; the
    runner sees :attr:`error` after the tick and ends the run with the reason.

    Args:
        stream: Where lines go.
        flush_each_line: Flush after every line (a real robot's run).
    """

    def __init__(self, stream: TextIO, flush_each_line: bool) -> None:
        self._write = stream.write
        self._flush = stream.flush if flush_each_line else None
        self._stream = stream
        self.error: OSError | None = None

    def msg(self, message: str) -> None:
        """Write one line (dropped after a failed write)."""
        if self.error is not None:
            return
        if has_secrets():  # a provider holds a key: no trace of it may reach the file
            cleaned = scrub(message)
            if cleaned != message:  # scrubbed again value by value, so the line stays JSON
                data = json.loads(message)
                message = ENCODE(scrub_data(data))
                if scrub(message) != message:  # a trace spread over several values: keep the ids only
                    message = ENCODE({**{k: data[k] for k in ("event", "mission", "tick", "t") if k in data},
                                       "redacted": "this line held a trace of a secret"})
        line = message + "\n"
        try:
            self._write(line)
            if self._flush is not None:
                self._flush()
        except OSError as error:
            self.error = error

    info = msg  # structlog's native bound logger calls the level name

    def flush(self) -> None:
        """Flush the stream (a failure is kept in :attr:`error`, not raised; nothing after a failure)."""
        if self.error is not None:
            return
        try:
            self._stream.flush()
        except OSError as error:
            self.error = error

    def redirect(self, stream: TextIO) -> None:
        """Write the following lines to ``stream``, flushing as before."""
        self._stream = stream
        self._write = stream.write
        if self._flush is not None:
            self._flush = stream.flush
