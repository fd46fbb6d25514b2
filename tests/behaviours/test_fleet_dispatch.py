"""The fleet patrol's dispatcher: contiguous stretches, nearest assignment, re-cut on a loss, done."""

from __future__ import annotations

from typing import Any

from missiontree.behaviours.fleet_dispatch import (
    PatrolDispatcher,
    assign_stretches,
    distinct_waypoints,
    partition_tour,
)
from missiontree.behaviours.waypoints import Waypoint
from missiontree.types import Pose2D


def _line(n: int) -> list[Waypoint]:
    return [Waypoint(f"P{i + 1}", Pose2D(float(i), 0.0, 0.0)) for i in range(n)]


Events = list[tuple[str, dict[str, Any]]]


def _dispatcher(n: int, names: list[str], laps: int = 1) -> tuple[PatrolDispatcher, Events]:
    events: Events = []
    d = PatrolDispatcher(_line(n), laps, names, lambda e, **f: events.append((e, f)), lambda: 0.0)
    return d, events


def test_stretches_cover_every_point_once_and_are_contiguous_on_the_tour() -> None:
    """Every waypoint lands in exactly one stretch, each stretch a run of consecutive tour positions."""
    points = [Pose2D(float(i % 4), float(i // 4), 0.0) for i in range(12)]
    stretches = partition_tour(points, 3)
    flat = sorted(i for s in stretches for i in s)
    assert flat == list(range(12))
    for s in stretches:
        steps = {(b - a) % 12 for a, b in zip(s, s[1:], strict=False)}
        assert steps <= {1}


def test_a_route_out_and_back_counts_each_waypoint_once() -> None:
    """A loop that repeats waypoints (out and back) patrols each distinct waypoint once per lap."""
    a, b, c = _line(3)
    assert [w.name for w in distinct_waypoints([a, b, c, b])] == ["P1", "P2", "P3"]


def test_each_robot_gets_the_stretch_nearest_to_it() -> None:
    """Two stretches at either end of a line go to the robot standing at that end."""
    points = [p.pose for p in _line(6)]
    stretches = [[0, 1, 2], [3, 4, 5]]
    chosen = assign_stretches(stretches, points, [Pose2D(5.0, 0.0, 0.0), Pose2D(0.0, 0.0, 0.0)])
    assert chosen == [1, 0]


def test_the_route_is_cut_once_every_robot_reported_its_pose() -> None:
    """No assignment until both robots joined; then fleet_assigned names every waypoint once."""
    d, events = _dispatcher(6, ["robot1", "robot2"])
    d.join("robot1", Pose2D(0.0, 0.0, 0.0))
    assert not d.started and d.next_for("robot1") is None
    d.join("robot2", Pose2D(5.0, 0.0, 0.0))
    assert events[0][0] == "fleet_assigned"
    names = sorted(n for ws in events[0][1]["assignment"].values() for n in ws)
    assert names == sorted(f"P{i + 1}" for i in range(6))


def test_a_lost_robots_waypoints_go_to_the_others_and_the_patrol_still_finishes() -> None:
    """After robot2 is lost, robot1 is given every waypoint still owed and the fleet ends done."""
    d, events = _dispatcher(6, ["robot1", "robot2"])
    d.join("robot1", Pose2D(0.0, 0.0, 0.0))
    d.join("robot2", Pose2D(5.0, 0.0, 0.0))
    assert d.lose("robot2", "killed")
    assert events[-1][0] == "fleet_rebalanced" and events[-1][1]["lost"] == "robot2"
    seen = []
    while (index := d.next_for("robot1")) is not None:
        seen.append(index)
        d.visited("robot1", index)
    assert sorted(seen) == list(range(6))
    assert d.done()


def test_losing_the_last_robot_leaves_nobody_to_take_the_work() -> None:
    """The dispatcher answers False when no live robot is left."""
    d, _ = _dispatcher(3, ["robot1"])
    d.join("robot1", Pose2D(0.0, 0.0, 0.0))
    assert not d.lose("robot1", "killed")


def test_a_skipped_waypoint_is_owed_no_more_visits() -> None:
    """An unreachable waypoint counts as done for a finite patrol, with its reason reported."""
    d, _ = _dispatcher(2, ["robot1"])
    d.join("robot1", Pose2D(0.0, 0.0, 0.0))
    d.visited("robot1", d.next_for("robot1") or 0)
    d.skip("robot1", 1, "no valid path")
    assert d.done()
    assert d.report()["skipped"] == {"P2": "no valid path"}


def test_an_endless_patrol_is_never_done() -> None:
    """laps: 0 keeps giving waypoints."""
    d, _ = _dispatcher(2, ["robot1"], laps=0)
    d.join("robot1", Pose2D(0.0, 0.0, 0.0))
    for _ in range(5):
        index = d.next_for("robot1")
        assert index is not None
        d.visited("robot1", index)
    assert not d.done()


def _three() -> tuple[PatrolDispatcher, Events]:
    d, events = _dispatcher(6, ["robot1", "robot2", "robot3"])
    for name, x in (("robot1", 0.0), ("robot2", 2.0), ("robot3", 5.0)):
        d.join(name, Pose2D(x, 0.0, 0.0))
    return d, events


def test_an_alarm_sends_the_nearest_free_other_robot() -> None:
    """robot1 raises an alarm at x=4.5: robot3 (0.5 m away) is sent, not robot1 itself nor robot2."""
    d, events = _three()
    assert d.alarm("robot1", 4.5, 0.0, 7) == "robot3"
    assert events[-1][0] == "alarm_dispatched" and events[-1][1]["robot"] == "robot3"
    assert d.response_for("robot3") is not None


def test_the_same_person_is_answered_once_and_a_busy_robot_is_not_sent_again() -> None:
    """A second alarm 1 m from the first sends nobody; one elsewhere goes to the next free robot."""
    d, _ = _three()
    d.alarm("robot1", 4.5, 0.0, 1)
    assert d.alarm("robot2", 5.5, 0.0, 2) is None
    assert d.alarm("robot1", 1.5, 10.0, 3) == "robot2"


def test_an_answered_alarm_frees_the_robot_and_records_the_outcome() -> None:
    """After responded(), robot3 is free again and the report says it reached the alarm."""
    d, _ = _three()
    d.alarm("robot1", 4.5, 0.0, 1)
    d.responded("robot3", "reached")
    assert d.response_for("robot3") is None
    assert d.report()["alarms_dispatched"][0]["outcome"] == "reached"


def test_the_alarm_a_robot_raises_where_it_was_sent_sends_nobody_back() -> None:
    """robot3 answered an alarm at x=4.5 and raises its own there: no robot is sent (no ping-pong)."""
    d, _ = _three()
    d.alarm("robot1", 4.5, 0.0, 1)
    d.responded("robot3", "reached")
    assert d.alarm("robot3", 4.6, 0.2, 9) is None
