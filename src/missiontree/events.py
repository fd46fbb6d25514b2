"""Where typed events go: the one event-sink protocol every layer writes to.

A leaf, a model call or the safety envelope reports what happened (goal sent, model call, alarm,
...) by ``sink.emit(kind, **fields)``; the engine's tick log is the sink of a run. Defined here, under
everything, so that the engine and the reasoning layer (which stand apart) name the same protocol.
"""

from __future__ import annotations

from typing import Any, Protocol

__all__ = ["EventSink", "ForwardEvents", "NullEvents"]


class EventSink(Protocol):
    """Where typed events (goal sent, model call, alarm, ...) go for the tick log."""

    def emit(self, event: str, /, **fields: Any) -> None:
        """Record one event of kind ``event``; fields must be JSON-serialisable."""
        ...


class NullEvents:
    """An event sink that drops everything (a tree ticked or a model called outside a run)."""

    def emit(self, event: str, /, **fields: Any) -> None:
        """Drop the event."""


class _HasEvents(Protocol):
    events: EventSink


class ForwardEvents:
    """Sends each event to ``holder.events`` as it is at the time of the event.

    A service made before the run starts (the mission's model caller) writes through this to the sink
    the runner installs later (the tick log, perhaps wrapped by a backend's hook).
    """

    def __init__(self, holder: _HasEvents) -> None:
        self.holder = holder

    def emit(self, event: str, /, **fields: Any) -> None:
        """Record the event in the holder's current sink."""
        self.holder.events.emit(event, **fields)
