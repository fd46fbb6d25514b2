"""A short time-indexed history of stamped values, for fusing late answers with old sensor data."""

from __future__ import annotations

import bisect
from collections import deque
from typing import Generic, TypeVar

T = TypeVar("T")


class StampedHistory(Generic[T]):
    """Keeps the values of the last ``horizon`` seconds, looked up by timestamp.

    Stamps must be pushed in non-decreasing order (as sensors deliver them).
    """

    def __init__(self, horizon: float = 10.0, maxlen: int = 10_000) -> None:
        self.horizon = horizon
        self._stamps: deque[float] = deque(maxlen=maxlen)
        self._values: deque[T] = deque(maxlen=maxlen)

    def __len__(self) -> int:
        return len(self._stamps)

    def push(self, stamp: float, value: T) -> None:
        """Append a value; drop what has fallen out of the horizon."""
        self._stamps.append(stamp)
        self._values.append(value)
        cutoff = stamp - self.horizon
        while self._stamps and self._stamps[0] < cutoff:
            self._stamps.popleft()
            self._values.popleft()

    def span(self) -> tuple[float, float] | None:
        """The oldest and newest stamps held, or None when empty."""
        if not self._stamps:
            return None
        return self._stamps[0], self._stamps[-1]

    def latest(self) -> tuple[float, T] | None:
        """The newest (stamp, value), or None when empty."""
        if not self._stamps:
            return None
        return self._stamps[-1], self._values[-1]

    def bracket(self, stamp: float) -> tuple[tuple[float, T], tuple[float, T]] | None:
        """The entries just before and just after ``stamp`` (equal when exact), None if outside."""
        if not self._stamps or stamp < self._stamps[0] or stamp > self._stamps[-1]:
            return None
        i = bisect.bisect_left(self._stamps, stamp)
        if self._stamps[i] == stamp or i == 0:
            return (self._stamps[i], self._values[i]), (self._stamps[i], self._values[i])
        return (self._stamps[i - 1], self._values[i - 1]), (self._stamps[i], self._values[i])

    def nearest(self, stamp: float, max_gap: float = float("inf")) -> T | None:
        """The value whose stamp is closest to ``stamp`` if within ``max_gap``, else None."""
        if not self._stamps:
            return None
        i = bisect.bisect_left(self._stamps, stamp)
        best = None
        best_gap = max_gap
        for j in (i - 1, i):
            if 0 <= j < len(self._stamps):
                gap = abs(self._stamps[j] - stamp)
                if gap <= best_gap:
                    best, best_gap = self._values[j], gap
        return best
