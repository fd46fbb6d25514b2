"""The runner's fleet scopes: a robot's events reach the run's sink as a start hook left it."""

from __future__ import annotations

from typing import Any

import pytest

from missiontree.engine.context import MissionContext
from missiontree.engine.leaf import Leaf, Status
from missiontree.engine.runner import Runner
from missiontree.plugins.hookspecs import hookimpl
from missiontree.testing import ClockRobot, clean_state, fresh_plugins


@pytest.fixture(autouse=True)
def _clean() -> None:
    clean_state()


class _Ping(Leaf):
    """Emits ``ping`` and succeeds."""

    def update(self) -> Status:
        self.emit("ping")
        return Status.SUCCESS


class _Wrapper:
    """A plugin that wraps the run's sink at mission start, as the ROS 2 backend does."""

    def __init__(self) -> None:
        self.seen: list[dict[str, Any]] = []

    @hookimpl
    def missiontree_mission_started(self, context: MissionContext, mission: object) -> None:
        inner, seen = context.events, self.seen

        class Sink:
            def emit(self, event: str, /, **fields: Any) -> None:
                seen.append({"event": event, **fields})
                inner.emit(event, **fields)

        context.events = Sink()


def test_a_fleet_robots_events_pass_through_a_sink_wrapped_at_mission_start() -> None:
    """A robot's event, emitted after a start hook wrapped the run's sink, reaches the wrapper."""
    plugins = fresh_plugins()
    wrapper = _Wrapper()
    plugins.pm.register(wrapper)
    leaf = _Ping("ping_leaf")
    robot_context = MissionContext(robot=ClockRobot())
    runner = Runner(leaf, MissionContext(robot=ClockRobot()), hook=plugins.hook, handle_signals=False,
                    scopes=[(leaf, robot_context, "robot2")])
    runner.run()
    assert {"event": "ping", "node": "ping_leaf", "robot": "robot2"} in wrapper.seen
