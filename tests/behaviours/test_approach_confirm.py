"""The shared approach-and-confirm steps on the simulator, each a node: plan, drive, face, place, look."""

from __future__ import annotations

import math
import threading
from pathlib import Path
from typing import Any

import pytest
from test_search_leaves import RED, backpack, of, room, run

from missiontree.behaviours.approach_steps import DriveToStandoff, view_height
from missiontree.behaviours.background import Background
from missiontree.types import Pose2D, PoseStamped

BLUE = (4.0, 4.2)
APPROACH_CONFIRM = {"Include": {"file": "subtrees/approach_confirm.yaml",
                                "params": {"target": "red backpack"}}}
STEPS = ("plan_standoff", "drive", "face", "place_by_depth", "look_for", "confirm")


def look_confirm(frames: int = 3, max_distance: float = 0.0) -> dict[str, Any]:
    """LookFor then ConfirmTarget in a Retry of ``frames`` looks, as the subtree has them."""
    steps = [{"LookFor": {"name": "look_for", "target": "red backpack"}},
             {"ConfirmTarget": {"name": "confirm", "target": "red backpack", "max_distance": max_distance}}]
    return {"Retry": {"name": "confirm_looks", "attempts": frames,
                      "child": {"Sequence": {"name": "look_confirm", "memory": True, "children": steps}}}}


def approach(max_attempts: int = 3) -> dict[str, Any]:
    """The subtree's approach steps alone, in their Retry."""
    steps = [{"PlanStandoff": {"name": "plan_standoff"}}, {"DriveToStandoff": {"name": "drive"}},
             {"FaceTarget": {"name": "face"}}, {"PlaceByDepth": {"name": "place_by_depth"}}]
    return {"Retry": {"name": "approach", "attempts": max_attempts,
                      "child": {"Sequence": {"name": "approach_step", "memory": True, "children": steps}}}}


def nodes_that_ran(events: list[dict[str, Any]]) -> set[str]:
    """The last path element of every node whose status changed in the tick log."""
    return {c["node"].rsplit("/", 1)[-1] for e in of(events, "tick") for c in e.get("changed", [])}


def test_the_approach_steps_end_at_a_standoff_pose_facing_the_object(tmp_path: Path) -> None:
    """From 3 m off and turned away, plan/drive/face/place end within 1 m of the backpack and facing it."""
    world = room(tmp_path, (1.0, 1.0, math.pi), [backpack("red_bag", "red", RED)])
    candidate = {"id": "backpack_1", "label": "backpack", "colour": "red", "x": 3.7, "y": 2.2, "z": 0.2}
    status, events, final = run(tmp_path, world, approach(), blackboard={"search_candidate": candidate},
                                max_duration=120)
    assert status == "SUCCESS"
    assert math.hypot(RED[0] - final.x, RED[1] - final.y) < 1.0
    assert abs(math.degrees(final.bearing_to(*RED))) < 12.0
    assert of(events, "approach_step")


def test_a_decoy_of_the_same_class_in_another_colour_is_rejected_after_every_look(tmp_path: Path) -> None:
    """Facing a blue backpack, "red backpack" is not confirmed in 3 looks: FAILURE, rejected once."""
    world = room(tmp_path, (3.0, 2.5, 0.0), [backpack("blue_bag", "blue", RED)])
    candidate = {"id": "backpack_1", "label": "backpack", "colour": "unknown", "x": RED[0], "y": RED[1],
                 "z": 0.2}
    board = {"search_candidate": candidate, "looks": []}
    status, events, _ = run(tmp_path, world, look_confirm(), blackboard=board, max_duration=40)
    assert status == "FAILURE"
    rejected = of(events, "candidate_rejected")
    assert len(rejected) == 1 and rejected[0]["object"] == "backpack_1" and "blue" in rejected[0]["reason"]
    assert "in 3 frames" in rejected[0]["reason"]
    assert not of(events, "object_found")


def test_the_right_object_beside_a_decoy_is_confirmed_on_its_own_detection(tmp_path: Path) -> None:
    """The red backpack with a blue one in the same view: confirmed on the red one's detection."""
    bags = [backpack("red_bag", "red", RED), backpack("blue_bag", "blue", BLUE)]
    world = room(tmp_path, (3.0, 3.3, 0.0), bags)
    candidate = {"id": "backpack_1", "label": "backpack", "colour": "red", "x": RED[0], "y": RED[1], "z": 0.2}
    board = {"search_candidate": candidate, "looks": []}
    status, events, _ = run(tmp_path, world, look_confirm(), blackboard=board, max_duration=40)
    assert status == "SUCCESS"
    assert of(events, "object_found")[0]["id"] == "backpack_1"


def test_a_confirmed_object_farther_than_max_distance_is_rejected_at_once(tmp_path: Path) -> None:
    """The red backpack confirmed 1 m away with ``max_distance`` 0.5: rejected after that one look."""
    world = room(tmp_path, (3.0, 2.5, 0.0), [backpack("red_bag", "red", RED)])
    candidate = {"id": "backpack_1", "label": "backpack", "colour": "red", "x": RED[0], "y": RED[1], "z": 0.2}
    board = {"search_candidate": candidate, "looks": []}
    root = look_confirm(max_distance=0.5)
    status, events, _ = run(tmp_path, world, root, blackboard=board, max_duration=40)
    assert status == "FAILURE" and not of(events, "object_found")
    [rejected] = of(events, "candidate_rejected")
    assert "more than 0.5 m" in rejected["reason"] and "(in 1 frames)" in rejected["reason"]


def test_the_subtree_confirms_an_object_believed_beyond_where_it_is_each_step_a_node(tmp_path: Path) -> None:
    """A belief half a metre beyond the backpack: found, not rejected; every step shows in the tick log.

    The standoff pose must let the camera see the object's lower part: chosen for its centre, the
    robot stood so close to the real backpack that the detector saw a laptop and the right object
    was rejected.
    """
    world = room(tmp_path, (1.0, 2.5, 0.0), [backpack("red_bag", "red", RED)])
    candidate = {"id": "backpack_1", "label": "backpack", "colour": "red", "x": RED[0] + 0.5, "y": RED[1],
                 "z": 0.2, "height": 0.45}
    status, events, final = run(tmp_path, world, APPROACH_CONFIRM, blackboard={"search_candidate": candidate},
                                max_duration=120)
    assert status == "SUCCESS", [e.get("reason") for e in of(events, "candidate_rejected")]
    assert not of(events, "candidate_rejected")
    assert of(events, "object_found")[0]["id"] == "backpack_1"
    assert math.hypot(RED[0] - final.x, RED[1] - final.y) > 0.6
    assert set(STEPS) <= nodes_that_ran(events)


def test_a_candidate_whose_time_runs_out_on_the_way_is_given_up_as_unreached(tmp_path: Path) -> None:
    """A deadline passing while the robot drives: rejected once as unreached; the approach ends in time."""
    world = room(tmp_path, (1.0, 1.0, math.pi), [backpack("red_bag", "red", RED)])
    candidate = {"id": "backpack_1", "label": "backpack", "colour": "red", "x": 3.7, "y": 2.2, "z": 0.2,
                 "deadline": 3.0}
    status, events, _ = run(tmp_path, world, APPROACH_CONFIRM, blackboard={"search_candidate": candidate},
                            max_duration=120)
    assert status == "FAILURE"
    rejected = of(events, "candidate_rejected")
    assert len(rejected) == 1 and rejected[0]["kind"] == "unreached"
    assert "time ran out" in rejected[0]["reason"]
    assert max(e.get("t", 0.0) for e in events if "t" in e) < 10.0
    assert "look_for" not in nodes_that_ran(events)


def test_view_height_is_the_candidates_bottom() -> None:
    """The camera must see the lower quarter: centre less a quarter of the height, else half the centre."""
    assert view_height({"z": 0.2, "height": 0.4}) == pytest.approx(0.1)
    assert view_height({"z": 0.1, "height": 0.8}) == 0.0
    assert view_height({"z": 0.8}) == pytest.approx(0.4)
    assert view_height({"z": float("nan"), "height": 0.2}) == 0.0


def test_a_goal_aborted_short_counts_as_reached_only_within_reach_of_the_candidate() -> None:
    """Stopped just short of the standoff pose but beyond ``reach`` of the object: not reached.

    Counted as reached, the search once ended 1.05 m from a bottle (past what a search counts as
    reached); now another pose is tried.
    """
    leaf = DriveToStandoff("drive", DriveToStandoff.Params(reach=1.0))
    leaf.cand = {"id": "bottle_2", "label": "bottle", "x": 9.13, "y": 1.53}
    assert leaf.within_reach(PoseStamped(0.0, Pose2D(8.41, 2.36, 0.0))) is False  # 1.10 m away
    assert leaf.within_reach(PoseStamped(0.0, Pose2D(8.63, 2.12, 0.0))) is True   # 0.77 m away
    assert leaf.within_reach(None) is False


def test_a_background_job_is_awaited_only_when_asked_to() -> None:
    """With ``wait`` the first poll returns the result; without, a poll before the job ends says not done."""
    assert Background(lambda x: x + 1, 1, wait=True).poll() == (True, 2, "")
    release = threading.Event()
    job = Background(lambda: 7 if release.wait(timeout=30) else -1)
    assert job.poll() == (False, None, "")  # the job waits for the event: a poll never blocks
    release.set()
    job.wait = True
    assert job.poll() == (True, 7, "")
    done, result, error = Background(lambda: 1 / 0, wait=True).poll()
    assert done and result is None and "ZeroDivisionError" in error


@pytest.mark.parametrize("mission", ["find_object", "go_to_intent", "map_and_go_to_intent"])
def test_every_mission_that_approaches_an_object_has_each_step_as_a_node(mission: str) -> None:
    """The shipped trees that approach an object build the shared steps as nodes of their own."""
    from missiontree.engine.build import build_tree
    from missiontree.engine.loader import load_mission
    from missiontree.testing import fresh_plugins

    plugins = fresh_plugins()
    tree = Path(__file__).resolve().parents[2] / "trees" / f"{mission}.yaml"
    root = build_tree(load_mission(tree, plugins.nodes), plugins.nodes)
    names = {node.name for node in root.iterate()}
    assert set(STEPS) <= names


def test_a_place_looked_from_may_give_way_to_one_nearby_but_a_pose_not_reached_may_not(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """After a look, another range on the same side will do; after a pose not reached, it is too near."""
    from types import SimpleNamespace

    from missiontree.behaviours import approach_steps
    from missiontree.reasoning.intent import GraphObject

    goal, nearer = Pose2D(1.0, 1.0, 0.0), Pose2D(1.2, 1.0, 0.0)
    ranking = SimpleNamespace(candidates=[SimpleNamespace(goal=goal)], rejected=[])
    monkeypatch.setattr(approach_steps, "plan_candidates", lambda *a, **k: ranking)
    monkeypatch.setattr(approach_steps, "other_viewpoint", lambda *a, **k: nearer)
    obj = GraphObject("cup_1", "cup", xy=(2.0, 1.0))
    grid: Any = object()
    assert approach_steps.standoff_goal(obj, grid, goal, 0.17, None, [], (goal,)) == (nearer, "")
    assert approach_steps.standoff_goal(obj, grid, goal, 0.17, None, [goal])[0] is None


def test_a_candidate_looked_at_with_no_other_place_to_look_from_is_wrong_not_unreached(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Looked at without confirming it and no second place: rejected as wrong (doubted), saying why."""
    from missiontree.behaviours import approach_steps

    marked: list[tuple[str, str]] = []
    monkeypatch.setattr(approach_steps, "mark_rejected",
                        lambda leaf, cand, reason, kind="wrong": marked.append((kind, reason)))
    leaf = approach_steps.PlanStandoff("plan_standoff", approach_steps.PlanStandoff.Params())
    tries = [{"x": 1.0, "y": 1.0, "yaw": 0.0, "reached": True, "why": ""},
             {"x": 1.0, "y": 1.0, "yaw": 0.0, "reached": False, "why": "the detector sees no chair",
              "looked": True}]
    leaf.cand = {"id": "chair_3", "label": "chair", "x": 2.0, "y": 2.0}
    leaf.read = lambda port, default=None: tries if port == "tries" else default  # type: ignore[method-assign]
    leaf.write = lambda port, value: None  # type: ignore[method-assign]
    job = Background(lambda: (None, "no standoff pose"), wait=True)  # the search found no place
    leaf.job = job
    assert leaf.update().name == "FAILURE"
    assert marked == [("wrong", "the detector sees no chair; no other place to look at it from")]


def test_a_step_waits_for_a_fresh_frame_then_fails_late_recording_the_stop() -> None:
    """No frame yet: RUNNING; none past the frame timeout: FAILURE with the stop appended under the key."""
    from types import SimpleNamespace

    from missiontree.behaviours.confirm_steps import frame_or_wait
    from missiontree.behaviours.search_common import FRAME_TIMEOUT
    from missiontree.engine.leaf import Status

    clock = {"now": 1.0, "frame": None}
    written: dict[str, Any] = {}
    robot = SimpleNamespace(now=lambda: clock["now"], rgbd=lambda: clock["frame"])
    leaf = SimpleNamespace(context=SimpleNamespace(robot=robot), running=lambda _m: Status.RUNNING,
                           fail=lambda _m: Status.FAILURE, write=written.__setitem__)
    earlier = [{"why": "first look"}]
    assert frame_or_wait(leaf, 0.5, "looks", lambda: earlier) is Status.RUNNING  # type: ignore[arg-type]
    assert not written
    clock["now"] = 0.5 + FRAME_TIMEOUT + 0.1
    assert frame_or_wait(leaf, 0.5, "looks", lambda: earlier) is Status.FAILURE  # type: ignore[arg-type]
    assert written["looks"][0] == earlier[0] and "no camera frame" in written["looks"][1]["stop"]
    clock["frame"] = frame = SimpleNamespace(stamp=0.6)
    assert frame_or_wait(leaf, 0.5, "looks", lambda: earlier) is frame  # type: ignore[arg-type]
