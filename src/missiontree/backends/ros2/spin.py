"""The executor's thread, one way for the robot and for the simulator's bridge.

Both keep a node in a context of their own and spin its executor on a thread until they close:
:func:`spin_until` is that thread's loop, :func:`stop_spinning` ends it in the order the close needs.
"""

from __future__ import annotations

import threading
from typing import Any

import rclpy
from rclpy.executors import ExternalShutdownException


def spin_until(context: Any, executor: Any, stop: threading.Event) -> None:
    """Spin ``executor`` until ``stop`` is set or ``context`` shuts down.

    A shutdown under the executor (the context closed while it waited) ends the loop quietly; any
    other error is raised while the context is still up.
    """
    try:
        while context.ok() and not stop.is_set():
            executor.spin_once(timeout_sec=0.1)
    except (ExternalShutdownException, rclpy.executors.ShutdownException):
        pass
    except Exception:  # noqa: BLE001 - the context was shut down under the executor during close
        if context.ok():
            raise


def stop_spinning(stop: threading.Event, spinner: threading.Thread, executor: Any) -> None:
    """End the spinning thread, then shut the executor down.

    In this order: a callback running under a shut-down executor fails on its destroyed guard
    condition.
    """
    stop.set()
    if spinner.is_alive():
        spinner.join(timeout=2.0)
    executor.shutdown(timeout_sec=1.0)
