"""Recording a ROS 2 bag from a running robot, for the command line (which reaches backends here).

:func:`record_bag` checks that ROS 2 support imports, then hands over to
:func:`missiontree.backends.ros2.bag_record.record_bag` (the recorder itself).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any


def record_bag(out: str | Path, duration: float, topics: Sequence[str] | None = None, *,
               domain_id: int | None = None, max_rate: Mapping[str, float] | None = None,
               discovery_timeout: float = 10.0, compression: str = "zstd") -> Any:
    """Record a bag over DDS; returns the recorder's ``BagSummary``.

    Raises:
        BackendUnavailableError: rclpy or the message packages do not import (names the install).
        BackendError: No topic found, or a type whose definition is not installed.
        ConfigError: A non-positive duration or rate, or an unknown compression.
    """
    from missiontree.backends.ros2 import require_rclpy

    require_rclpy()
    from missiontree.backends.ros2.bag_record import record_bag as record

    return record(out, duration, topics, domain_id=domain_id, max_rate=max_rate,
                  discovery_timeout=discovery_timeout, compression=compression)


def default_topics() -> tuple[str, ...]:
    """The TurtleBot 4 topics recorded when none are named (the recorder need not import to list them)."""
    from missiontree.backends.ros2.bag_record import DEFAULT_TOPICS

    return DEFAULT_TOPICS
