"""The clock nodes measure time on: the robot's clock when a mission context is given, else monotonic.

In the simulator the robot's clock is simulated time, so ``Wait: {seconds: 30}`` lasts thirty
simulated seconds however fast the machine runs; trees ticked outside the runner (tests, scripts)
fall back to :func:`time.monotonic`.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

Clock = Callable[[], float]


def clock_of(context: Any | None) -> Clock:
    """The clock of a :class:`~missiontree.engine.context.MissionContext` (``robot.now``), or monotonic."""
    robot = getattr(context, "robot", None)
    now = getattr(robot, "now", None)
    return now if callable(now) else time.monotonic
