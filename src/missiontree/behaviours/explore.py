"""Explore: drive to frontiers (or scan points) until no reachable unexplored place is left.

The leaf reads only the robot: its map (``occupancy()``, the lidar's learned map, ``/map`` from
SLAM on ROS 2), its pose, and ``navigate_to`` handles. Where to go next is decided by
:class:`missiontree.mapping.exploration.ExplorationPlanner`: ``gain`` (unknown area a frontier
reveals against the path; with ``order: tour`` the first stop of the tour revealing the most
soonest, an option), ``nearest`` (as explore_lite), ``scan_points`` (the search report's, largest first).

While driving it re-plans every ``replan_period`` seconds: a goal whose frontier has been seen
meanwhile is dropped for the next one (the lidar reaches far ahead of the robot), and the
``gain`` strategy also switches, at every third re-plan, when another goal scores clearly (1.3
times) better -- but never back to a place it left before reaching it, and a place left twice as
seen (its frontier flickering in the scans) is gone to and looked at instead of left again.

A frontier is given up only when the map proves it closed. A try fails when the navigation stack
aborts the goal, when the path left to it (the navigator's feedback; the straight line without
one) has not shrunk for ``no_progress_timeout`` seconds, or when its frontier stays unknown once
reached. The map is then asked: no way to the frontier on it (or the frontier is no longer worth a
trip, or the unknown behind it is no space the robot fits into: the inside of furniture, the far
side of a wall) -- given up as closed, with the reason; a way -- the frontier is tried again from another
approach (through the doorway, or from another place; :mod:`missiontree.mapping.exploration`),
after the frontiers not tried yet, and given up *open* after ``max_attempts`` tries. A frontier
given up as closed that the map opens again later is tried again (up to ``max_attempts`` in all).
With ``look_around`` the robot turns a full circle at each goal reached, in ``look_steps`` steps
with a pause at each (the report's 360° scan), by ``drive`` commands.

Ends SUCCESS ("explored") only when no reachable frontier worth a trip (or unvisited scan point)
remains and no frontier was given up open; the reason names the small unknown slivers left (the
planner's ``slivers``: count and m^2). When some were given up open (the map still shows a way to
a frontier the robot could not get to), the exploration is *partial*: FAILURE (or SUCCESS with
``partial_is_success``) whose reason starts with ``partial:`` and names each such frontier (its
position and why it was left) and the unknown area left behind them (m^2). FAILURE with a reason
also when no map arrives within ``map_timeout`` or the robot is stuck (neither the known area grew
nor the robot moved for ``stuck_timeout`` seconds); FAILURE "partial: the time budget of N s was
spent: ..." (what is left, as a partial end says it) once a run of the leaf took ``time_budget``
robot seconds. The reason is the node's failure reason in the run's summary.json. On every end,
halts included, the learned map is written into the run directory as ``map.pgm`` + ``map.yaml``
(Nav2 map_server format) beside ``exploration.json``: how it ended (``explored``, ``partial``,
``failed`` or ``halted``), ``complete``, the frontiers left (positions, why) and the unknown area
behind them, the frontiers given up and why; the blackboard gets ``explore_complete`` and
``unexplored`` (the frontiers left).

Leaves built on Explore (the search's ``ResumeExplore`` and ``Locate``) use its public interface:
:meth:`Explore.planner_options` and :meth:`Explore.make_planner` (the planner a run uses),
:meth:`Explore.select_goal` (choose and send the next goal), the hooks :meth:`Explore.on_goal_reached`,
:meth:`Explore.on_give_up`, :meth:`Explore.goal_still_wanted` (drop a goal in hand whose place was seen on
the way), :meth:`Explore.wants_look` and :meth:`Explore.on_look_done` (a full turn at a goal and what it
showed), :meth:`Explore.on_goal_failed` (a goal of the subclass's own kind that failed),
:meth:`Explore.reset_progress` (restart the stuck timer), :meth:`Explore.summary`, :func:`known_area`.
"""

from __future__ import annotations

import math
from typing import Annotated, Any, Literal

from pydantic import BaseModel, Field

from missiontree.behaviours.explore_report import (
    budget_text,
    known_area,
    partial_text,
    save_leaf,
    slivers_text,
)
from missiontree.engine.leaf import Leaf, Status
from missiontree.engine.ports import Output
from missiontree.mapping.exploration import Candidate, ExplorationPlanner, LeftOpen
from missiontree.mapping.grid import free_mask
from missiontree.robot.actions import ActionHandle, ActionStatus
from missiontree.types import OccupancyGrid, Pose2D, Tolerance, wrap_angle

_SELECT, _DRIVE, _LOOK = "select", "drive", "look"
#: Known area must grow by this much (m^2), or the robot move this far (m), to count as progress.
_AREA_PROGRESS = 0.25
_MOVE_PROGRESS = 0.25
#: A frontier place left this many times before it was reached (its frontier flickering seen and
#: unseen) is no longer left as seen: the robot goes there and looks.
_MAX_LEFT = 2
#: The goal in hand is compared with every other (a ranking of the whole window) at every this many
#: re-plans; whether its own frontier was seen is checked at each (a look at its place only).
_COMPARE_EVERY = 3


class Explore(Leaf):
    """Explore an unknown place: frontiers by gain against path cost (or nearest, or scan points).

    Writes the learned map as ``map.pgm`` + ``map.yaml`` into the run directory when it ends.
    """

    class Params(BaseModel):
        strategy: Literal["gain", "nearest", "scan_points"] = Field(
            "gain", description="gain: unknown area revealed against path cost; nearest: nearest frontier "
            "(explore_lite); scan_points: the report's scan points, largest region first.")
        order: Literal["score", "tour"] = Field("score", description="strategy gain: go first to the best "
            "gain against path (score) or to the first stop of the tour revealing the most soonest (tour).")
        look_around: bool = Field(False, description="Turn a full circle at each goal reached.")
        look_steps: int = Field(4, ge=1, le=36, description="Steps of the full turn (pause after each).")
        look_pause: float = Field(0.5, ge=0, description="Pause after each step of the turn (s).")
        turn_speed: float = Field(1.0, gt=0, description="Angular speed of the look-around (rad/s).")
        scan_point_erosion: float = Field(
            0.5, ge=0, description="Scan point erosion (m); over half a door's width cuts rooms apart.")
        sensor_range: float = Field(
            4.0, gt=0, description="Range over which a frontier's gain is counted (m).")
        cost_rate: float = Field(
            0.15, ge=0, description="Gain discount per metre of path (1/m), strategy gain.")
        min_gain: float = Field(
            1.0, ge=0, description="strategy gain: skip frontiers revealing less unknown area (m^2).")
        min_frontier_size: float = Field(0.5, gt=0, description="Ignore frontiers shorter than this (m).")
        footprint_radius: float = Field(
            0.2, gt=0, description="Robot radius for planning and goal clearance (m).")
        nav_footprint_radius: float | None = Field(
            None, gt=0, description="Radius the navigation stack plans with on the learned map (m): a "
            "frontier it shows no way to is closed, not left open. Default: nav_body_radius padded by "
            "nav_padding_cells cells of the map (the simulator's navigator: 0.27 m at 5 cm, 0.23 m at 3 cm).")
        nav_body_radius: float = Field(0.17, gt=0, description="The robot body's radius (m; TurtleBot 4).")
        nav_padding_cells: float = Field(
            2.0, ge=0, description="Cells of the map the navigation pads the body with (the default "
            "nav_footprint_radius; 1 offered frontiers behind gaps the navigator then refused).")
        xy_tolerance: float = Field(0.3, gt=0, description="Distance at which a goal counts as reached (m).")
        replan_period: float = Field(
            2.0, gt=0, description="Re-evaluate the goal this often while driving (s).")
        no_progress_timeout: float = Field(
            30.0, gt=0, description="End a try when the path left to its goal (navigation feedback) has "
            "not shrunk for this long (s); the frontier is tried again from another approach.")
        max_attempts: int = Field(
            3, ge=1, le=10, description="Tries of a frontier the map still shows a way to (each from "
            "another approach) before it is given up, leaving the exploration partial.")
        partial_is_success: bool = Field(
            False, description="End SUCCESS (the reason still starting 'partial:') when frontiers were "
            "given up while the map showed a way to them; default FAILURE.")
        stuck_timeout: float = Field(
            60.0, gt=0, description="Fail when neither the map grew nor the robot moved for this long (s).")
        time_budget: float | None = Field(
            None, gt=0, description="End FAILURE 'partial: the time budget ...' (exploration.json: partial) "
            "after this many robot seconds of a run of the leaf, naming what is left; default: no limit.")
        map_timeout: float = Field(
            10.0, gt=0, description="Fail when no map with free space arrives in time (s).")
        map_name: str = Field("map", pattern=r"^[A-Za-z0-9_.-]+$",
                              description="Base name of the map files written into the run directory.")
        explored_area: Annotated[str, Output("known map area when the leaf ended (m^2)", type="float")] = (
            "explored_area")
        map_yaml: Annotated[str, Output("path of the map.yaml written", type="str")] = "map_yaml"
        explore_complete: Annotated[str, Output(
            "True when the leaf ended with nothing reachable left unexplored", type="bool")] = (
            "explore_complete")
        unexplored: Annotated[str, Output(
            "frontiers left unexplored when the leaf ended: [{x, y, reason}]", type="list")] = "unexplored"

    params: Params

    def __init__(self, name: str, params: BaseModel | None = None) -> None:
        super().__init__(name, params)
        self.planner: ExplorationPlanner | None = None
        self.handle: ActionHandle | None = None
        self.target: Candidate | None = None
        self.state = _SELECT
        self.started = 0.0
        self.goals = 0
        self.last_grid: OccupancyGrid | None = None
        self.left: list[LeftOpen] | None = None   # set when nothing is left but frontiers given up open
        self.dropped: list[tuple[float, float]] = []  # frontier places left before they were reached
        #: explored | partial | failed | stopped (halted, or ended by a subclass's own rule)
        self.outcome = "stopped"
        self.time_budget_spent = False
        self.map_written: tuple[Any, ...] | None = None  # what the map files last written hold
        self._reset_timers(0.0)

    def _reset_timers(self, now: float) -> None:
        self.next_replan = now
        self.replans = 0
        self.goal_started = now
        self.goal_best = math.inf
        self.goal_best_at = now
        self.progress_at = now
        self.progress_area = 0.0
        self.progress_xy = (math.nan, math.nan)
        self.area_at = -math.inf
        self.look_turned = 0.0
        self.look_yaw = 0.0
        self.look_pause_until = -math.inf
        self.look_started = now
        self.look_steps_done = 0
        self.look_target: Candidate | None = None  # the goal reached that the look is for

    # -- lifecycle ---------------------------------------------------------------------------------

    def initialise(self) -> None:
        """Start with the planner :meth:`make_planner` gives (a new one: empty blacklist) and no goal."""
        self.planner = self.make_planner()
        self.handle = None
        self.target = None
        self.state = _SELECT
        self.goals = 0
        self.last_grid = None
        self.left = None
        self.dropped = []
        self.outcome, self.time_budget_spent = "stopped", False
        self.started = self.context.robot.now()
        self._reset_timers(self.started)

    def update(self) -> Status:
        """One step of select -> drive -> (look around) -> select; returns at once."""
        robot = self.context.robot
        now = robot.now()
        grid = robot.occupancy()
        stamped = robot.pose()
        if grid is None or stamped is None or (self.last_grid is None and not free_mask(grid).any()):
            if now - self.started > self.params.map_timeout:
                got = "nothing" if grid is None else "no free cell"
                return self.fail(f"no map with free space within {self.params.map_timeout:g} s "
                                 f"(is the robot mapping? occupancy() gave {got})")
            return self.running("waiting for the map")
        self.last_grid = grid
        assert self.planner is not None
        self.planner.reach_radius = self.nav_radius(grid.resolution)
        pose = stamped.pose
        if self.params.time_budget and now - self.started >= self.params.time_budget:  # 0: none, as Locate
            return self._explore_time_up(grid, pose)
        if self._stuck(now, grid, pose):
            return self.fail(f"stuck: the map did not grow and the robot did not move for "
                             f"{self.params.stuck_timeout:g} s ({self.summary(grid)})")
        if self.state == _LOOK:
            if not self._look(now, pose):
                return self.running(f"looking around: {math.degrees(self.look_turned):.0f} deg")
            self.state = _SELECT
            target, self.look_target = self.look_target, None
            if target is not None:
                self.on_look_done(target, grid, pose)
        if self.state == _DRIVE:
            status = self._drive(now, grid, pose)
            if status is not None:
                return status
        if self.state == _SELECT:
            return self._ended(self.select_goal(now, grid, pose), grid)
        return self.running(self._feedback(pose))

    def _ended(self, status: Status, grid: OccupancyGrid) -> Status:
        """A SUCCESS that left frontiers given up open is partial: FAILURE unless ``partial_is_success``."""
        if status != Status.SUCCESS or self.left is None or self.state != _SELECT:
            return status
        text = self.partial_text(grid, self.left)
        if self.params.partial_is_success:
            return self.succeed(text)
        return self.fail(text)

    def _explore_time_up(self, grid: OccupancyGrid, pose: Pose2D) -> Status:
        """The time budget is spent: stop the goal in hand, end FAILURE 'partial: ...' with what is left."""
        assert self.planner is not None and self.params.time_budget
        if self.handle is not None:
            self.handle.cancel()
            self.handle = None
        self.outcome, self.left, self.time_budget_spent = "partial", None, True
        return self.fail(budget_text(self.planner, grid, (pose.x, pose.y), self.params.time_budget,
                                     self.summary(grid)))

    def terminate(self, new_status: Status) -> None:
        """Cancel the goal, stop turning and write the learned map into the run directory."""
        robot = self.ctx.robot if self.ctx is not None else None
        if self.handle is not None:
            self.handle.cancel()
            self.handle = None
        if robot is not None and self.state == _LOOK:
            robot.drive(0.0, 0.0)
        self.state = _SELECT
        save_leaf(self)

    # -- public interface for leaves built on Explore ------------------------------------------------

    def planner_options(self) -> dict[str, Any]:
        """The exploration planner's options, from the parameters."""
        p = self.params
        return {"strategy": p.strategy, "footprint_radius": p.footprint_radius,
                "reach_radius": self.nav_radius(0.05),
                "sensor_range": p.sensor_range, "min_frontier_m": p.min_frontier_size,
                "cost_rate": p.cost_rate, "erosion_m": p.scan_point_erosion, "min_gain_m2": p.min_gain,
                "order": p.order}

    def nav_radius(self, resolution: float) -> float:
        """The footprint the navigation plans with on a map of ``resolution`` (m per cell).

        A planner judging reachability with a larger one than the navigator's dropped frontiers
        behind gaps the robot could drive through (on a 3 cm map, 0.46-0.54 m), and could end
        "explored" with the rooms behind them unseen.
        """
        p = self.params
        if p.nav_footprint_radius is not None:
            return p.nav_footprint_radius
        return p.nav_body_radius + p.nav_padding_cells * resolution

    def make_planner(self) -> ExplorationPlanner:
        """The planner for a run of the leaf (called by :meth:`initialise`; a new one each run here).

        Subclasses may keep one across runs (its blacklist and visited goals) or rank its goals.
        """
        return ExplorationPlanner(**self.planner_options())

    def select_goal(self, now: float, grid: OccupancyGrid, pose: Pose2D) -> Status:
        """Send the best candidate goal (RUNNING), or SUCCESS when no reachable one remains.

        When none remains, frontiers given up that the map now offers a way to are tried again
        while they have tries left; those left over set :attr:`left` (the exploration is partial:
        :meth:`update` turns the SUCCESS into FAILURE, subclasses may first try them their way).
        """
        planner = self.planner
        assert planner is not None
        candidates = planner.candidates(grid, (pose.x, pose.y))
        self.left = None
        if not candidates and planner.blacklist:
            left = planner.left_open(grid, (pose.x, pose.y))
            again = [o for o in left if len(planner.tries(o.entry.target)) < self.params.max_attempts]
            if again:
                self.emit("explore_reopen", goals=[
                    {"x": round(o.candidate.x, 3), "y": round(o.candidate.y, 3), "was": o.entry.reason}
                    for o in again])
                for o in again:  # still counted as a try, and still steering the next approach
                    planner.blacklist.remove(o.entry)
                    planner.failures.append(o.entry)
                candidates = planner.candidates(grid, (pose.x, pose.y))
                left = [o for o in left if o not in again]
            if not candidates and left:
                self.left = left
        if not candidates:
            self.outcome = "explored" if self.left is None else "partial"
            what = f"no reachable {self._what()} worth a trip remains"
            return self.succeed(f"explored: {what} ({self.summary(grid)})")
        self._send(now, candidates[0])
        return self.running(self._feedback(pose))

    def partial_text(self, grid: OccupancyGrid, left: list[LeftOpen]) -> str:
        """'partial: N frontiers left ... at (x, y) (why) ...; about A m^2 unknown behind them (summary)'."""
        assert self.planner is not None
        return partial_text(self.planner, grid, left, self.summary(grid))

    def on_goal_reached(self, goal: Candidate) -> None:
        """Called when the robot reached ``goal`` (before any look-around); nothing here."""

    def on_give_up(self, goal: Candidate, reason: str) -> None:
        """Called when ``goal`` was blacklisted (``self.last_grid`` is the map then); nothing here."""

    def goal_still_wanted(self, grid: OccupancyGrid, goal: Candidate) -> bool:
        """Whether the goal being driven to is still worth going on to (asked at each re-plan).

        Here: a frontier goal while its frontier is not seen -- judged within the blacklist's radius,
        as the frontier piece's own point shifts as its far edge flickers in the scans (a 0.3 m test
        sent the robot back and forth between two frontiers for a whole run); other kinds always.
        Subclasses drop their own goals whose place was seen on the way.
        """
        if goal.kind != "frontier":
            return True
        assert self.planner is not None
        return self.planner.still_frontier(grid, *goal.target, radius=self.planner.blacklist_radius)

    def wants_look(self, goal: Candidate) -> bool:
        """Whether to turn a full circle at ``goal`` once reached; here the ``look_around`` parameter."""
        return self.params.look_around

    def on_look_done(self, goal: Candidate, grid: OccupancyGrid, pose: Pose2D) -> None:
        """Called after the full turn at ``goal``: a frontier still unknown from there is a failed try."""
        assert self.planner is not None
        if goal.kind == "frontier" and self.planner.still_frontier(grid, *goal.target):
            self._try_failed(goal, "reached and looked around, but its frontier stays unknown from there",
                             grid, pose)

    def on_goal_failed(self, goal: Candidate, reason: str) -> None:
        """A goal of another kind than a frontier failed (aborted, no progress): here it is given up."""
        self._give_up(goal, reason, proved_closed=True)

    def reset_progress(self, now: float, pose: Pose2D | None = None) -> None:
        """Restart the stuck timer: the robot moved and looked under another's control meanwhile.

        Kept from before, the timer ended the next step "stuck" at once where the robot had stopped.
        """
        self.progress_at, self.area_at, self.progress_area = now, -math.inf, -math.inf
        self.progress_xy = (pose.x, pose.y) if pose is not None else (math.nan, math.nan)

    def summary(self, grid: OccupancyGrid) -> str:
        """Known area, goals sent and places given up, e.g. '20.8 m^2 known, 3 goals, 2 unreachable'.

        ``unreachable``: given up as the map proved them closed; ``given up open``: while it
        showed a way (after ``max_attempts`` tries).
        """
        assert self.planner is not None
        text = f"{known_area(grid):.1f} m^2 known, {self.goals} goals"
        closed = sum(b.proved_closed for b in self.planner.blacklist)
        opened = len(self.planner.blacklist) - closed
        if closed:
            text += f", {closed} unreachable"
        if opened:
            text += f", {opened} given up open"
        return text + slivers_text(self.planner)

    # -- states ------------------------------------------------------------------------------------

    def _drive(self, now: float, grid: OccupancyGrid, pose: Pose2D) -> Status | None:
        """Poll the goal; None when the state changed to select (or look) and the caller goes on."""
        assert self.handle is not None and self.target is not None and self.planner is not None
        target = self.target
        status = self.handle.status()
        if status.done:
            result = self.handle.result()
            self.handle = None
            if status is ActionStatus.SUCCEEDED:
                self.planner.visit(target.x, target.y)
                self.emit("explore_reached", x=target.x, y=target.y)
                self.on_goal_reached(target)
                look = self.wants_look(target)
                if target.kind == "frontier" and not look \
                        and self.planner.still_frontier(grid, *target.target):
                    # standing there did not reveal it (a gap the lidar cannot look into from there)
                    self._try_failed(target, "reached, but its frontier stays unknown from there", grid, pose)
                if look:
                    self._start_look(now, pose)
                    self.look_target = target
                    return self.running("looking around")
            else:
                reason = (result.reason if result is not None and result.reason else status.value)
                self._try_failed(target, f"goal {status.value}: {reason}", grid, pose)
            self.state = _SELECT
            return None
        feedback = self.handle.feedback()
        # progress is the path left (Nav2's distance_remaining): the straight line grows while the
        # path leads out of a room and round to a door
        distance = (feedback.distance_remaining if feedback is not None
                    and math.isfinite(feedback.distance_remaining) else math.hypot(target.x - pose.x,
                                                                                   target.y - pose.y))
        if distance < self.goal_best - 0.1:
            self.goal_best, self.goal_best_at = distance, now
        elif now - self.goal_best_at > self.params.no_progress_timeout:
            self.handle.cancel()
            self.handle = None
            self._try_failed(target, f"no progress along the path for {self.params.no_progress_timeout:g} s",
                             grid, pose)
            self.state = _SELECT
            return None
        if now >= self.next_replan and target.kind != "scan_point":
            self.next_replan = now + self.params.replan_period
            seen = not self.goal_still_wanted(grid, target)
            if seen and self._times_left(target.target) >= _MAX_LEFT:
                seen = False  # it flickers: go there and look (reached, its frontier decides)
            self.replans += 1
            if seen or (self.params.strategy == "gain" and self.replans % _COMPARE_EVERY == 0):
                return self._replan(now, grid, pose, target, seen)
        return self.running(self._feedback(pose))

    def _replan(self, now: float, grid: OccupancyGrid, pose: Pose2D, target: Candidate,
                seen: bool) -> Status | None:
        """Leave a goal whose frontier was seen for the best one, or switch to a clearly better one.

        A place once left before it was reached is never switched back to for scoring better (it
        is chosen again only when the goal in hand ends): two goals scoring alike in turn sent the
        robot back and forth between them for whole runs.
        """
        assert self.planner is not None and self.handle is not None
        candidates = self.planner.candidates(grid, (pose.x, pose.y))
        if not candidates:
            self.handle.cancel()
            self.handle = None
            self.state = _SELECT
            return None
        best = candidates[0]
        if seen:
            self.dropped.append(target.target)
            self._send(now, best)  # its frontier has been seen meanwhile: on to the next
        else:
            current = _matching(candidates, target, radius=0.5)
            if current is not None and best is not current and self.planner.better(best, current) \
                    and self._times_left(best.target) == 0:
                self.dropped.append(target.target)
                self._send(now, best)
        return self.running(self._feedback(pose))

    def _times_left(self, place: tuple[float, float]) -> int:
        """How often a goal for the frontier place ``place`` was left before it was reached."""
        assert self.planner is not None
        r = self.planner.blacklist_radius
        return sum(math.dist(place, p) <= r for p in self.dropped)

    def _send(self, now: float, candidate: Candidate) -> None:
        robot = self.context.robot
        if self.handle is not None:
            self.handle.cancel()
        self.outcome, self.left = "stopped", None
        self.target = candidate
        self.handle = robot.navigate_to(Pose2D(candidate.x, candidate.y, 0.0),
                                        Tolerance(self.params.xy_tolerance, 2.0 * math.pi))
        self.state = _DRIVE
        self.goals += 1
        self.goal_started = now
        self.goal_best, self.goal_best_at = math.inf, now
        self.next_replan = now + self.params.replan_period
        self.emit("explore_goal", x=candidate.x, y=candidate.y, kind=candidate.kind,
                  strategy=self.params.strategy, gain_m2=round(candidate.gain_m2, 3),
                  path_m=round(candidate.path_m, 3), score=round(candidate.score, 4))
        self.context.mark("goal", candidate.x, candidate.y, candidate.kind)

    def _try_failed(self, target: Candidate, reason: str, grid: OccupancyGrid, pose: Pose2D) -> None:
        """A try failed: give the place up when the map proves it closed or its tries are used up.

        Otherwise the try is recorded (:meth:`ExplorationPlanner.fail`) and the place stays on offer,
        from another approach.
        """
        planner = self.planner
        assert planner is not None
        if target.kind != "frontier":
            self.on_goal_failed(target, reason)
            return
        tries = len(planner.tries(target.target)) + 1
        still = planner.still_frontier(grid, *target.target)
        if still and not planner.reachable(grid, (pose.x, pose.y), target.target):
            self._give_up(target, f"{reason}; the map shows no way to it", proved_closed=True)
        elif still and not planner.opens_onto_space(grid, target.target):
            self._give_up(target, f"{reason}; nothing the robot fits into lies behind it", proved_closed=True)
        elif tries >= self.params.max_attempts:
            self._give_up(target, f"{reason} (after {tries} tr{'ies' if tries > 1 else 'y'}; the map still "
                          f"shows a way)", proved_closed=False)
        else:
            planner.fail(target.x, target.y, reason, target.target)
            self.emit("explore_try_failed", x=target.x, y=target.y, reason=reason, tries=tries)

    def _give_up(self, target: Candidate, reason: str, proved_closed: bool = True) -> None:
        assert self.planner is not None
        self.planner.give_up(target.x, target.y, reason, target.target, proved_closed=proved_closed)
        if target.kind == "scan_point":
            self.planner.visit(target.x, target.y)
        self.emit("explore_blacklist", x=target.x, y=target.y, reason=reason, proved_closed=proved_closed)
        self.on_give_up(target, reason)

    def _start_look(self, now: float, pose: Pose2D) -> None:
        self.state = _LOOK
        self.look_turned = 0.0
        self.look_yaw = pose.yaw
        self.look_pause_until = -math.inf
        self.look_started = now
        self.look_steps_done = 0

    def _look(self, now: float, pose: Pose2D) -> bool:
        """Turn a full circle in steps with pauses; True when done (or given up after a timeout)."""
        robot = self.context.robot
        p = self.params
        self.look_turned += wrap_angle(pose.yaw - self.look_yaw)
        self.look_yaw = pose.yaw
        step = 2.0 * math.pi / p.look_steps
        limit = 2.0 * (2.0 * math.pi / p.turn_speed + p.look_steps * p.look_pause) + 5.0
        if self.look_turned >= 2.0 * math.pi - 0.05 or now - self.look_started > limit:
            robot.drive(0.0, 0.0)
            return True
        if now < self.look_pause_until:
            robot.drive(0.0, 0.0)
            return False
        # pause when a step boundary has just been passed
        done_steps = int((self.look_turned + 0.02) // step)
        if done_steps > self.look_steps_done and p.look_pause > 0:
            self.look_steps_done = done_steps
            self.look_pause_until = now + p.look_pause
            robot.drive(0.0, 0.0)
            return False
        self.look_steps_done = done_steps
        remaining = 2.0 * math.pi - self.look_turned
        robot.drive(0.0, min(p.turn_speed, max(0.3, 2.0 * remaining)))
        return False

    # -- progress, feedback, map -----------------------------------------------------------------

    def _stuck(self, now: float, grid: OccupancyGrid, pose: Pose2D) -> bool:
        """Whether neither the robot moved nor the known area grew for ``stuck_timeout`` seconds.

        The known area (a count over the whole grid) is taken at most once a second, and only while
        the robot stands still: on a 30 x 50 m floor counting it every tick cost more than the
        robot's own mapping.
        """
        moved = math.hypot(pose.x - self.progress_xy[0], pose.y - self.progress_xy[1])
        if not moved <= _MOVE_PROGRESS:  # NaN (reset_progress without a pose) starts it here
            self.progress_xy, self.progress_at, self.progress_area = (pose.x, pose.y), now, -math.inf
            return False
        if now - self.area_at >= 1.0:
            self.area_at = now
            area = known_area(grid)
            if area > self.progress_area + _AREA_PROGRESS:
                self.progress_area, self.progress_at = area, now
        return now - self.progress_at > self.params.stuck_timeout

    def _what(self) -> str:
        return "unvisited scan point" if self.params.strategy == "scan_points" else "frontier"

    def _feedback(self, pose: Pose2D) -> str:
        if self.target is None:
            return "choosing a goal"
        d = math.hypot(self.target.x - pose.x, self.target.y - pose.y)
        return f"to {self.target.kind} ({self.target.x:.2f}, {self.target.y:.2f}): {d:.1f} m"


def _matching(candidates: list[Candidate], target: Candidate, radius: float) -> Candidate | None:
    """The candidate standing for the same frontier as ``target`` (nearest within ``radius``)."""
    best, best_d = None, radius
    for c in candidates:
        d = math.hypot(c.target[0] - target.target[0], c.target[1] - target.target[1])
        if d <= best_d:
            best, best_d = c, d
    return best
