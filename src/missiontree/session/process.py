"""Process settings for long mission runs: set by the application, never by the library.

Two settings help a process that runs missions for hours (the command line, a batch worker):

- glibc's mmap threshold pinned (:func:`~missiontree.engine.native_memory.pin_mmap_threshold`), so
  big buffers go back to the system when freed instead of fragmenting the heap;
- the objects a session opened (models, robot, imported modules) frozen out of the garbage
  collector for the span of the run (:func:`gc.freeze`), so its full passes stop landing as
  ~25 ms stalls in a tick; unfrozen after the run, so a process running many missions still
  collects each one's cycles.

Both change the whole process, so a program that only imports missiontree (a test, a notebook, an
application embedding a tree) keeps its own settings: they take effect once the application asks
with :func:`tune_process`. The command line (:mod:`missiontree.cli.main`) and the batch workers
(:mod:`missiontree.evaluation.worker`) do; the session marks its run with :func:`run_span`.
"""

from __future__ import annotations

import contextlib
import gc
from collections.abc import Iterator

from missiontree.engine.native_memory import pin_mmap_threshold

__all__ = ["process_tuned", "run_span", "tune_process"]

_tuned = False


def tune_process() -> None:
    """Apply the settings for long runs to this process (idempotent; call from the application)."""
    global _tuned
    pin_mmap_threshold()
    _tuned = True


def process_tuned() -> bool:
    """True once :func:`tune_process` was called in this process."""
    return _tuned


@contextlib.contextmanager
def run_span() -> Iterator[None]:
    """The span of one mission's run: the heap opened so far frozen when the process is tuned."""
    if not _tuned:
        yield
        return
    gc.freeze()
    try:
        yield
    finally:
        gc.unfreeze()
