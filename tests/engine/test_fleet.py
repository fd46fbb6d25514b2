"""The fleet root: robots ticked together, a failed robot lost, the fleet failing only when stuck."""

from __future__ import annotations

import py_trees
import pytest

from missiontree.engine.fleet import FleetRoot, FleetView, RobotEvents, RobotScope, namespace_tree
from missiontree.engine.leaf import Leaf
from missiontree.engine.nodes.basic import Running
from missiontree.engine.nodes.stub import Stub
from missiontree.testing import clean_state

Status = py_trees.common.Status


@pytest.fixture(autouse=True)
def _clean() -> None:
    clean_state()


class _Ends(Leaf):
    """Returns the status it was made with (FAILURE with a reason)."""

    def __init__(self, name: str, status: Status) -> None:
        super().__init__(name)
        self.result = status

    def update(self) -> Status:
        return self.fail("gone") if self.result is Status.FAILURE else self.result


def _root(statuses: list[Status], taker: bool) -> tuple[FleetRoot, FleetView]:
    names = [f"robot{i + 1}" for i in range(len(statuses))]
    view = FleetView(names, lambda: 1.0)
    if taker:
        view.on_loss(lambda name, reason: bool(view.live()))
    scopes = [RobotScope(n, _Ends("leaf", s) if s is not Status.RUNNING else Running("leaf"))
              for n, s in zip(names, statuses, strict=True)]
    return FleetRoot(scopes, view), view


def _tick(root: FleetRoot) -> Status:
    for _ in root.tick():
        pass
    return root.status


def test_a_lost_robot_whose_work_is_taken_over_does_not_fail_the_fleet() -> None:
    """robot2 fails, a listener takes its work: the fleet runs on and records the loss."""
    root, view = _root([Status.RUNNING, Status.FAILURE], taker=True)
    assert _tick(root) is Status.RUNNING
    assert view.lost["robot2"]["taken_over"] is True
    assert root.robot_report()["robot2"]["status"] == "FAILURE"


def test_a_lost_robot_nobody_takes_over_fails_the_fleet() -> None:
    """A plain tree copied per robot has nobody to take a lost robot's work: the fleet fails."""
    root, _ = _root([Status.RUNNING, Status.FAILURE], taker=False)
    assert _tick(root) is Status.FAILURE


def test_the_fleet_succeeds_when_every_robot_ended_and_one_succeeded_with_losses_taken() -> None:
    """One success plus a taken-over loss is SUCCESS."""
    root, _ = _root([Status.SUCCESS, Status.FAILURE], taker=True)
    assert _tick(root) is Status.SUCCESS


def test_every_robot_failing_fails_the_fleet() -> None:
    """Nobody left: FAILURE even with a listener."""
    root, _ = _root([Status.FAILURE, Status.FAILURE], taker=True)
    assert _tick(root) is Status.FAILURE


def test_robot_events_carry_the_robot() -> None:
    """Events through a robot's sink gain robot=<name> and are counted."""
    seen: list[dict[str, object]] = []

    class _Sink:
        def emit(self, event: str, /, **fields: object) -> None:
            seen.append({"event": event, **fields})

    sink = RobotEvents(_Sink(), "robot2")
    sink.emit("goal_sent", node="patrol")
    assert seen == [{"event": "goal_sent", "node": "patrol", "robot": "robot2"}]
    assert sink.counts == {"goal_sent": 1}


def test_namespace_tree_stores_each_copys_keys_under_its_robot_and_keeps_fleet_keys_shared() -> None:
    """Two copies writing the same key land in /robot1/ and /robot2/; a /fleet/ key stays one."""
    copies = []
    for name in ("robot1", "robot2"):
        node = py_trees.behaviours.Success(name="n")
        client = node.attach_blackboard_client(name=f"c{name}")
        client.register_key("patrol_waypoint", py_trees.common.Access.WRITE)
        client.register_key("/fleet/alarm", py_trees.common.Access.WRITE)
        namespace_tree(node, name)
        client.set("patrol_waypoint", name)
        client.set("/fleet/alarm", name)
        copies.append(client)
    storage = py_trees.blackboard.Blackboard.storage
    assert storage["/robot1/patrol_waypoint"] == "robot1"
    assert storage["/robot2/patrol_waypoint"] == "robot2"
    assert storage["/fleet/alarm"] == "robot2"
    assert copies[0].get("patrol_waypoint") == "robot1"


def test_the_loss_reason_is_the_failure_that_ended_the_robots_tree() -> None:
    """A Selector whose guard failed (absorbed) and whose patrol then failed: the patrol's reason."""
    guard = _Ends("guard", Status.FAILURE)
    patrol = _Ends("patrol", Status.FAILURE)
    patrol.result = Status.FAILURE
    selector = py_trees.composites.Selector("respond_or_patrol", memory=False, children=[guard, patrol])
    guard.fail = lambda reason: Leaf.fail(guard, "no new alarm")  # type: ignore[method-assign]
    patrol.fail = lambda reason: Leaf.fail(patrol, "robot lost")  # type: ignore[method-assign]
    view = FleetView(["robot1", "robot2"], lambda: 1.0)
    view.on_loss(lambda name, reason: True)
    root = FleetRoot([RobotScope("robot1", Running("leaf")), RobotScope("robot2", selector)], view)
    _tick(root)
    assert view.lost["robot2"]["reason"] == "robot lost"


def test_a_substituted_nodes_writes_follow_its_robots_namespace() -> None:
    """A stub's blackboard writes land under its copy's /robotN/ like the replaced node's would."""
    for name in ("robot1", "robot2"):
        stub = Stub("locate", status=Status.SUCCESS, writes={"search_candidate": {"label": name}})
        namespace_tree(stub, name)
        stub.tick_once()
        assert stub.status == Status.SUCCESS
    storage = py_trees.blackboard.Blackboard.storage
    assert storage["/robot1/search_candidate"] == {"label": "robot1"}
    assert storage["/robot2/search_candidate"] == {"label": "robot2"}
    assert "/search_candidate" not in storage
