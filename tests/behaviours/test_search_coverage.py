"""The search's view coverage: what the camera looked at, and going to look at the rest before 'not found'."""

from __future__ import annotations

import math

import numpy as np
from patrol_doubles import Events, FakeHandle, FakeRobot

from missiontree.behaviours.search_coverage import ViewCoverage, straight_lengths, view_goals
from missiontree.behaviours.search_locate import Locate
from missiontree.engine.context import MissionContext
from missiontree.engine.leaf import Status
from missiontree.reasoning.search_priors import Target
from missiontree.robot.actions import ActionStatus
from missiontree.types import CameraIntrinsics, OccupancyGrid, Pose2D, RGBDFrame, Tolerance

RES = 0.05
K = CameraIntrinsics(64, 48, 40.0, 40.0, 32.0, 24.0)  # about 77 degrees across


def hall(length: float = 9.0, width: float = 2.0) -> np.ndarray:
    """A closed hall ``length`` x ``width`` m, all of it known: walls round a free floor."""
    data = np.zeros((int(width / RES), int(length / RES)), np.int8)
    data[0, :] = data[-1, :] = 100
    data[:, 0] = data[:, -1] = 100
    return data


def grid_of(data: np.ndarray) -> OccupancyGrid:
    return OccupancyGrid(0.0, RES, Pose2D(0.0, 0.0), data)


class CameraRobot(FakeRobot):
    """A robot on a known map that reaches every goal at once and sends a frame from where it stands."""

    def __init__(self, data: np.ndarray, start: Pose2D) -> None:
        super().__init__()
        self.data = data
        self.set_pose(start)

    def occupancy(self) -> OccupancyGrid | None:  # type: ignore[override]
        return OccupancyGrid(self.time, RES, Pose2D(0.0, 0.0), self.data.copy())

    def rgbd(self) -> RGBDFrame | None:
        image = np.zeros((K.height, K.width, 3), np.uint8)
        return RGBDFrame(self.time, image, np.ones((K.height, K.width), np.float32), K, self.current)

    def navigate_to(self, goal: Pose2D, tolerance: Tolerance | None = None) -> FakeHandle:
        self.set_pose(goal)
        handle = FakeHandle(goal, tolerance, ActionStatus.SUCCEEDED, "", 1)
        self.goals.append(handle)
        return handle


class Detector:
    """Only its class list is read (the target phrase against the detector's classes)."""

    labels = ["backpack", "bottle"]


def test_the_camera_sees_up_to_the_first_wall_and_within_its_range() -> None:
    """Cells in the field of view up to view_range are seen; behind the robot and past a wall they are not."""
    data = hall()
    data[:, 60] = 100  # a wall across the hall at x = 3 m
    cov = ViewCoverage(view_range=4.0, cell=0.25)
    cov.add_view(grid_of(data), Pose2D(1.5, 1.0, 0.0), K.hfov)
    assert cov.key(2.5, 1.0) in cov.seen
    assert cov.key(3.0, 1.0) in cov.seen  # the wall itself
    assert cov.key(3.6, 1.0) not in cov.seen  # behind it
    assert cov.key(0.6, 1.0) not in cov.seen  # behind the camera


def test_view_goals_sweep_out_from_the_robot_and_end_when_all_is_seen() -> None:
    """Unseen floor behind the robot: look from here first; then farther on; none once all was seen."""
    grid = grid_of(hall())
    cov = ViewCoverage(view_range=3.0)
    cov.add_view(grid, Pose2D(1.0, 1.0, math.pi), K.hfov)  # looking at the west wall
    goals, _ = view_goals(cov, grid, (1.0, 1.0), straight_lengths, 0.17)
    assert goals and math.hypot(goals[0].x - 1.0, goals[0].y - 1.0) < 0.5
    for yaw in np.linspace(-math.pi, math.pi, 8, endpoint=False):  # a turn where it stands
        cov.add_view(grid, Pose2D(1.0, 1.0, float(yaw)), K.hfov)
    goals, _ = view_goals(cov, grid, (1.0, 1.0), straight_lengths, 0.17)
    assert goals and 2.5 < goals[0].x < 5.0
    for x in np.arange(0.5, 9.0, 1.0):
        for yaw in np.linspace(-math.pi, math.pi, 8, endpoint=False):
            cov.add_view(grid, Pose2D(float(x), 1.0, float(yaw)), K.hfov)
    goals, _ = view_goals(cov, grid, (1.0, 1.0), straight_lengths, 0.17)
    assert goals == []


def test_with_no_frontier_left_the_search_looks_at_the_unseen_floor_before_not_found() -> None:
    """A hall mapped whole, a metre of it seen by the camera: view goals first, then 'not found'."""
    robot = CameraRobot(hall(), Pose2D(1.0, 1.0, math.pi))
    events = Events()
    leaf = Locate("locate", Locate.Params(target="red backpack", priors="none"))
    models = {"detector": Detector()}
    leaf.setup(context=MissionContext(robot=robot, events=events, models=models))  # type: ignore[arg-type]
    for _ in range(3000):
        leaf.tick_once()
        if leaf.status in (Status.SUCCESS, Status.FAILURE):
            break
        robot.advance(0.1)
    assert leaf.status == Status.FAILURE
    assert events.of("search_view_goal"), "went nowhere to look"
    assert "not found" in leaf.feedback_message and "the camera looked at" in leaf.feedback_message
    covered = events.of("search_covered")[-1]
    assert covered["seen_m2"] >= 0.9 * covered["floor_m2"]


def test_a_cell_counts_as_seen_only_after_enough_frames() -> None:
    """With min_views 3, two frames leave the floor unseen and the third marks it seen."""
    grid = grid_of(hall())
    cov = ViewCoverage(view_range=3.0, min_views=3)
    for _ in range(2):
        cov.add_view(grid, Pose2D(1.0, 1.0, 0.0), K.hfov)
    assert cov.key(2.5, 1.0) not in cov.seen
    cov.add_view(grid, Pose2D(1.0, 1.0, 0.0), K.hfov)
    assert cov.key(2.5, 1.0) in cov.seen


def test_frontiers_that_appear_while_looking_are_explored_first() -> None:
    """A door opens onto unknown floor during the looks: the search goes back to exploring frontiers."""
    data = np.full((40, 240), -1, np.int8)
    data[:, :180] = hall()
    data[:, 180] = 100  # the hall's east wall at x = 9 m; unknown beyond

    class Opening(CameraRobot):
        def navigate_to(self, goal: Pose2D, tolerance: Tolerance | None = None) -> FakeHandle:
            self.data[10:30, 179:181] = 0  # a doorway onto the unknown
            return super().navigate_to(goal, tolerance)

    robot = Opening(data, Pose2D(1.0, 1.0, math.pi))
    events = Events()
    # the looks after the frontiers (view_window 0: no looking while exploring)
    leaf = Locate("locate", Locate.Params(target="red backpack", priors="none", view_window=0))
    models = {"detector": Detector()}
    leaf.setup(context=MissionContext(robot=robot, events=events, models=models))  # type: ignore[arg-type]
    for _ in range(3000):
        leaf.tick_once()
        if leaf.status in (Status.SUCCESS, Status.FAILURE) or events.of("explore_goal"):
            break
        robot.advance(0.1)
    assert events.of("search_view_goal") and events.of("search_frontiers_again")
    assert events.of("explore_goal"), leaf.feedback_message


def test_a_partial_exploration_goes_on_to_look_at_the_floor() -> None:
    """Explore ending 'partial:' (frontiers left that the map shows a way to) is not the search's failure."""

    class Partial(Locate):
        def explore_step(self) -> Status:
            return self.fail("partial: 1 frontier left unexplored though the map shows a way")

    robot = CameraRobot(hall(), Pose2D(1.0, 1.0, math.pi))
    events = Events()
    leaf = Partial("locate", Locate.Params(target="red backpack", priors="none"))
    models = {"detector": Detector()}
    leaf.setup(context=MissionContext(robot=robot, events=events, models=models))  # type: ignore[arg-type]
    leaf.tick_once()
    assert leaf.status == Status.RUNNING, leaf.feedback_message
    assert events.of("search_explored")[0]["reason"].startswith("partial:")
    assert events.of("search_view_goal")


def test_an_exploration_stuck_where_the_map_stopped_growing_goes_on_to_look() -> None:
    """Explore ending 'stuck:' does not spend a round of the search: the floor is looked at next."""

    class Stuck(Locate):
        def explore_step(self) -> Status:
            return self.fail("stuck: the map did not grow and the robot did not move for 60 s")

    robot = CameraRobot(hall(), Pose2D(1.0, 1.0, math.pi))
    events = Events()
    leaf = Stuck("locate", Locate.Params(target="red backpack", priors="none"))
    models = {"detector": Detector()}
    leaf.setup(context=MissionContext(robot=robot, events=events, models=models))  # type: ignore[arg-type]
    leaf.tick_once()
    assert leaf.status == Status.RUNNING, leaf.feedback_message
    assert events.of("search_view_goal")


def test_the_replan_period_grows_with_the_map_up_to_its_cap() -> None:
    """2 s on a small map; 10 s (the cap) on a million-cell map: choosing frontiers stays bounded."""
    models = {"detector": Detector()}
    periods = []
    for data in (hall(), np.zeros((1000, 1000), np.int8)):
        robot = CameraRobot(data, Pose2D(1.0, 1.0, 0.0))
        leaf = Locate("locate", Locate.Params(target="red backpack", priors="none"))
        leaf.setup(context=MissionContext(robot=robot, events=Events(), models=models))  # type: ignore[arg-type]
        leaf._scale_replan()
        periods.append(leaf.params.replan_period)
    assert periods == [2.0, 10.0]


def test_floor_beyond_a_gap_too_narrow_is_not_gone_to_through_unknown_cells() -> None:
    """Known floor behind a wall (a 0.2 m slit, a stretch of wall unmapped) is given up, not aimed at."""
    data = hall()
    data[:, 90] = 100  # a wall across at x = 4.5 m
    data[5:9, 90] = 0  # a slit 0.2 m wide: the lidar saw through it
    data[20:32, 90] = -1  # a stretch of the wall the lidar has not seen
    robot = CameraRobot(data, Pose2D(1.0, 1.0, math.pi))
    events = Events()
    leaf = Locate("locate", Locate.Params(target="red backpack", priors="none"))
    models = {"detector": Detector()}
    leaf.setup(context=MissionContext(robot=robot, events=events, models=models))  # type: ignore[arg-type]
    leaf.frontiers_done = True  # the unknown stretch is no frontier worth going to here
    for _ in range(3000):
        leaf.tick_once()
        if leaf.status in (Status.SUCCESS, Status.FAILURE):
            break
        robot.advance(0.1)
    assert leaf.status == Status.FAILURE
    assert events.of("search_view_goal")
    assert all(g["x"] < 4.5 for g in events.of("search_view_goal"))


def test_a_spent_time_budget_ends_the_search_not_found_with_what_was_left() -> None:
    """With a 5 s budget the search stops looking soon after 5 s and says the budget was spent."""
    robot = CameraRobot(hall(30.0, 2.0), Pose2D(1.0, 1.0, math.pi))
    events = Events()
    leaf = Locate("locate", Locate.Params(target="red backpack", priors="none", time_budget=5.0))
    models = {"detector": Detector()}
    leaf.setup(context=MissionContext(robot=robot, events=events, models=models))  # type: ignore[arg-type]
    for _ in range(3000):
        leaf.tick_once()
        if leaf.status in (Status.SUCCESS, Status.FAILURE):
            break
        robot.advance(0.1)
    assert leaf.status == Status.FAILURE
    assert robot.now() < 6.0
    assert "not found" in leaf.feedback_message and "time budget" in leaf.feedback_message


def test_a_spent_budget_offers_no_object_of_another_colour() -> None:
    """Out of time, a grey backpack seen in a few frames is not approached for a closer look at its colour."""
    leaf = Locate("locate", Locate.Params(target="red backpack", priors="none"))
    leaf.goal = Target("red backpack", "backpack", ("red",))
    leaf.exhausted = True
    entry = {"id": "b", "label": "backpack", "colour": "grey", "x": 1.0, "y": 1.0, "observations": 3}
    assert leaf._ranked(dict(entry), [], (0.0, 0.0), with_mismatch=True)[0] == 2
    leaf.budget_spent = True
    unreached = [{"id": "b", "label": "backpack", "x": 1.0, "y": 1.0, "kind": "unreached"}]
    assert leaf._ranked({**entry, "colour": "red"}, unreached, (0.0, 0.0), with_mismatch=False)[0] == -1


def _offer(leaf: Locate, robot: CameraRobot) -> Status:
    """Enter the leaf afresh (as the tree's Retry does) and tick it until it ends."""
    for _ in range(50):
        leaf.tick_once()
        if leaf.status in (Status.SUCCESS, Status.FAILURE):
            return leaf.status
        robot.advance(0.1)
    raise AssertionError(f"still {leaf.status.name}: {leaf.feedback_message}")


def test_the_search_says_not_found_once_max_candidates_were_offered_and_rejected() -> None:
    """Three red backpacks known, two offered at most: both rejected, the verdict is 'not found' saying so."""
    from missiontree.behaviours.search_common import mark_rejected
    from missiontree.reasoning.intent import GraphObject

    robot = CameraRobot(hall(), Pose2D(1.0, 1.0, 0.0))
    leaf = Locate("locate", Locate.Params(target="red backpack", priors="none", max_candidates=2))
    leaf.setup(context=MissionContext(robot=robot, events=Events(), models={"detector": Detector()}))  # type: ignore[arg-type]
    leaf.file_objects = [
        GraphObject(f"b{i}", "backpack", "a red backpack", xy=(2.0 + 2.0 * i, 1.0)) for i in range(3)
    ]
    for _ in range(2):
        assert _offer(leaf, robot) == Status.SUCCESS
        mark_rejected(leaf, dict(leaf.read("candidate")), "not it")
    assert _offer(leaf, robot) == Status.FAILURE
    assert leaf.feedback_message.startswith("not found") and "2 candidates" in leaf.feedback_message


def test_a_candidate_carries_the_deadline_of_its_approach() -> None:
    """With a time budget, the candidate says by when (robot s) its approach must have reached it."""
    from missiontree.reasoning.intent import GraphObject

    robot = CameraRobot(hall(), Pose2D(1.0, 1.0, 0.0))
    robot.advance(7.0)
    params = Locate.Params(target="red backpack", priors="none", time_budget=100.0, approach_time=30.0)
    leaf = Locate("locate", params)
    leaf.setup(context=MissionContext(robot=robot, events=Events(), models={"detector": Detector()}))  # type: ignore[arg-type]
    leaf.file_objects = [GraphObject("b", "backpack", "a red backpack", xy=(3.0, 1.0))]
    assert _offer(leaf, robot) == Status.SUCCESS
    assert leaf.read("candidate")["deadline"] == 137.0


class SlowRobot(CameraRobot):
    """A robot whose goals stay under way (it never arrives) and that sends no camera frame."""

    def rgbd(self) -> RGBDFrame | None:
        return None

    def navigate_to(self, goal: Pose2D, tolerance: Tolerance | None = None) -> FakeHandle:
        handle = FakeHandle(goal, tolerance, ActionStatus.SUCCEEDED, "", 10_000)
        self.goals.append(handle)
        return handle


def _east_open_corridor() -> np.ndarray:
    """A corridor closed to the west, known free from x = 0.5 to 4.5 m, unknown beyond to the east."""
    data = np.full((32, 160), -1, np.int8)
    data[:, 10:90] = 0
    data[0, 10:90] = data[-1, 10:90] = 100
    data[:, 10] = 100
    return data


def _reveal_east(data: np.ndarray) -> None:
    """The lidar maps the corridor's east end whole: no frontier is left."""
    data[:, 90:130] = 0
    data[0, 90:130] = data[-1, 90:130] = 100
    data[:, 130] = 100


def test_a_frontier_goal_the_lidar_mapped_is_kept_until_the_camera_looked_there() -> None:
    """The lidar maps the east end while the robot drives there: the goal stays until the camera saw it."""
    robot = SlowRobot(_east_open_corridor(), Pose2D(1.5, 0.8, 0.0))
    # no places to look from in the running: the tour would first look at the floor where it stands
    leaf = Locate("locate", Locate.Params(target="red backpack", priors="none", view_window=0.0))
    leaf.setup(context=MissionContext(robot=robot, events=Events(), models={"detector": Detector()}))  # type: ignore[arg-type]
    for _ in range(5):
        leaf.tick_once()
        robot.advance(0.1)
    assert len(robot.goals) == 1 and robot.goals[0].goal.x > 3.5
    goal = robot.goals[0]
    _reveal_east(robot.data)
    for _ in range(60):  # several re-plans
        leaf.tick_once()
        robot.advance(0.1)
    assert not goal.cancelled and robot.goals == [goal], "dropped before the camera looked there"
    assert leaf.coverage is not None
    grid = robot.occupancy()
    assert grid is not None
    for x in (3.0, 4.0, 5.0):  # the camera has now looked at the east end
        for yaw in np.linspace(-math.pi, math.pi, 8, endpoint=False):
            for _ in range(3):
                leaf.coverage.add_view(grid, Pose2D(x, 0.8, float(yaw)), K.hfov)
    for _ in range(60):
        leaf.tick_once()
        robot.advance(0.1)
    assert goal.cancelled


def test_a_goal_reached_or_failed_is_judged_by_the_lidar_alone() -> None:
    """The planner's hold answers only the re-plan's test (the blacklist's radius), not a reached goal's."""
    from missiontree.behaviours.search_resume import PriorPlanner

    grid = grid_of(hall())  # all known: no lidar frontier anywhere
    planner = PriorPlanner(lambda c: 0.0, 0.0)
    planner.held = lambda g, x, y: True
    planner.hold_active = True
    assert planner.still_frontier(grid, 4.0, 1.0, radius=planner.blacklist_radius)
    assert not planner.still_frontier(grid, 4.0, 1.0)  # a reached goal's and a failed try's test
    planner.hold_active = False
    assert not planner.still_frontier(grid, 4.0, 1.0, radius=planner.blacklist_radius)


def test_a_glimpse_of_the_targets_class_is_offered_for_a_closer_look() -> None:
    """A backpack seen a few times far off that did not become an object is a candidate to approach."""
    from missiontree.semantics.live import LiveScene

    robot = CameraRobot(hall(), Pose2D(1.0, 1.0, 0.0))
    scene = LiveScene(doubtful=[("bottle", 2.0, 1.0), ("backpack", 6.0, 1.2)])
    ctx = MissionContext(robot=robot, events=Events(), models={"detector": Detector()})  # type: ignore[arg-type]
    ctx.scene = scene
    leaf = Locate("locate", Locate.Params(target="red backpack", priors="none"))
    leaf.setup(context=ctx)
    assert _offer(leaf, robot) == Status.SUCCESS
    picked = leaf.read("candidate")
    assert (picked["label"], picked["source"], picked["x"]) == ("backpack", "glimpse", 6.0)


def test_exploring_again_after_the_looks_does_not_end_stuck_at_once() -> None:
    """Back to new frontiers after 100 s of looking, standing where exploring stopped: not 'stuck'."""
    data = np.full((40, 240), -1, np.int8)
    data[:, :180] = hall()
    data[10:30, 179:181] = 0  # a doorway onto the unknown east of the hall
    robot = SlowRobot(data, Pose2D(1.0, 1.0, 0.0))
    events = Events()
    leaf = Locate("locate", Locate.Params(target="red backpack", priors="none"))
    leaf.setup(context=MissionContext(robot=robot, events=events, models={"detector": Detector()}))  # type: ignore[arg-type]
    leaf.tick_once()
    assert leaf.handle is not None  # exploring: on the way to the door
    leaf.handle.cancel()  # as if exploring had ended here, and the looks had begun
    leaf.handle, leaf.state = None, "select"
    leaf.frontiers_done, leaf.frontiers_left, leaf.cover_state = True, [], "select"
    leaf.progress_area = 1e9  # the known area, as Explore last counted it, has not grown since
    robot.advance(100.0)  # the looks took 100 s; the robot is back where exploring stopped
    for _ in range(3):
        leaf.tick_once()
        robot.advance(0.1)
    assert events.of("search_frontiers_again")
    assert not [e for e in events.of("search_explored") if str(e["reason"]).startswith("stuck")]
    assert leaf.status == Status.RUNNING and leaf.handle is not None, leaf.feedback_message


def _corridor_open_both_ends() -> np.ndarray:
    """A corridor known free from x = 3 to 6 m, unknown beyond both ends (a frontier west and east)."""
    data = np.full((32, 180), -1, np.int8)
    data[:, 60:120] = 0
    data[0, 60:120] = data[-1, 60:120] = 100
    return data


def test_a_frontier_with_floor_the_camera_has_not_seen_near_it_ranks_first() -> None:
    """Two frontiers alike for the lidar: the one whose goal has unseen floor near it comes first."""
    from missiontree.behaviours.search_resume import PriorPlanner

    grid = grid_of(_corridor_open_both_ends())
    planner = PriorPlanner(lambda c: 0.0, 0.0)
    plain = planner.candidates(grid, (4.5, 0.8))
    assert {c.target[0] < 4.5 for c in plain} == {True, False}
    planner.camera_unseen = lambda g, x, y: 6.0 if x > 4.5 else 0.0
    ranked = planner.candidates(grid, (4.5, 0.8))
    assert ranked[0].target[0] > 4.5 and ranked[0].gain_m2 > max(c.gain_m2 for c in plain)


def test_places_to_look_from_compete_with_frontiers_but_not_in_reachability_checks() -> None:
    """A place to look from scoring best comes first; the map's reachability tests never see it."""
    from missiontree.behaviours.search_resume import PriorPlanner
    from missiontree.mapping.exploration import Candidate

    grid = grid_of(_corridor_open_both_ends())
    planner = PriorPlanner(lambda c: 0.0, 0.0)
    view = Candidate(4.0, 0.8, "view", 16, 8.0, 0.5, 100.0, (4.2, 0.8))
    planner.views = lambda g, xy: [view]
    assert planner.candidates(grid, (4.5, 0.8))[0] is view
    assert all(c.kind == "frontier" for c in planner.reach_candidates(grid, (4.5, 0.8)))


def test_the_goal_in_hand_is_not_left_for_a_farther_one() -> None:
    """A clearly better goal farther away does not replace the goal in hand; a nearer one does."""
    from missiontree.behaviours.search_resume import PriorPlanner
    from missiontree.mapping.exploration import Candidate

    planner = PriorPlanner(lambda c: 0.0, 0.0)
    current = Candidate(5.0, 0.0, "frontier", 10, 5.0, 5.0, 1.0, (5.5, 0.0))
    far = Candidate(14.0, 0.0, "frontier", 10, 50.0, 14.0, 3.0, (14.5, 0.0))
    near = Candidate(2.0, 0.0, "frontier", 10, 5.0, 2.0, 3.0, (2.5, 0.0))
    assert not planner.better(far, current)
    assert planner.better(near, current)


def test_a_place_to_look_from_is_dropped_once_its_floor_was_seen_on_the_way() -> None:
    """No frontier in a hall the camera has not seen: a view goal while exploring, left once seen."""
    robot = SlowRobot(hall(), Pose2D(1.0, 1.0, math.pi))
    events = Events()
    leaf = Locate("locate", Locate.Params(target="red backpack", priors="none"))
    leaf.setup(context=MissionContext(robot=robot, events=events, models={"detector": Detector()}))  # type: ignore[arg-type]
    leaf.tick_once()
    goals = events.of("explore_goal")
    assert goals and goals[0]["kind"] == "view", goals
    first = robot.goals[0]
    assert leaf.target is not None and leaf.coverage is not None
    tx, ty = leaf.target.target
    grid = robot.occupancy()
    assert grid is not None
    for yaw in np.linspace(-math.pi, math.pi, 8, endpoint=False):  # the camera saw it on the way
        for _ in range(3):
            leaf.coverage.add_view(grid, Pose2D(tx, ty, float(yaw)), K.hfov)
    for _ in range(30):
        leaf.tick_once()
        robot.advance(0.1)
    assert first.cancelled and len(robot.goals) > 1


def test_a_place_to_look_from_not_reached_gives_its_floor_up_without_a_blacklist() -> None:
    """An aborted view goal: the floor near it is given up, no exploration place is blacklisted."""

    class Refusing(SlowRobot):
        def navigate_to(self, goal: Pose2D, tolerance: Tolerance | None = None) -> FakeHandle:
            handle = FakeHandle(goal, tolerance, ActionStatus.ABORTED, "no path", 1)
            self.goals.append(handle)
            return handle

    robot = Refusing(hall(), Pose2D(1.0, 1.0, math.pi))
    events = Events()
    leaf = Locate("locate", Locate.Params(target="red backpack", priors="none"))
    leaf.setup(context=MissionContext(robot=robot, events=events, models={"detector": Detector()}))  # type: ignore[arg-type]
    for _ in range(3):
        leaf.tick_once()
        robot.advance(0.1)
    assert events.of("search_view_given_up")
    assert leaf.planner is not None and not leaf.planner.blacklist
    assert leaf.coverage is not None and leaf.coverage.skipped


def test_reset_progress_restarts_the_stuck_timer() -> None:
    """After reset_progress, an old progress time no longer ends the next step 'stuck'."""
    robot = SlowRobot(hall(), Pose2D(1.0, 1.0, 0.0))
    leaf = Locate("locate", Locate.Params(target="red backpack", priors="none", stuck_timeout=10.0))
    leaf.setup(context=MissionContext(robot=robot, events=Events(), models={"detector": Detector()}))  # type: ignore[arg-type]
    grid = robot.occupancy()
    assert grid is not None
    pose = Pose2D(1.0, 1.0, 0.0)
    leaf.progress_xy, leaf.progress_at, leaf.progress_area, leaf.area_at = (1.0, 1.0), 0.0, 1e9, 0.0
    assert leaf._stuck(100.0, grid, pose)
    leaf.reset_progress(100.0, pose)
    assert not leaf._stuck(100.5, grid, pose)


def test_the_floor_near_the_robot_is_labelled_in_a_window_and_the_whole_floor_kept() -> None:
    """floor(radius=) holds only cells near the robot; the whole floor of one grid is labelled once."""
    grid = grid_of(hall())
    cov = ViewCoverage(view_range=2.5)
    near = cov.floor(grid, (1.0, 1.0), radius=1.0)
    assert near and all(abs((k[0] + 0.5) * cov.cell - 1.0) <= 1.3 for k in near)
    whole = cov.floor(grid, (1.0, 1.0))
    assert len(whole) > len(near)
    calls = []
    cov._floor_cells = lambda g, xy: calls.append(1) or set()  # type: ignore[method-assign,assignment,func-returns-value]
    assert cov.floor(grid, (1.0, 1.0)) is whole and not calls


def test_exploration_json_lists_frontiers_left_not_places_to_look_from() -> None:
    """A search stopped with only unseen floor near it: no 'frontier left' is reported for it."""
    from missiontree.behaviours.explore_report import exploration_report

    robot = SlowRobot(hall(), Pose2D(1.0, 1.0, math.pi))
    leaf = Locate("locate", Locate.Params(target="red backpack", priors="none"))
    leaf.setup(context=MissionContext(robot=robot, events=Events(), models={"detector": Detector()}))  # type: ignore[arg-type]
    leaf.tick_once()
    assert leaf.target is not None and leaf.target.kind == "view"
    grid = robot.occupancy()
    assert grid is not None
    report = exploration_report(leaf.planner, "stopped", 1, grid, None, (1.0, 1.0))
    assert report["frontiers_left"] == []


def test_view_goals_are_toured_near_corner_first_not_far_side_first() -> None:
    """The tour takes the near pair of places before the far one that scores best one step ahead."""
    from missiontree.behaviours.search_coverage import ViewGoal, tour_view_goals

    g = OccupancyGrid(0.0, 0.1, Pose2D(0.0, 0.0), np.zeros((100, 100), np.int8))
    far = ViewGoal(2.0, 5.0, (2.0, 5.0), 6.0, 3.0, 6.0 / 1.45)
    a = ViewGoal(8.0, 5.0, (8.0, 5.0), 5.0, 3.0, 5.0 / 1.45)
    b = ViewGoal(8.0, 6.0, (8.0, 6.0), 5.0, 3.2, 5.0 / 1.48)
    assert tour_view_goals(g, [far, a, b]) == [a, b, far]
