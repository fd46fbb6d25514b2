"""Tests of the Patrol leaf and the waypoint formats, on a scripted robot."""

from __future__ import annotations

import math
from pathlib import Path

import py_trees
import pytest
from patrol_doubles import Events, FakeHandle, FakeRobot

from missiontree.behaviours.patrol import Patrol
from missiontree.behaviours.waypoints import load_waypoints, parse_waypoints
from missiontree.engine.context import MissionContext
from missiontree.engine.leaf import Status
from missiontree.errors import ConfigError
from missiontree.robot.actions import INFRASTRUCTURE, ActionResult, ActionStatus
from missiontree.testing import tick_until

ROUTE = [[1.0, 0.0, 0.0], [2.0, 0.0, 0.0], [2.0, 1.0, 1.57]]


def make(robot: FakeRobot, **params: object) -> tuple[Patrol, Events]:
    events = Events()
    leaf = Patrol("patrol", Patrol.Params(**params))
    leaf.setup(context=MissionContext(robot=robot, events=events))
    return leaf, events


def test_patrol_drives_the_route_for_the_laps_asked() -> None:
    """Two laps of three waypoints send six goals in order and end in SUCCESS."""
    robot = FakeRobot()
    leaf, events = make(robot, waypoints=ROUTE, laps=2)
    tick_until(leaf, max_ticks=50)
    assert leaf.status == Status.SUCCESS
    assert [(g.goal.x, g.goal.y) for g in robot.goals] == [(1, 0), (2, 0), (2, 1)] * 2
    assert len(events.of("waypoint_reached")) == 6
    assert [e["lap"] for e in events.of("lap_done")] == [1, 2]


def test_unreachable_waypoint_is_skipped_with_reason_and_patrol_goes_on() -> None:
    """An aborted goal is logged as skipped with the planner's reason and the next waypoint follows."""
    robot = FakeRobot()
    robot.unreachable.add((2.0, 0.0))
    leaf, events = make(robot, waypoints=ROUTE, laps=1)
    tick_until(leaf, max_ticks=50)
    assert leaf.status == Status.SUCCESS
    skipped = events.of("waypoint_skipped")
    assert [s["waypoint"] for s in skipped] == ["P2"]
    assert "goal inside an obstacle" in skipped[0]["reason"]
    assert [e["waypoint"] for e in events.of("waypoint_reached")] == ["P1", "P3"]


def test_patrol_fails_when_a_whole_lap_is_unreachable() -> None:
    """A route whose every waypoint aborts fails instead of spinning forever."""
    robot = FakeRobot()
    robot.unreachable.update({(1.0, 0.0), (2.0, 0.0), (2.0, 1.0)})
    leaf, _ = make(robot, waypoints=ROUTE, laps=0)
    tick_until(leaf, max_ticks=50)
    assert leaf.status == Status.FAILURE
    assert "3 waypoints in a row unreachable" in leaf.feedback_message


def test_preempted_patrol_resumes_at_interrupted_waypoint() -> None:
    """Halted while driving to P2, the patrol cancels that goal and drives to P2 again when restarted."""
    robot = FakeRobot()
    leaf, events = make(robot, waypoints=ROUTE, laps=1)
    for _ in range(4):  # P1 reached after 3 polls, P2 sent
        leaf.tick_once()
    assert robot.goals[-1].goal.x == 2.0 and robot.goals[-1].goal.y == 0.0
    leaf.stop(Status.INVALID)  # a higher-priority branch takes over
    assert robot.goals[-1].cancelled
    assert events.of("patrol_preempted")[0]["waypoint"] == "P2"
    leaf.tick_once()
    assert (robot.goals[-1].goal.x, robot.goals[-1].goal.y) == (2.0, 0.0)
    tick_until(leaf, max_ticks=50)
    assert [e["waypoint"] for e in events.of("waypoint_reached")] == ["P1", "P2", "P3"]


def test_yaw_tolerance_is_passed_to_navigation() -> None:
    """The configured yaw tolerance (2π accepts any heading, seed 001 §3.6) reaches the goal."""
    robot = FakeRobot()
    leaf, _ = make(robot, waypoints=ROUTE, yaw_tolerance=6.28, xy_tolerance=0.2)
    leaf.tick_once()
    assert robot.goals[0].tolerance.yaw == pytest.approx(6.28)
    assert robot.goals[0].tolerance.xy == pytest.approx(0.2)


def test_waypoint_timeout_skips_a_slow_goal() -> None:
    """A goal not reached within waypoint_timeout is cancelled and skipped."""
    robot = FakeRobot()
    robot.polls_per_goal = 1000
    leaf, events = make(robot, waypoints=ROUTE[:2], waypoint_timeout=5.0)
    leaf.tick_once()
    robot.advance(6.0)
    leaf.tick_once()
    assert robot.goals[0].cancelled
    assert "not reached within 5 s" in events.of("waypoint_skipped")[0]["reason"]


def test_patrol_params_need_exactly_one_route_source() -> None:
    """Giving neither inline waypoints nor a file is a validation error naming both."""
    with pytest.raises(ValueError, match="exactly one of `waypoints`"):
        Patrol.Params()


def test_parse_accepts_seed_lists_and_mappings() -> None:
    """[x, y, yaw] lists and {x, y, yaw, name} mappings both parse."""
    route = parse_waypoints([[4.2, 3.8, 0.0], {"name": "door", "x": 1, "y": 2, "yaw": 0.5}])
    assert [w.name for w in route] == ["P1", "door"]
    assert route[1].pose.yaw == 0.5


def test_parse_reads_nav2_panel_file(tmp_path: Path) -> None:
    """The Nav2 RViz panel's waypoint file (pose list + quaternion) loads with its headings."""
    path = tmp_path / "wps.yaml"
    path.write_text(
        "waypoints:\n"
        "  waypoint1:\n    pose: [2.0, 1.0, 0.0]\n    orientation: [0.0, 0.0, 0.7071068, 0.7071068]\n"
        "  waypoint0:\n    pose: [1.0, 0.5, 0.0]\n    orientation: [0.0, 0.0, 0.0, 1.0]\n")
    route = load_waypoints(str(path))
    assert [w.name for w in route] == ["waypoint0", "waypoint1"]
    assert route[1].pose.yaw == pytest.approx(math.pi / 2)


def test_parse_reads_pose_stamped_dumps() -> None:
    """geometry_msgs PoseStamped-like mappings parse, yaw from the quaternion."""
    route = parse_waypoints([{"header": {"frame_id": "map"}, "pose": {
        "position": {"x": 1.0, "y": -2.0, "z": 0.0}, "orientation": {"z": 1.0, "w": 0.0}}}])
    assert route[0].pose.x == 1.0 and route[0].pose.yaw == pytest.approx(math.pi)


def test_load_picks_named_route(tmp_path: Path) -> None:
    """A file with several routes needs the route named; an unknown name lists the known ones."""
    path = tmp_path / "routes.yaml"
    path.write_text("routes:\n  A: [[5.9, -0.07, 0.0], [10.0, -1.35, 0.0]]\n  B: [[10.0, -3.07]]\n")
    assert len(load_waypoints(str(path), "A")) == 2
    with pytest.raises(ConfigError, match="holds several routes"):
        load_waypoints(str(path))
    with pytest.raises(ConfigError, match="known: A, B"):
        load_waypoints(str(path), "C")


@pytest.mark.parametrize("bad, message", [
    ([], "at least one waypoint"),
    ([[1.0]], "expected \\[x, y\\] or \\[x, y, yaw\\]"),
    ([["a", 2.0]], "expected a finite number, found 'a'"),
    ("corridor", "expected a list of waypoints"),
    ([{"z": 1}], "found keys \\['z'\\]"),
])
def test_bad_waypoints_say_what_was_expected(bad: object, message: str) -> None:
    """Malformed routes raise ConfigError saying what was expected and what was found."""
    with pytest.raises(ConfigError, match=message):
        parse_waypoints(bad, "trees/patrol.yaml: Patrol.waypoints")


def test_patrol_in_a_tree_restarts_after_success() -> None:
    """Under a Repeat-like restart the patrol starts from the first waypoint again after finishing."""
    robot = FakeRobot()
    leaf, _ = make(robot, waypoints=ROUTE[:1], laps=1)
    root = py_trees.composites.Sequence("root", memory=True, children=[leaf])
    tick_until(root, max_ticks=10)
    tick_until(root, max_ticks=10)
    assert [(g.goal.x, g.goal.y) for g in robot.goals] == [(1.0, 0.0), (1.0, 0.0)]


def test_order_list_gives_the_loop_with_repeats(tmp_path: Path) -> None:
    """A file's `order:` list drives out and back (names repeat), as the combined route does."""
    path = tmp_path / "c.yaml"
    path.write_text("waypoints:\n  - {name: P1, pose: [0, 0, 0]}\n  - {name: P2, pose: [1, 0, 0]}\n"
                    "  - {name: P3, pose: [2, 0, 0]}\norder: [P1, P2, P3, P2]\n")
    assert [w.name for w in load_waypoints(str(path))] == ["P1", "P2", "P3", "P2"]
    path.write_text("waypoints:\n  - {name: P1, pose: [0, 0, 0]}\norder: [P1, P9]\n")
    with pytest.raises(ConfigError, match="unknown waypoints P9"):
        load_waypoints(str(path))


def test_shipped_scenario_routes_load() -> None:
    """The seed's scenario files load by name: A has 2 waypoints, C the 22-stop combined loop."""
    assert len(load_waypoints("scenario_a")) == 2
    route = load_waypoints("scenario_c")
    assert len(route) == 22 and route[8].name == "P7"


# -- a lost robot is not an unreachable waypoint ----------------------------------------------------

class NoServerRobot(FakeRobot):
    """Every goal aborts because no NavigateToPose server answers (as the ROS 2 backend reports it)."""

    def navigate_to(self, goal, tolerance=None):  # type: ignore[no-untyped-def]
        handle = FakeHandle(goal, tolerance, ActionStatus.ABORTED, "no NavigateToPose action server on "
                            "/navigate_to_pose after 5 s", 1)
        original = handle.result

        def result():  # type: ignore[no-untyped-def]
            plain = original()
            return None if plain is None else ActionResult(plain.status, plain.reason, kind=INFRASTRUCTURE)

        handle.result = result  # type: ignore[method-assign]
        self.goals.append(handle)
        return handle


def test_no_navigation_server_fails_the_patrol_instead_of_skipping_every_waypoint() -> None:
    """The first goal lost to a missing server fails the patrol with the reason; nothing is 'skipped'."""
    route = [[float(i), 0.0, 0.0] for i in range(1, 23)]
    robot = NoServerRobot()
    leaf, events = make(robot, waypoints=route, laps=1)
    tick_until(leaf, max_ticks=200)
    assert leaf.status == Status.FAILURE
    assert "robot lost" in leaf.feedback_message
    assert "no NavigateToPose action server" in leaf.feedback_message
    assert events.of("waypoint_skipped") == [] and len(events.of("patrol_lost")) == 1
    assert len(robot.goals) == 1


class VanishedRobot(FakeRobot):
    """The robot stops publishing its pose at t=1 s; goals never end (nothing answers any more)."""

    def pose(self):  # type: ignore[no-untyped-def]
        stamped = super().pose()
        assert stamped is not None
        return type(stamped)(min(stamped.stamp, 1.0), stamped.pose)


def test_a_stale_pose_fails_the_patrol_and_cancels_the_goal() -> None:
    """With the pose 2 s stale the patrol cancels its goal and fails saying the robot is lost."""
    robot = VanishedRobot()
    robot.polls_per_goal = 10_000
    leaf, events = make(robot, waypoints=ROUTE, laps=1, max_pose_age=2.0)
    for _ in range(100):
        leaf.tick_once()
        if leaf.status != Status.RUNNING:
            break
        robot.advance(0.1)
    assert leaf.status == Status.FAILURE and "pose was last updated" in leaf.feedback_message
    assert 3.0 <= robot.time <= 3.3
    assert robot.goals[0].cancelled and events.of("waypoint_skipped") == []


def test_an_unreachable_waypoint_is_still_skipped_not_lost() -> None:
    """A planner abort without the infrastructure kind is skipped as before."""
    robot = FakeRobot()
    robot.unreachable.add((2.0, 0.0))
    leaf, events = make(robot, waypoints=ROUTE, laps=1)
    tick_until(leaf, max_ticks=50)
    assert leaf.status == Status.SUCCESS and len(events.of("waypoint_skipped")) == 1
    assert events.of("patrol_lost") == []


def test_halted_on_the_tick_its_goal_succeeded_the_patrol_counts_the_waypoint_and_moves_on() -> None:
    """Preempted at the moment a waypoint is reached: the visit counts, the next start heads onwards.

    The goal for P2 has ended (the robot is there) but the patrol is halted before it polls it, as
    when servoing on an alarm preempts it on that very tick. Driving back to P2 afterwards would
    repeat the visit, or lose it when the person who raised the alarm now stands on P2.
    """
    robot = FakeRobot()
    leaf, events = make(robot, waypoints=ROUTE, laps=1)
    for _ in range(4):  # P1 reached after 3 polls, P2 sent
        leaf.tick_once()
    robot.goals[-1].polls = 1  # P2's goal ends at its next poll: the robot has arrived
    leaf.stop(Status.INVALID)  # a higher-priority branch takes over before the patrol polls
    assert [e["waypoint"] for e in events.of("waypoint_reached")] == ["P1", "P2"]
    assert events.of("patrol_preempted") == []  # no goal was cut short
    robot.unreachable.add((2.0, 0.0))  # the person now stands on P2
    tick_until(leaf, max_ticks=50)
    assert leaf.status == Status.SUCCESS
    assert [(g.goal.x, g.goal.y) for g in robot.goals] == [(1, 0), (2, 0), (2, 1)]  # P2 not driven twice
    assert [e["waypoint"] for e in events.of("waypoint_reached")] == ["P1", "P2", "P3"]
    assert events.of("waypoint_skipped") == []


def test_halted_as_the_last_waypoint_of_the_last_lap_is_reached_the_patrol_ends_on_its_next_start() -> None:
    robot = FakeRobot()
    leaf, events = make(robot, waypoints=ROUTE[:2], laps=1)
    for _ in range(4):
        leaf.tick_once()
    robot.goals[-1].polls = 1
    leaf.stop(Status.INVALID)
    assert [e["lap"] for e in events.of("lap_done")] == [1]
    leaf.tick_once()
    assert leaf.status == Status.SUCCESS
    assert len(robot.goals) == 2 and "1 lap(s): 2 waypoints reached" in leaf.feedback_message
    leaf.tick_once()  # started again (a tree that repeats it): a new patrol from P1
    assert leaf.status == Status.RUNNING and (robot.goals[-1].goal.x, robot.goals[-1].goal.y) == (1, 0)


def test_a_preemption_in_a_tree_on_the_arrival_tick_keeps_the_visit() -> None:
    """The patrol under a Selector whose first branch takes over on the tick P2's goal ends."""
    robot = FakeRobot()
    events = Events()
    patrol = Patrol("patrol", Patrol.Params(waypoints=ROUTE, laps=1))
    alarm = {"on": False}

    class Respond(py_trees.behaviour.Behaviour):
        def update(self) -> py_trees.common.Status:
            return py_trees.common.Status.RUNNING if alarm["on"] else py_trees.common.Status.FAILURE

    root = py_trees.composites.Selector("respond_or_patrol", memory=False,
                                        children=[Respond("respond"), patrol])
    py_trees.trees.setup(root, context=MissionContext(robot=robot, events=events))
    for _ in range(4):
        root.tick_once()
    robot.goals[-1].polls = 1  # P2 reached during this tick's step
    alarm["on"] = True
    root.tick_once()  # the respond branch preempts the patrol before it polls
    robot.unreachable.add((2.0, 0.0))
    alarm["on"] = False
    for _ in range(20):
        root.tick_once()
        if patrol.status == Status.SUCCESS:
            break
    assert [e["waypoint"] for e in events.of("waypoint_reached")] == ["P1", "P2", "P3"]
    assert events.of("waypoint_skipped") == []
