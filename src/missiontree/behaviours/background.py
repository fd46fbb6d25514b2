"""Map geometry off the tick: a job on a worker thread, polled by a leaf, deterministic in simulation.

Planning a standoff pose (a Dijkstra search over the learned map) can take longer than a tick on a
large map; a leaf must not hold the tick for it. :class:`Background` runs such a function on a small
shared pool and is polled from ``update``. It is not a model call (no role, no latency draw, no
``model_call`` event). In a simulated run that is not paced to wall time the poll waits for the
result, so a run is the same whatever the machine's load, as model calls are in simulation.
"""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from missiontree.engine.context import MissionContext

#: Geometry jobs run at once (a mission has few leaves planning at the same time).
WORKERS = 2

_POOL: ThreadPoolExecutor | None = None


def _pool() -> ThreadPoolExecutor:
    global _POOL
    if _POOL is None:
        _POOL = ThreadPoolExecutor(max_workers=WORKERS, thread_name_prefix="geometry")
    return _POOL


class Background:
    """One function run on a worker thread; :meth:`poll` returns (done, result, error)."""

    def __init__(self, fn: Callable[..., Any], *args: Any, wait: bool = False) -> None:
        """Start ``fn(*args)``; with ``wait`` the first poll waits for it (simulated runs)."""
        self.wait = wait
        self._future: Future[Any] | None = _pool().submit(fn, *args)

    def poll(self) -> tuple[bool, Any, str]:
        """(finished, its result, "" or why it failed); never blocks unless ``wait``."""
        future = self._future
        if future is None:
            return True, None, "cancelled"
        if not future.done() and not self.wait:
            return False, None, ""
        self._future = None
        error = future.exception()
        if error is not None:
            return True, None, f"{type(error).__name__}: {error}"
        return True, future.result(), ""

    def cancel(self) -> None:
        """Drop the job (a running one finishes on its thread, its result unread)."""
        if self._future is not None:
            self._future.cancel()
            self._future = None


def waits(ctx: MissionContext) -> bool:
    """Whether jobs of this mission are awaited: a simulated robot not paced to wall time."""
    return bool(ctx.robot.simulated) and not ctx.realtime
