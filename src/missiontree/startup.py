"""Ctrl-C while the command starts: never a traceback, and never lost.

The default SIGINT handler raises KeyboardInterrupt wherever the main thread is, and some places
swallow it: a weakref callback of the import system ("Exception ignored in ... _get_module_lock"),
or an extension module's import that clears errors. A Ctrl-C there used to vanish, and the run
went on to its end (exit 1 for a run that did not succeed) as if nothing had been pressed.
:func:`guard` installs a handler that records the signal before raising, so the command line can
ask :func:`interrupted` once start-up is over and exit 130 all the same. The run itself installs
its own handlers (:mod:`missiontree.engine.runner`) and puts this one back when it ends; when it
takes over from this one it asks :func:`guarding` and :func:`interrupted`, so a Ctrl-C swallowed
while the session was being built stops the run at once instead of letting it run to its end.

Where Python swallows the KeyboardInterrupt it still prints it ("Exception ignored in ...", a
traceback through :func:`_on_sigint`) by way of :data:`sys.unraisablehook`; :func:`guard` wraps
that hook so an interrupt it already recorded is not printed, and anything else still is. The run's
own "stop now" on a second signal raises through :func:`raise_interrupt` too, so one that lands in
a finaliser (an llvmlite object's ``__del__`` collected mid-tick) is recorded and kept quiet as well.
"""

from __future__ import annotations

import signal
import sys
import threading

TYPE_CHECKING = False  # not typing's: importing typing builds classes, where a Ctrl-C precedes the guard
if TYPE_CHECKING:
    from types import FrameType
    from typing import Any, NoReturn

_pending = False


def raise_interrupt() -> NoReturn:
    """Record a Ctrl-C and raise KeyboardInterrupt (recorded first: where Python swallows it, it is kept)."""
    global _pending
    _pending = True
    raise KeyboardInterrupt


def _on_sigint(signum: int, frame: FrameType | None) -> None:
    raise_interrupt()


def _quiet_unraisable(unraisable: sys.UnraisableHookArgs) -> None:
    """Drop a swallowed KeyboardInterrupt (it is recorded); print anything else as Python would."""
    if isinstance(unraisable.exc_value, KeyboardInterrupt) and _pending:
        return
    sys.__unraisablehook__(unraisable)


def guard() -> None:
    """Record SIGINT from now on (and raise KeyboardInterrupt as Python's default handler does)."""
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, _on_sigint)
        sys.unraisablehook = _quiet_unraisable


def guarding(handler: Any) -> bool:
    """Whether ``handler`` (a SIGINT handler replaced by the run's own) is this module's guard."""
    return handler is _on_sigint


def interrupted() -> bool:
    """Whether SIGINT arrived since :func:`guard` (even if its KeyboardInterrupt was swallowed)."""
    return _pending
