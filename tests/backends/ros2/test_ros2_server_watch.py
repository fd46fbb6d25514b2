"""A robot's view of its NavigateToPose server across goals (ServerWatch), on a fake clock and client."""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any

import pytest

pytest.importorskip("rclpy", reason="ROS 2 extra not installed: pip install -e .[ros2]; setup-ros2.sh")

from missiontree.backends.ros2 import navigation  # noqa: E402
from missiontree.backends.ros2.navigation import ActionGoal, ServerWatch  # noqa: E402
from missiontree.robot.actions import INFRASTRUCTURE, ActionStatus  # noqa: E402
from missiontree.types import Pose2D  # noqa: E402


class _Client:
    """An action client whose server is up or not; it never answers a goal."""

    def __init__(self) -> None:
        self.up = True
        self.sent = 0

    def server_is_ready(self) -> bool:
        return self.up

    def send_goal_async(self, *args: Any, **kwargs: Any) -> Any:
        self.sent += 1
        return SimpleNamespace(add_done_callback=lambda fn: None)


@pytest.fixture
def clock(monkeypatch: pytest.MonkeyPatch) -> SimpleNamespace:
    """The navigation module's monotonic clock, set by the test."""
    fake = SimpleNamespace(t=100.0)
    monkeypatch.setattr(navigation, "time", SimpleNamespace(monotonic=lambda: fake.t))
    return fake


def _goal(client: _Client, watch: ServerWatch) -> ActionGoal:
    return ActionGoal(client, object(), Pose2D(1.0, 0.0, 0.0), 15.0, lambda: None, "navigate_to_pose",
                      watch=watch)


def test_a_goal_after_the_server_has_been_gone_long_aborts_at_once(clock: SimpleNamespace) -> None:
    """Seen, then gone for 20 s: a new goal ends ABORTED (infrastructure) at its first look, unsent."""
    client = _Client()
    watch = ServerWatch(client)
    assert watch.ready()
    client.up = False
    clock.t += 20.0
    goal = _goal(client, watch)
    assert goal.status() is ActionStatus.ABORTED
    result = goal.result()
    assert result is not None and result.kind == INFRASTRUCTURE and "went away" in result.reason
    assert client.sent == 0


def test_a_server_never_seen_gets_the_goals_own_timeout(clock: SimpleNamespace) -> None:
    """Never seen (a robot starting): the goal waits its server_timeout from its own start, then aborts."""
    client = _Client()
    client.up = False
    watch = ServerWatch(client)
    clock.t += 60.0
    goal = _goal(client, watch)
    assert goal.status() is ActionStatus.PENDING
    clock.t += 16.0
    assert goal.status() is ActionStatus.ABORTED
    assert "no NavigateToPose action server" in goal.result().reason  # type: ignore[union-attr]


def test_a_server_gone_briefly_does_not_end_a_new_goal(clock: SimpleNamespace) -> None:
    """Gone for less than server_timeout: the new goal waits and is sent when the server is back."""
    client = _Client()
    watch = ServerWatch(client)
    watch.ready()
    client.up = False
    clock.t += 5.0
    goal = _goal(client, watch)
    assert goal.status() is ActionStatus.PENDING
    client.up = True
    goal.status()
    assert client.sent == 1
