"""Where to look next in the search: ResumeExplore (exploration kept across rounds) and Locate (a candidate).

- :class:`ResumeExplore`: the ``Explore`` leaf kept across the rounds of a search (visited goals and
  blacklist survive a retry); it may stop after each goal reached (the report's MOVING_TO_SCAN: one
  scan point at a time) and fail "not found" once nothing is left. A goal given up on a half-learned
  map (a doorway judged blocked while its jambs were still unknown) is offered once more when the map
  around it has grown since, or the map now places its frontier's goal elsewhere.
- :class:`Locate`: a candidate of the target from what is known — the live semantic map that
  ``BuildSceneGraph`` fuses every frame into (a candidate seen once is not forgotten when the robot
  turns away) or a loaded scene graph — else exploration ordered by where the target is likely
  (:mod:`missiontree.reasoning.search_priors`: a cup -> kitchen first) and by the frontiers' gain,
  until a candidate appears; then, once no frontier is left (or the exploration ended partial), it
  goes to look at the reachable floor the camera has not had in view
  (:mod:`~missiontree.behaviours.search_coverage`), back to frontiers that appear meanwhile. A
  candidate that could not be reached is offered once more when nothing is left to explore or look
  at. FAILURE "not found" when the reachable space is explored and looked at and no candidate is left.

Both use ``Explore`` through its public interface only (``make_planner``, ``select_goal``, the
``on_goal_reached`` / ``on_give_up`` hooks, ``summary``).

Tick-log events: ``search_candidate``, ``search_explored``, ``search_view_goal``,
``search_view_given_up``, ``search_covered``, ``search_frontiers_again``, ``search_priors`` (whose
ranking of the rooms is used: the language model's, or the offline table's and why), ``explore_retry``
(and Explore's).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Annotated, Any, Literal

import cv2
import numpy as np
from pydantic import BaseModel, Field

from missiontree.behaviours.explore import Explore
from missiontree.behaviours.intent import find_scene_graph
from missiontree.behaviours.search_common import REJECT_RADIUS, read_target, rejected_entries
from missiontree.behaviours.search_coverage import ViewCoverage, ViewGoal, known_path_lengths, view_goals
from missiontree.engine.leaf import Status
from missiontree.engine.ports import Output
from missiontree.errors import MissionTreeError
from missiontree.mapping.exploration import Blacklisted, ExplorationPlanner
from missiontree.mapping.exploration import Candidate as Frontier
from missiontree.mapping.grid import free_mask, occupied_mask, unknown_mask
from missiontree.perception.colour import canonical_colour
from missiontree.reasoning.calls import CallStatus, ModelCall, model_caller
from missiontree.reasoning.intent import GraphObject, graph_objects
from missiontree.reasoning.phrases import fold_label
from missiontree.reasoning.search_priors import (
    RoomRanking,
    Target,
    priors_from_ranking,
    region_score,
    room_priors,
    room_ranking_messages,
    room_types,
)
from missiontree.robot.actions import ActionHandle, ActionStatus
from missiontree.types import OccupancyGrid, Pose2D, Tolerance, wrap_angle

#: Known area (m^2) counted around a goal given up, to tell whether the map there has grown since.
AROUND_M = 1.5
#: A retried goal's new place must lie this far (m) from the one given up, when the map did not grow.
MOVED_M = 0.1
#: How far (m) a frontier goal too near an obstacle may be moved to give the robot room.
NUDGE_M = 0.6
#: Times the search goes back from looking at the floor to exploring frontiers that appeared meanwhile.
MAX_FRONTIER_ROUNDS = 5
#: After a full turn at a view goal, floor still unseen within this share of the view range is hidden
#: from there (behind furniture) and given up; farther floor is left for a later goal.
HIDDEN_WITHIN = 0.8
#: An instance whose colour the semantic map's majority vote settled over this many frames is not
#: looked at closer for another colour (when nothing else is left, ones seen in fewer frames are).
TRUSTED_COLOUR_FRAMES = 10


class PriorPlanner(ExplorationPlanner):
    """Exploration candidates re-scored by where the target is likely: score x (1 + weight x prior).

    A frontier goal nearer an obstacle than the robot's radius plus margin (on a half-learned map a
    doorway's goal often lands beside a jamb seen later; the navigation stack refuses such a goal)
    is moved to the nearest known-free cell within :data:`NUDGE_M` that has that room.
    """

    def __init__(self, bias: Any, weight: float, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.bias = bias
        self.weight = weight

    def candidates(
        self, grid: Any, robot_xy: tuple[float, float], *args: Any, **kwargs: Any
    ) -> list[Frontier]:
        """The planner's candidates (goals given room), best first after the prior (options passed on)."""
        found = super().candidates(grid, robot_xy, *args, **kwargs)
        if not found:
            return found
        room = self.footprint_radius + self.goal_margin
        clear = clearance_map(grid)
        found = [_with_room(c, grid, clear, room) for c in found]
        if self.weight <= 0:
            return found
        scored = [replace(c, score=c.score * (1.0 + self.weight * self.bias(c))) for c in found]
        return sorted(scored, key=lambda c: -c.score)


def clearance_map(grid: OccupancyGrid) -> np.ndarray:
    """Distance (m) of every cell to the nearest occupied cell."""
    occupied = occupied_mask(grid)
    return cv2.distanceTransform((~occupied).astype(np.uint8), cv2.DIST_L2, 5) * grid.resolution


def clearance_at(grid: OccupancyGrid, clear: np.ndarray, x: float, y: float) -> float:
    """Distance (m) from (x, y) to the nearest occupied cell (inf off the map)."""
    r, c = grid.world_to_cell(x, y)
    h, w = clear.shape
    return float(clear[r, c]) if 0 <= r < h and 0 <= c < w else math.inf


def _with_room(c: Frontier, grid: OccupancyGrid, clear: np.ndarray, room: float) -> Frontier:
    """``c`` with its goal moved to the nearest free cell within NUDGE_M that keeps ``room`` (m)."""
    if c.kind != "frontier" or clearance_at(grid, clear, c.x, c.y) >= room:
        return c
    res = grid.resolution
    r0, c0 = grid.world_to_cell(c.x, c.y)
    k = int(math.ceil(NUDGE_M / res))
    h, w = clear.shape
    rs, re_, cs, ce = max(0, r0 - k), min(h, r0 + k + 1), max(0, c0 - k), min(w, c0 + k + 1)
    if rs >= re_ or cs >= ce:
        return c
    free = free_mask(grid)[rs:re_, cs:ce]
    rr, cc = np.nonzero(free & (clear[rs:re_, cs:ce] >= room))
    if not len(rr):
        return c
    d2 = (rr + rs - r0) ** 2 + (cc + cs - c0) ** 2
    j = int(np.argmin(d2))
    if d2[j] > k * k:
        return c
    x, y = grid.cell_to_world(int(rr[j] + rs), int(cc[j] + cs))
    return replace(c, x=float(x), y=float(y))


@dataclass
class _GivenUp:
    """A goal given up: the known area around it then, and whether it was offered again already."""

    entry: Blacklisted
    known_m2: float
    retried: bool = False


class ResumeExplore(Explore):
    """Explore that resumes where it left off when entered again, and may stop after each goal reached.

    Keeps its visited goals and blacklist across runs of the leaf (a tree that retries does not
    revisit what it saw). With ``max_goals`` it ends SUCCESS after reaching that many goals (the
    report's MOVING_TO_SCAN: one scan point at a time). With ``exhausted_fails`` it ends FAILURE
    "not found" once nothing is left to explore, at once on every later entry. With ``retry_grown``,
    when nothing else is left, a goal given up is offered once more if the known map within
    1.5 m of it grew by ``retry_growth`` m^2 since, or the map now puts its frontier's goal where
    the robot has more room than where it failed: a doorway's goal beside a jamb seen late.
    """

    class Params(Explore.Params):
        max_goals: int = Field(
            0, ge=0, description="End SUCCESS after reaching this many goals (0: explore all)."
        )
        exhausted_fails: bool = Field(False, description="Nothing left to explore is FAILURE 'not found'.")
        retry_grown: bool = Field(
            True,
            description="Once nothing else is left, offer a goal given up once more when the map "
            "around it grew or now places its goal elsewhere.",
        )
        retry_growth: float = Field(
            2.5,
            ge=0,
            description="Growth of the known area within 1.5 m of a goal given up (m^2; a third of "
            "that disc) that offers it once more.",
        )
        second_chances: int = Field(
            0,
            ge=0,
            description="Times every goal given up is tried again once nothing else is left, "
            "whatever the map shows (costs time when the target is absent).",
        )
        # the search's defaults (Explore's: 0.5 m and 1.0 m^2)
        scan_point_erosion: float = Field(
            0.4, ge=0, description="Scan point erosion (m); over half a door's width cuts rooms apart."
        )
        min_gain: float = Field(
            0.5, ge=0, description="strategy gain: skip frontiers revealing less unknown area (m^2)."
        )

    params: Params

    def __init__(self, name: str, params: BaseModel | None = None) -> None:
        super().__init__(name, params)
        self.kept: ExplorationPlanner | None = None
        self.exhausted = False
        self.reached = 0
        self.chances_used = 0
        self.given_up: list[_GivenUp] = []

    def make_planner(self) -> ExplorationPlanner:
        """The planner kept for the whole mission (made once by :meth:`new_planner`)."""
        if self.kept is None:
            self.kept = self.new_planner()
        return self.kept

    def new_planner(self) -> ExplorationPlanner:
        """A planner for the mission (subclasses rank its goals)."""
        return ExplorationPlanner(**self.planner_options())

    def initialise(self) -> None:
        """Explore on with what earlier runs of this leaf learned (blacklist, visited goals)."""
        super().initialise()
        self.reached = 0

    def on_goal_reached(self, goal: Frontier) -> None:
        """Count the goals reached in this run of the leaf."""
        self.reached += 1

    def on_give_up(self, goal: Frontier, reason: str) -> None:
        """Remember the known area around the goal given up (to tell later whether the map grew)."""
        if self.planner is None or not self.planner.blacklist:
            return
        entry = self.planner.blacklist[-1]
        grid = self.last_grid
        self.given_up.append(_GivenUp(entry, _known_around(grid, entry) if grid is not None else 0.0))

    def explore_step(self) -> Status:
        """One step of exploration (Explore's update); sets ``exhausted`` when nothing is left."""
        status = super().update()
        if status == Status.SUCCESS and not (self.params.max_goals and self.reached >= self.params.max_goals):
            self.exhausted = True
        return status

    def update(self) -> Status:
        """One step of exploration; SUCCESS after ``max_goals`` goals; exhausted -> FAILURE when asked."""
        if self.exhausted and self.params.exhausted_fails:
            return self.fail(f"not found: nothing left to explore ({self.feedback_message})")
        status = self.explore_step()
        if status == Status.SUCCESS and self.exhausted and self.params.exhausted_fails:
            return self.fail(f"not found: {self.feedback_message}")
        return status

    def select_goal(self, now: float, grid: OccupancyGrid, pose: Pose2D) -> Status:
        """Choose the next goal, unless ``max_goals`` goals were reached in this run of the leaf.

        When nothing is left but goals given up, those whose surroundings changed are offered once
        more (``retry_grown``); then all of them get ``second_chances``.
        """
        if self.params.max_goals and self.reached >= self.params.max_goals:
            return self.succeed(f"reached {self.reached} goal{'s' if self.reached > 1 else ''}")
        status = super().select_goal(now, grid, pose)
        planner = self.planner
        if status != Status.SUCCESS or planner is None or not planner.blacklist:
            return status
        if self.params.retry_grown:
            again = self._changed_since_given_up(grid, pose)
            if again:
                self.emit(
                    "explore_retry",
                    goals=[{"x": round(g.entry.x, 3), "y": round(g.entry.y, 3)} for g in again],
                    reasons=[g.entry.reason for g in again],
                )
                for g in again:
                    g.retried = True
                    planner.blacklist.remove(g.entry)
                retried = super().select_goal(now, grid, pose)
                if retried != Status.SUCCESS:
                    return retried
        if self.chances_used < self.params.second_chances:
            self.chances_used += 1
            self.emit("explore_second_chance", goals=len(planner.blacklist))
            planner.blacklist.clear()
            return super().select_goal(now, grid, pose)
        return status

    def _changed_since_given_up(self, grid: OccupancyGrid, pose: Pose2D) -> list[_GivenUp]:
        """Goals given up, not retried yet, whose surroundings grew or whose frontier's goal moved."""
        assert self.planner is not None
        planner = self.planner
        # a place given up again after its retry stays given up
        done = [g.entry for g in self.given_up if g.retried]
        open_ = [
            g
            for g in self.given_up
            if not g.retried and g.entry in planner.blacklist and not any(_near(g.entry, d) for d in done)
        ]
        if not open_:
            return []
        grown = [g for g in open_ if _known_around(grid, g.entry) - g.known_m2 >= self.params.retry_growth]
        rest = [g for g in open_ if g not in grown]
        if not rest:
            return grown
        kept = list(planner.blacklist)
        planner.blacklist[:] = [b for b in kept if all(b is not g.entry for g in rest)]
        try:
            offered = planner.candidates(grid, (pose.x, pose.y))
        finally:
            planner.blacklist[:] = kept
        r = planner.blacklist_radius
        room = planner.footprint_radius + planner.goal_margin
        clear = clearance_map(grid)
        moved = []
        for g in rest:
            b = g.entry
            before = clearance_at(grid, clear, b.x, b.y)
            for c in offered:
                same = math.dist(c.target, b.target) <= r if math.isfinite(b.target[0]) else False
                if not (same or math.dist((c.x, c.y), (b.x, b.y)) <= r):
                    continue
                shift = math.dist((c.x, c.y), (b.x, b.y))
                now = clearance_at(grid, clear, c.x, c.y)
                # the map now places its goal where the robot has more room than where it failed
                if now >= room and now > before + 0.01 and shift >= MOVED_M:
                    moved.append(g)
                    break
        return grown + moved


def _near(a: Blacklisted, b: Blacklisted, radius: float = 0.75) -> bool:
    return math.dist((a.x, a.y), (b.x, b.y)) <= radius


def _known_around(grid: OccupancyGrid, entry: Blacklisted, radius: float = AROUND_M) -> float:
    """Known area (m^2) within ``radius`` of a goal given up and of the frontier place it was to see."""
    res = grid.resolution
    h, w = grid.data.shape
    known = ~unknown_mask(grid)
    total = 0.0
    places = [(entry.x, entry.y)]
    if math.isfinite(entry.target[0]) and math.dist(entry.target, (entry.x, entry.y)) > radius:
        places.append(entry.target)
    k = int(math.ceil(radius / res))
    for x, y in places:
        r0, c0 = grid.world_to_cell(x, y)
        rs, re_, cs, ce = max(0, r0 - k), min(h, r0 + k + 1), max(0, c0 - k), min(w, c0 + k + 1)
        if rs >= re_ or cs >= ce:
            continue
        rr, cc = np.mgrid[rs:re_, cs:ce]
        disc = (rr - r0) ** 2 + (cc - c0) ** 2 <= k * k
        total += float(np.count_nonzero(known[rs:re_, cs:ce] & disc)) * res * res
    return total


class Locate(ResumeExplore):
    """A candidate of the target: from the semantic map or a loaded graph, else explore where it is likely.

    SUCCESS with ``search_candidate`` written as soon as an object of the target's class that was
    not rejected is known (colour matches first, then colour unknown). Otherwise explores (frontiers
    by gain, weighted by the room priors) until one is seen. When nothing is left to explore, a
    candidate rejected only because it could not be reached is offered once more (the map has grown
    since), and objects of the class whose other colour rests on fewer than
    :data:`TRUSTED_COLOUR_FRAMES` frames are looked at; FAILURE "not found" when none is left.
    """

    class Params(ResumeExplore.Params):
        target: str = Field(description="What to find: colour words and a class ('red backpack').")
        scene_graph: str = Field(
            "", description="A scene graph file (NAIS JSON) whose objects are checked first."
        )
        priors: Literal["offline", "model", "none"] = Field(
            "offline",
            description="Rank frontiers by where the target is likely: the offline stand-in's table, "
            "the language model of `priors_role` (the table until it answers, and when it fails or "
            "answers out of place), or not at all.",
        )
        priors_role: str = Field("llm", description="priors: model -- the language model role asked.")
        prior_weight: float = Field(
            2.0, ge=0, description="How much the prior multiplies a frontier's score."
        )
        view_coverage: bool = Field(
            True,
            description="Once no frontier is left, go and look at the reachable floor the camera has "
            "not had within view_range (the lidar maps a large floor long before the camera saw it).",
        )
        view_range: float = Field(
            2.5,
            gt=0,
            description="Range (m) within which the camera counts as having looked at the floor: the "
            "shipped detector finds bottles and umbrellas reliably to about 2-2.5 m, backpacks beyond 4 m.",
        )
        view_frames: int = Field(
            3, ge=1, description="Frames that must have had a floor cell in view for it to count as seen."
        )
        view_min_area: float = Field(
            0.75, ge=0, description="Unseen patches of floor smaller than this are not gone to (m^2)."
        )
        view_timeout: float = Field(
            20.0,
            gt=0,
            description="Give up a place to look from the robot got no closer to for this long (s).",
        )
        look_speed: float = Field(1.0, gt=0, description="Turn rate of the look at a view goal (rad/s).")
        replan_cells: int = Field(
            100_000,
            ge=1,
            description="The re-plan period while driving (replan_period) grows with the map beyond this "
            "many cells, up to max_replan_period: choosing frontiers costs about the map's size (7 s a "
            "choice on a 1.7 M-cell warehouse map), so its cost per simulated second stays bounded.",
        )
        max_replan_period: float = Field(
            10.0, gt=0, description="Longest re-plan period on a large map (s)."
        )
        time_budget: float = Field(
            0.0,
            ge=0,
            description="Robot seconds from the leaf's first start after which it explores and looks no "
            "more: the candidates known are still offered, then 'not found' names the floor left unseen "
            "(a mission's time limit otherwise ends an absent target's search with no verdict); 0: none.",
        )
        rejected: Annotated[
            str, Output("candidates rejected so far (emptied when the mission starts)", type="list")
        ] = "search_rejected"
        candidate: Annotated[str, Output("the candidate to approach", type="dict")] = "search_candidate"

    params: Params

    def __init__(self, name: str, params: BaseModel | None = None) -> None:
        super().__init__(name, params)
        self.goal: Target | None = None
        self.file_objects: list[GraphObject] = []
        self.priors: dict[str, float] = {}
        self.priors_source = "offline"
        self.prior_call: ModelCall | None = None
        self.asked = False
        self.offered_again: set[str] = set()
        self.coverage: ViewCoverage | None = None
        self.last_view = -math.inf
        self.frontiers_done = False
        self.cover_state = "select"
        self.cover_goal: ViewGoal | None = None
        self.cover_handle: ActionHandle | None = None
        self.cover_best = math.inf
        self.cover_best_at = 0.0
        self.look_turned = 0.0
        self.look_yaw = 0.0
        self.look_started = 0.0
        self.cover_goals = 0
        self.cover_skipped = 0
        self.frontier_rounds = 0
        self.explore_end = ""
        self.base_replan: float | None = None
        self.first_start: float | None = None
        self.budget_spent = False
        self.frontiers_left: list[tuple[float, float]] = []

    def on_setup(self) -> None:
        """Read the target against the detector's classes and load the graph file, if any."""
        # py_trees' blackboard outlives a mission in the same process (batch runs, benchmarks): the
        # rejected candidates start empty with each mission, never inherited from another one.
        self.write("rejected", [])
        self.coverage = ViewCoverage(self.params.view_range, min_views=self.params.view_frames)
        if self.ctx is None:
            return
        self.goal = read_target(self.ctx, self.params.target)
        self.priors = room_priors(self.goal.label) if self.params.priors != "none" else {}
        if self.params.scene_graph:
            from missiontree.semantics.scene_graph import SceneGraph

            graph = SceneGraph.load(find_scene_graph(self.params.scene_graph))
            self.file_objects = list(graph_objects(graph).objects.values())

    def new_planner(self) -> ExplorationPlanner:
        """Frontiers by gain, their scores weighted by the room priors."""
        return PriorPlanner(self._prior, self.params.prior_weight, **self.planner_options())

    def initialise(self) -> None:
        """Explore on; with ``priors: model`` the language model is asked once a mission (no waiting)."""
        super().initialise()
        if self.params.priors == "model" and not self.asked and self.goal is not None:
            self.asked = True
            messages = room_ranking_messages(self.goal.text, room_types())
            try:
                self.prior_call = model_caller(self.context).chat(
                    self.params.priors_role, messages, RoomRanking, node=self.name
                )
            except MissionTreeError as error:  # no such role: the stand-in's table it is
                self._priors_fallback(str(error))

    def terminate(self, new_status: Status) -> None:
        """Stop exploring; halted, cancel a ranking still in flight (kept across rounds otherwise)."""
        if self.prior_call is not None and new_status == Status.INVALID:
            self.prior_call.cancel()
            self.prior_call = None
            self._priors_fallback("the search moved on before the language model answered")
        if self.cover_handle is not None:
            self.cover_handle.cancel()
            self.cover_handle = None
        if self.cover_state == "look" and self.ctx is not None:
            self.ctx.robot.drive(0.0, 0.0)
        self.cover_state = "select"
        super().terminate(new_status)

    def _poll_priors(self) -> None:
        """Take the language model's ranking when it has come (or keep the stand-in's table)."""
        call = self.prior_call
        if call is None or not call.status().done:
            return
        self.prior_call = None
        if call.status() is not CallStatus.SUCCEEDED:
            self._priors_fallback(call.error() or call.status().value)
            return
        try:
            priors = priors_from_ranking(call.result().value, room_types())
        except ValueError as error:
            self._priors_fallback(str(error))
            return
        self.priors, self.priors_source = priors, "model"
        self.emit("search_priors", source="model", role=self.params.priors_role, priors=priors)

    def _priors_fallback(self, reason: str) -> None:
        self.priors_source = "offline"
        self.emit(
            "search_priors",
            source="offline",
            role=self.params.priors_role,
            reason=reason[:300],
            priors=self.priors,
        )

    def update(self) -> Status:
        """A known candidate ends the leaf; else one step of exploration, then of looking at the floor."""
        self._poll_priors()
        self._view()
        # once the time budget is spent, only candidates that may be the target by their colour
        found = self._pick(with_mismatch=self.exhausted and not self.budget_spent)
        if found is not None:
            return self._found(found)
        if self.exhausted:
            return self._not_found()
        if self._out_of_time():
            return self._exhausted()
        if not self.frontiers_done:
            self._scale_replan()
            status = self.explore_step()
            # a partial exploration (frontiers the map shows a way to were left) or one stuck where
            # the map stopped growing goes on to look at the floor like a complete one (a round of
            # the search is not spent on it); what was left is named in the not-found reason
            partial = status == Status.FAILURE and str(self.failure_reason).startswith(("partial:", "stuck:"))
            if status == Status.FAILURE and not partial:
                return self.fail(
                    f"searching for the {self.goal.text if self.goal else '?'}: {self.failure_reason}"
                )
            if status != Status.SUCCESS and not partial:
                return status
            self.frontiers_done = True
            self.exhausted = False
            self.frontiers_left = self._frontier_places()  # new ones only bring exploring back
            self.explore_end = self.failure_reason if partial else self.feedback_message
            self.failure_reason = ""
            self.emit("search_explored", reason=self.explore_end)
            if not self.params.view_coverage:
                return self._exhausted()
        status = self._cover()
        if status == Status.SUCCESS:
            return self._exhausted()
        return status

    def _out_of_time(self) -> bool:
        """Whether the time budget is spent (then exploring and looking stop; noted for the reason)."""
        budget = self.params.time_budget
        now = self.context.robot.now()
        if self.first_start is None:
            self.first_start = now
        if not budget or now - self.first_start < budget:
            return False
        if not self.budget_spent:
            self.budget_spent = True
            if self.handle is not None:
                self.handle.cancel()
                self.handle = None
            if self.cover_handle is not None:
                self.cover_handle.cancel()
                self.cover_handle = None
            if self.cover_state == "look":
                self.context.robot.drive(0.0, 0.0)
            self.cover_state = "select"
            self.emit("search_time_budget", budget_s=budget)
        return True

    def _scale_replan(self) -> None:
        """Re-plan less often on a large map (replan_period x cells / replan_cells, capped)."""
        grid = self.last_grid if self.last_grid is not None else self.context.robot.occupancy()
        if grid is None:
            return
        if self.base_replan is None:
            self.base_replan = self.params.replan_period
        scale = max(1.0, grid.data.size / self.params.replan_cells)
        period = min(max(self.base_replan, self.params.max_replan_period), self.base_replan * scale)
        if period != self.params.replan_period:
            self.params = self.params.model_copy(update={"replan_period": period})

    def _frontier_places(self, known: list[tuple[float, float]] | None = None) -> list[tuple[float, float]]:
        """The frontiers the planner offers now (their places), less those within 1 m of ``known``."""
        robot = self.context.robot
        grid, stamped = robot.occupancy(), robot.pose()
        if self.planner is None or grid is None or stamped is None:
            return []
        places = [c.target for c in self.planner.candidates(grid, (stamped.pose.x, stamped.pose.y))]
        return [p for p in places if all(math.dist(p, k) > 1.0 for k in known or [])]

    def _exhausted(self) -> Status:
        """Nothing left to explore or look at: a candidate once more, or not found."""
        self.exhausted = True
        found = self._pick(with_mismatch=not self.budget_spent)
        return self._found(found) if found is not None else self._not_found()

    # -- looking at the floor the camera has not seen -------------------------------------------------

    def _view(self) -> None:
        """Add the newest camera frame's view to the coverage."""
        robot = self.context.robot
        frame = robot.rgbd()
        if self.coverage is None or frame is None or frame.stamp <= self.last_view:
            return
        grid = robot.occupancy()
        if grid is None:
            return
        self.last_view = frame.stamp
        self.coverage.add_view(grid, frame.camera_pose, frame.intrinsics.hfov)

    def _cover(self) -> Status:
        """One step of select -> drive -> look at the floor not yet seen; SUCCESS when none is left."""
        assert self.coverage is not None
        robot = self.context.robot
        grid, stamped = robot.occupancy(), robot.pose()
        if grid is None or stamped is None:
            return self.running("waiting for the map")
        pose, now = stamped.pose, robot.now()
        if self.cover_state == "drive":
            return self._cover_drive(grid, pose, now)
        if self.cover_state == "look":
            return self._cover_look(grid, pose, now)
        if self.planner is not None and self.frontier_rounds < MAX_FRONTIER_ROUNDS:
            # the map grew while looking (a room seen through a door): its frontiers come first
            if self._frontier_places(self.frontiers_left):
                self.frontier_rounds += 1
                self.frontiers_done = False
                self.emit("search_frontiers_again", round=self.frontier_rounds)
                return self.running("new frontiers on the map: exploring on")
        goals, unplaced = view_goals(
            self.coverage,
            grid,
            (pose.x, pose.y),
            known_path_lengths,
            self.params.footprint_radius,
            min_area_m2=self.params.view_min_area,
            cost_rate=self.params.cost_rate,
        )
        for patch in unplaced:
            self.coverage.skip(patch)
            self.cover_skipped += 1
        if not goals:
            seen, floor = self.coverage.seen_share(grid, (pose.x, pose.y))
            self.emit(
                "search_covered",
                seen_m2=round(seen, 1),
                floor_m2=round(floor, 1),
                goals=self.cover_goals,
                given_up=self.cover_skipped,
            )
            return self.succeed("looked at the reachable floor")
        goal = goals[0]
        yaw = math.atan2(goal.target[1] - goal.y, goal.target[0] - goal.x)
        self.cover_goal = goal
        self.cover_goals += 1
        self.cover_handle = robot.navigate_to(Pose2D(goal.x, goal.y, yaw), Tolerance(0.3, 2.0 * math.pi))
        self.cover_best, self.cover_best_at = math.inf, now
        self.cover_state = "drive"
        self.emit(
            "search_view_goal",
            x=round(goal.x, 3),
            y=round(goal.y, 3),
            unseen_m2=round(goal.area_m2, 2),
            path_m=round(goal.path_m, 2),
        )
        self.context.mark("goal", goal.x, goal.y, "view")
        return self.running(f"to look at {goal.area_m2:.1f} m^2 of floor not yet seen")

    def _cover_drive(self, grid: OccupancyGrid, pose: Pose2D, now: float) -> Status:
        assert self.cover_handle is not None and self.cover_goal is not None
        goal = self.cover_goal
        distance = math.hypot(goal.x - pose.x, goal.y - pose.y)
        status = self.cover_handle.status()
        if status.done:
            self.cover_handle = None
            if status is ActionStatus.SUCCEEDED or distance <= 0.5:
                return self._start_cover_look(pose, now)
            return self._give_up_view(grid, pose, f"goal {status.value}")
        if distance < self.cover_best - 0.1:
            self.cover_best, self.cover_best_at = distance, now
        elif now - self.cover_best_at > self.params.view_timeout:
            self.cover_handle.cancel()
            self.cover_handle = None
            return self._give_up_view(grid, pose, f"no progress for {self.params.view_timeout:g} s")
        return self.running(f"to look at the floor not yet seen: {distance:.1f} m to go")

    def _start_cover_look(self, pose: Pose2D, now: float) -> Status:
        self.cover_state = "look"
        self.look_turned, self.look_yaw, self.look_started = 0.0, pose.yaw, now
        return self.running("looking around")

    def _cover_look(self, grid: OccupancyGrid, pose: Pose2D, now: float) -> Status:
        """A full turn where the goal was reached; then what stayed unseen near it is given up."""
        assert self.coverage is not None and self.cover_goal is not None
        robot = self.context.robot
        self.look_turned += abs(wrap_angle(pose.yaw - self.look_yaw))
        self.look_yaw = pose.yaw
        limit = 2.0 * (2.0 * math.pi / self.params.look_speed) + 5.0
        if self.look_turned < 2.0 * math.pi - 0.05 and now - self.look_started < limit:
            robot.drive(0.0, self.params.look_speed)
            return self.running(f"looking around: {math.degrees(self.look_turned):.0f} deg")
        robot.drive(0.0, 0.0)
        self.cover_state = "select"
        # what the camera still has not seen within reach of here is hidden from the floor: given up
        cov = self.coverage
        near = HIDDEN_WITHIN * cov.view_range
        hidden = {
            k
            for k in cov.unseen(grid, (pose.x, pose.y))
            if math.hypot((k[0] + 0.5) * cov.cell - pose.x, (k[1] + 0.5) * cov.cell - pose.y) <= near
        }
        self.coverage.skip(hidden)
        target = self.coverage.key(*self.cover_goal.target)
        if target not in self.coverage.seen:
            self.coverage.skip({target})
        return self.running("looked around")

    def _give_up_view(self, grid: OccupancyGrid, pose: Pose2D, why: str) -> Status:
        """The place to look from was not reached: the unseen cells near its patch's centre are given up."""
        assert self.coverage is not None and self.cover_goal is not None
        goal = self.cover_goal
        near = {
            k
            for k in self.coverage.unseen(grid, (pose.x, pose.y))
            if math.hypot(
                (k[0] + 0.5) * self.coverage.cell - goal.target[0],
                (k[1] + 0.5) * self.coverage.cell - goal.target[1],
            )
            <= self.coverage.view_range / 2.0
        }
        self.coverage.skip(near | {self.coverage.key(*goal.target)})
        self.cover_skipped += 1
        self.cover_state = "select"
        self.emit("search_view_given_up", x=round(goal.x, 3), y=round(goal.y, 3), reason=why)
        return self.running(f"gave up a place to look from ({why})")

    def _found(self, found: dict[str, Any]) -> Status:
        if found.pop("again", False):
            self.offered_again.add(str(found["id"]))
        self.write("candidate", found)
        self.emit("search_candidate", **found)
        return self.succeed(
            f"candidate {found['id']} ({found['colour']} {found['label']}) from "
            f"{found['source']} at ({found['x']:.2f}, {found['y']:.2f})"
        )

    def _not_found(self) -> Status:
        assert self.goal is not None
        tried = rejected_entries(self.read("rejected", []))
        shown = "; ".join(f"{e.get('id')}: {e.get('reason', '')}" for e in tried[:4])
        grid = self.last_grid
        known = f", {self.summary(grid)}" if grid is not None and self.planner is not None else ""
        if self.budget_spent:
            known += f"; the time budget of {self.params.time_budget:g} s was spent before all was looked at"
        if self.explore_end.startswith(("partial:", "stuck:")):
            known += f"; exploration {self.explore_end[:300]}"
        robot = self.context.robot
        stamped, now_grid = robot.pose(), robot.occupancy()
        if (
            now_grid is not None
            and stamped is not None
            and self.coverage is not None
            and self.params.view_coverage
        ):
            seen, floor = self.coverage.seen_share(now_grid, (stamped.pose.x, stamped.pose.y))
            known += f"; the camera looked at {seen:.0f} of {floor:.0f} m^2 of reachable floor"
        return self.fail(
            f"not found: no {self.goal.text} in the reachable space explored{known}"
            + (f" ({len(tried)} candidates rejected: {shown})" if tried else "")
        )

    # -- candidates -------------------------------------------------------------------------------

    def _pick(self, with_mismatch: bool) -> dict[str, Any] | None:
        """The best known candidate not rejected: colour match first, then unknown colour, then nearest."""
        if self.goal is None:
            return None
        goal = self.goal
        rejected = rejected_entries(self.read("rejected", []))
        stamped = self.context.robot.pose()
        here = (stamped.pose.x, stamped.pose.y) if stamped is not None else (0.0, 0.0)
        options: list[tuple[int, float, dict[str, Any]]] = []
        scene = getattr(self.ctx, "scene", None)
        instances = getattr(scene, "map", None)
        for inst in list(instances) if instances is not None else []:
            if fold_label(inst.label) != fold_label(goal.label):
                continue
            entry = {
                "id": inst.id,
                "label": inst.label,
                "colour": inst.colour,
                "x": round(inst.position[0], 3),
                "y": round(inst.position[1], 3),
                "z": round(inst.position[2], 3),
                "height": round(inst.size[2], 3),
                "source": "semantic map",
                "observations": inst.observations,
            }
            options.append(self._ranked(entry, rejected, here, with_mismatch))
        for obj in self.file_objects:
            if obj.xy is None or fold_label(obj.label) != fold_label(goal.label):
                continue
            colours = [c for c in obj.attributes if c in goal.colours] or obj.attributes[:1]
            entry = {
                "id": obj.id,
                "label": obj.label,
                "colour": colours[0] if colours else "unknown",
                "x": obj.xy[0],
                "y": obj.xy[1],
                "z": obj.z,
                "source": "scene graph",
            }
            options.append(self._ranked(entry, rejected, here, with_mismatch))
        options = [o for o in options if o[0] >= 0]
        if not options:
            return None
        return min(options, key=lambda o: (o[0], o[1]))[2]

    def _ranked(
        self,
        entry: dict[str, Any],
        rejected: list[dict[str, Any]],
        here: tuple[float, float],
        with_mismatch: bool,
    ) -> tuple[int, float, dict[str, Any]]:
        """(rank, distance, entry); rank -1: ruled out. Unreached ones come back once when exhausted."""
        assert self.goal is not None
        unreached = False
        for r in rejected:
            if r.get("id") == entry["id"] or (
                fold_label(str(r.get("label", ""))) == fold_label(entry["label"])
                and math.hypot(
                    float(r.get("x", math.inf)) - entry["x"], float(r.get("y", math.inf)) - entry["y"]
                )
                < REJECT_RADIUS
            ):
                if r.get("kind", "wrong") != "unreached":
                    return -1, 0.0, entry
                unreached = True
        if unreached:
            if not self.exhausted or self.budget_spent or str(entry["id"]) in self.offered_again:
                return -1, 0.0, entry
            entry = {**entry, "again": True}
        colour = canonical_colour(str(entry["colour"]))
        if not self.goal.colours or colour in self.goal.colours:
            rank = 0
        elif colour in ("", "unknown"):
            rank = 1
        elif with_mismatch and int(entry.get("observations", 0)) < TRUSTED_COLOUR_FRAMES:
            rank = 2  # its colour may be misread: worth a close look once nothing else is left
        else:
            rank = -1
        return rank, math.hypot(entry["x"] - here[0], entry["y"] - here[1]), entry

    def _prior(self, frontier: Frontier) -> float:
        """Likelihood of the target beyond a frontier: its room's type and the objects seen near it."""
        if not self.priors:
            return 0.0
        scene = getattr(self.ctx, "scene", None)
        instances = getattr(scene, "map", None)
        seen = [(i.label, i.xy) for i in instances] if instances is not None else []
        room_type = None
        for room in getattr(scene, "rooms", None) or []:
            if _inside(room.polygon, frontier.x, frontier.y):
                room_type = room.type
                break
        return region_score((frontier.x, frontier.y), self.priors, seen, room_type)


def _inside(polygon: Any, x: float, y: float) -> bool:
    """Point in polygon (even-odd rule); False for an empty polygon."""
    pts = [(float(p[0]), float(p[1])) for p in polygon]
    inside = False
    for (x1, y1), (x2, y2) in zip(pts, pts[1:] + pts[:1], strict=True):
        if (y1 > y) != (y2 > y) and x < x1 + (y - y1) * (x2 - x1) / (y2 - y1):
            inside = not inside
    return inside
