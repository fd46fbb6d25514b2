"""Per-call timings kept in bounded memory: the recent samples plus running totals."""

from __future__ import annotations

import statistics
from collections import deque
from collections.abc import Iterator


class TimingLog:
    """Milliseconds per call: the last ``keep`` samples, and count / total / max over the whole run.

    Iterates and measures ``len`` over the kept samples (``statistics.median(log)`` is the median
    of the recent calls); ``count`` is every call. Memory stays flat on long runs.
    """

    def __init__(self, keep: int = 4096) -> None:
        self.recent: deque[float] = deque(maxlen=keep)
        self.count = 0
        self.total_ms = 0.0
        self.max_ms = 0.0

    def append(self, ms: float) -> None:
        """Record one call."""
        self.recent.append(ms)
        self.count += 1
        self.total_ms += ms
        self.max_ms = max(self.max_ms, ms)

    def __len__(self) -> int:
        return len(self.recent)

    def __iter__(self) -> Iterator[float]:
        return iter(self.recent)

    def __getitem__(self, index: int) -> float:
        return self.recent[index]

    def __bool__(self) -> bool:
        return self.count > 0

    @property
    def mean_ms(self) -> float:
        """Mean over every call (nan before the first)."""
        return self.total_ms / self.count if self.count else float("nan")

    def median(self) -> float:
        """Median of the kept samples (nan before the first)."""
        return statistics.median(self.recent) if self.recent else float("nan")
