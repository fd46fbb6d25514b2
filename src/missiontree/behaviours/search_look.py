"""Explore, then look at the floor the camera has not seen: the search's coverage of the reachable space.

The lidar maps a large floor long before the camera has looked at it. :class:`LookExplore` explores
the frontiers (as :class:`~missiontree.behaviours.search_resume.ResumeExplore`, kept across the
search's rounds); once no frontier is left (or the exploration ended partial), it goes to look at the
reachable floor the camera has not had in view (:mod:`~missiontree.behaviours.search_coverage`),
with a full turn at each place, and goes back to frontiers that appear meanwhile (a room seen
through a door). While exploring, it already prefers goals that bring floor the camera has not
seen into view: a frontier's gain counts the unseen floor near its goal, and places near the robot
from which unseen floor is looked at (``view_window``) compete with the frontiers on the same
score (kind ``view``; dropped once that floor was seen on the way, a full turn where reached). While
driving to a frontier, the goal is kept after the lidar has mapped its
frontier as long as the camera has not looked at the floor there (``hold_radius``, ``hold_area``):
the search's coverage is the camera's, and dropping such a goal sent the robot elsewhere and back.
``Locate`` builds on it with the candidates and the time budget.

Tick-log events: ``search_explored``, ``search_view_goal``, ``search_view_given_up``,
``search_covered``, ``search_frontiers_again``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from pydantic import BaseModel, Field

from missiontree.behaviours.search_coverage import (
    ViewCoverage,
    ViewGoal,
    known_path_lengths,
    look_arc,
    tour_view_goals,
    unseen_bearings,
    view_goals,
)
from missiontree.behaviours.search_resume import PriorPlanner, ResumeExplore
from missiontree.engine.leaf import Status
from missiontree.mapping.exploration import Candidate as Frontier
from missiontree.robot.actions import ActionHandle, ActionStatus
from missiontree.types import OccupancyGrid, Pose2D, Tolerance, wrap_angle

#: Times the search goes back from looking at the floor to exploring frontiers that appeared meanwhile.
MAX_FRONTIER_ROUNDS = 5
#: The arc look keeps the floor it turns to this share of the half field of view inside the image's edge.
ARC_MARGIN = 0.8
#: Camera frames a second the dwell after each part of an arc look counts on (the simulator's 5).
FRAME_RATE = 5.0


@dataclass
class ArcLook:
    """A turn in place through signed parts (rad), with a dwell after each for the camera's frames."""

    turns: list[float]
    yaw: float
    started: float
    dwell: float
    limit: float
    turned: float = 0.0
    paused_at: float | None = None
    parts: list[float] = field(default_factory=list)

    def step(self, yaw: float, now: float, speed: float) -> float | None:
        """The turn rate to drive now (rad/s), or None once the look is over (or timed out)."""
        if now - self.started > self.limit:
            return None
        if self.paused_at is not None:
            if now - self.paused_at < self.dwell:
                return 0.0
            self.paused_at = None
            if not self.turns:
                return None
        if not self.turns:
            self.paused_at = now
            return 0.0
        self.turned += wrap_angle(yaw - self.yaw)
        self.yaw = yaw
        left = self.turns[0] - self.turned
        if abs(left) <= 0.05 or left * self.turns[0] <= 0:
            self.parts.append(self.turned)
            self.turns.pop(0)
            self.turned = 0.0
            self.paused_at = now
            return 0.0
        return math.copysign(min(speed, max(0.3, 2.0 * abs(left))), left)


#: After a full turn at a view goal, floor still unseen within this share of the view range is hidden
#: from there (behind furniture) and given up; farther floor is left for a later goal.
HIDDEN_WITHIN = 0.8


class LookExplore(ResumeExplore):
    """Explore the frontiers, then look at the reachable floor the camera has not had in view.

    :meth:`look_step` is one step of it: RUNNING while exploring or looking, SUCCESS once no
    frontier and no unseen reachable floor is left, FAILURE when the exploration failed outright
    (a partial or stuck exploration goes on to look at the floor; what was left is in
    ``explore_end``).
    """

    class Params(ResumeExplore.Params):
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
        hold_radius: float = Field(
            1.0,
            ge=0,
            description="A frontier goal the lidar has mapped is kept while the camera has not looked at "
            "hold_area of the floor within this range of its frontier (m; 0: dropped as the lidar maps it).",
        )
        hold_area: float = Field(
            0.5, ge=0, description="Unseen floor (m^2) near a frontier that keeps its goal while driving."
        )
        camera_gain: bool = Field(
            True,
            description="While exploring, a frontier's gain counts the floor the camera has not looked at "
            "within view_range of its goal beside the unknown area.",
        )
        view_window: float = Field(
            6.0,
            ge=0,
            description="While exploring, places within this range (m) of the robot to look at unseen "
            "floor from compete with the frontiers (gain: unseen floor within view_range; 0: after the "
            "frontiers only).",
        )
        view_gain_min: float = Field(
            2.0, ge=0,
            description="Unseen floor (m^2) a place to look from must bring into view while exploring.",
        )
        look: Literal["arc", "full"] = Field(
            "arc",
            description="At a place to look from: turn only through the arc holding the floor in sight "
            "the camera has not looked at (none: no turn), or a full circle.",
        )

    params: Params

    def __init__(self, name: str, params: BaseModel | None = None) -> None:
        super().__init__(name, params)
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
        self.frontiers_left: list[tuple[float, float]] = []
        self.hfov = math.radians(60.0)
        self.arc: ArcLook | None = None
        self.arc_goal: Frontier | None = None

    def on_setup(self) -> None:
        """A fresh record of what the camera has looked at."""
        self.coverage = ViewCoverage(self.params.view_range, min_views=self.params.view_frames)

    def terminate(self, new_status: Status) -> None:
        """Stop exploring and looking."""
        self.stop_looking()
        super().terminate(new_status)

    def stop_looking(self) -> None:
        """Cancel the goal of a place to look from, stop a turn in progress, choose anew next time."""
        if self.cover_handle is not None:
            self.cover_handle.cancel()
            self.cover_handle = None
        if (self.cover_state == "look" or self.arc is not None) and self.ctx is not None:
            self.ctx.robot.drive(0.0, 0.0)
        self.cover_state = "select"
        self.arc, self.arc_goal = None, None

    def explore_step(self) -> Status:
        """One step of exploration; a goal being driven to is kept until the camera has looked there."""
        planner = self.planner
        if not isinstance(planner, PriorPlanner):
            return super().explore_step()
        planner.held = self._camera_waits
        planner.hold_active = bool(
            self.params.view_coverage
            and self.params.hold_radius > 0
            and self.state == "drive"
            and self.handle is not None
        )
        planner.driving = self.target if planner.hold_active else None
        looking = self.params.view_coverage and self.coverage is not None
        planner.camera_unseen = self._camera_unseen if looking and self.params.camera_gain else None
        planner.views = self._view_places if looking and self.params.view_window > 0 else None
        try:
            return super().explore_step()
        finally:
            # detached between steps: the report an ending round writes (exploration.json, the
            # frontiers left) lists frontiers only and need not place view goals on the whole map
            planner.hold_active, planner.driving = False, None
            planner.camera_unseen, planner.views = None, None

    def _camera_waits(self, grid: OccupancyGrid, x: float, y: float) -> bool:
        """Whether the camera has yet to look at ``hold_area`` of the floor near a frontier place."""
        if self.coverage is None:
            return False
        return self.coverage.unseen_near(grid, (x, y), self.params.hold_radius) >= self.params.hold_area

    def _camera_unseen(self, grid: OccupancyGrid, x: float, y: float) -> float:
        """Floor (m^2) within view_range of (x, y) the camera has not looked at."""
        assert self.coverage is not None
        return self.coverage.unseen_near(grid, (x, y), self.params.view_range)

    def _view_places(self, grid: OccupancyGrid, robot_xy: tuple[float, float]) -> list[Frontier]:
        """Places within ``view_window`` to look at unseen floor from, as exploration goals of kind view.

        Scored like a frontier (gain x exp(-cost_rate x path)), the gain being the unseen floor
        within view_range of the place; only the window around the robot is labelled.
        """
        assert self.coverage is not None and self.planner is not None
        planner = self.planner

        def lengths(g: OccupancyGrid, start: tuple[float, float], goals: Sequence[tuple[float, float]],
                    radius: float) -> list[float | None]:
            return planner.path_lengths(planner.window(g), start, goals, radius)

        goals, _ = view_goals(self.coverage, grid, robot_xy, lengths, planner.nav_radius,
                              min_area_m2=self.params.view_gain_min, cost_rate=self.params.cost_rate,
                              radius=self.params.view_window)
        per = self.coverage.cell ** 2
        return [
            Frontier(g.x, g.y, "view", int(round(g.area_m2 / per)), g.area_m2, g.path_m,
                     g.area_m2 * float(np.exp(-self.params.cost_rate * g.path_m)), g.target)
            for g in goals
            if g.area_m2 >= self.params.view_gain_min and not planner.is_blacklisted(g.x, g.y)
        ]

    def goal_still_wanted(self, grid: OccupancyGrid, goal: Frontier) -> bool:
        """A place to look from is wanted while the floor it is for was not seen on the way."""
        if goal.kind == "view":
            return self._camera_waits(grid, *goal.target)
        return super().goal_still_wanted(grid, goal)

    def wants_look(self, goal: Frontier) -> bool:
        """A full turn where a place to look from was reached (``look: full``; the arc look is ours)."""
        return (goal.kind == "view" and self.params.look == "full") or super().wants_look(goal)

    def on_goal_reached(self, goal: Frontier) -> None:
        """At a place to look from (``look: arc``), turn to the floor in sight not yet seen."""
        super().on_goal_reached(goal)
        if goal.kind == "view" and self.params.look == "arc" and self.coverage is not None:
            self.arc_goal = goal

    def select_goal(self, now: float, grid: OccupancyGrid, pose: Pose2D) -> Status:
        """The arc look at a place to look from just reached comes first; then the next goal."""
        goal = self.arc_goal
        if goal is not None:
            if self.arc is None:
                self.arc = self._arc_for(grid, pose, now)
            if self._arc_step(pose, now):
                return self.running("looking at the floor not yet seen")
            self.arc_goal = None
            self._skip_hidden(grid, pose, goal.target)
        return super().select_goal(now, grid, pose)

    def _arc_for(self, grid: OccupancyGrid, pose: Pose2D, now: float) -> ArcLook:
        """The arc look from ``pose``: the turns that bring the unseen floor in sight into view."""
        assert self.coverage is not None
        half = ARC_MARGIN * self.hfov / 2.0
        if self.params.look == "full":
            turns = [2.0 * math.pi]
        else:
            plan = look_arc(unseen_bearings(self.coverage, grid, pose), half)
            turns = [t for t in plan if abs(t) > 0.05] if plan is not None else []
        dwell = self.params.view_frames / FRAME_RATE
        total = sum(abs(t) for t in turns)
        limit = 2.0 * total / self.params.look_speed + (len(turns) + 1) * dwell + 5.0
        self.emit("search_look", turns_deg=[round(math.degrees(t)) for t in turns])
        return ArcLook(turns, pose.yaw, now, dwell, limit)

    def _arc_step(self, pose: Pose2D, now: float) -> bool:
        """Drive the arc look on; False (and the robot stopped) once it is over."""
        assert self.arc is not None
        rate = self.arc.step(pose.yaw, now, self.params.look_speed)
        if rate is None:
            self.context.robot.drive(0.0, 0.0)
            self.arc = None
            return False
        self.context.robot.drive(0.0, rate)
        return True

    def on_look_done(self, goal: Frontier, grid: OccupancyGrid, pose: Pose2D) -> None:
        """After the turn at a place to look from, the floor still unseen near it is hidden from there."""
        if goal.kind != "view" or self.coverage is None:
            super().on_look_done(goal, grid, pose)
            return
        self._skip_hidden(grid, pose, goal.target)

    def on_goal_failed(self, goal: Frontier, reason: str) -> None:
        """A place to look from not reached: the unseen floor near its patch is given up (not blacklisted)."""
        if goal.kind != "view" or self.coverage is None:
            super().on_goal_failed(goal, reason)
            return
        grid = self.last_grid
        if grid is not None:
            self._skip_near(grid, goal.target, (goal.x, goal.y))
        self.cover_skipped += 1
        self.emit("search_view_given_up", x=round(goal.x, 3), y=round(goal.y, 3), reason=reason)

    def _skip_hidden(self, grid: OccupancyGrid, pose: Pose2D, target: tuple[float, float]) -> None:
        """Floor still unseen within HIDDEN_WITHIN of the view range of ``pose`` is hidden: given up."""
        assert self.coverage is not None
        cov = self.coverage
        near = HIDDEN_WITHIN * cov.view_range
        hidden = {
            k
            for k in cov.unseen(grid, (pose.x, pose.y), radius=near + cov.cell)
            if math.hypot((k[0] + 0.5) * cov.cell - pose.x, (k[1] + 0.5) * cov.cell - pose.y) <= near
        }
        cov.skip(hidden)
        key = cov.key(*target)
        if key not in cov.seen:
            cov.skip({key})

    def _skip_near(self, grid: OccupancyGrid, target: tuple[float, float], xy: tuple[float, float]) -> None:
        """Give up the unseen cells within half the view range of ``target`` (seen from ``xy``'s floor)."""
        assert self.coverage is not None
        cov = self.coverage
        half = cov.view_range / 2.0
        near = {
            k
            for k in cov.unseen(grid, xy, radius=math.dist(xy, target) + cov.view_range)
            if math.hypot((k[0] + 0.5) * cov.cell - target[0], (k[1] + 0.5) * cov.cell - target[1]) <= half
        }
        cov.skip(near | {cov.key(*target)})

    def look_step(self) -> Status:
        """One step: explore while frontiers are left, then look at the floor not yet seen."""
        if not self.frontiers_done:
            status = self.explore_step()
            # a partial exploration (frontiers the map shows a way to were left) or one stuck where
            # the map stopped growing goes on to look at the floor like a complete one (a round of
            # the search is not spent on it); what was left is named in the not-found reason
            partial = status == Status.FAILURE and str(self.failure_reason).startswith(("partial:", "stuck:"))
            if status != Status.SUCCESS and not partial:
                return status
            self.frontiers_done = True
            self.exhausted = False
            self.frontiers_left = self._frontier_places()  # new ones only bring exploring back
            self.explore_end = self.failure_reason if partial else self.feedback_message
            self.failure_reason = ""
            self.emit("search_explored", reason=self.explore_end)
            if not self.params.view_coverage:
                return Status.SUCCESS
        return self._cover()

    def _frontier_places(self, known: list[tuple[float, float]] | None = None) -> list[tuple[float, float]]:
        """The frontiers the planner offers now (their places), less those within 1 m of ``known``."""
        robot = self.context.robot
        grid, stamped = robot.occupancy(), robot.pose()
        if self.planner is None or grid is None or stamped is None:
            return []
        places = [c.target for c in self.planner.candidates(grid, (stamped.pose.x, stamped.pose.y))]
        return [p for p in places if all(math.dist(p, k) > 1.0 for k in known or [])]


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
        self.hfov = frame.intrinsics.hfov
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
        again = self._frontiers_again(pose, now)
        if again is not None:
            return again
        goals = self._next_view_goals(grid, pose)
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
        return self._send_view_goal(goals[0], now)

    def _frontiers_again(self, pose: Pose2D, now: float) -> Status | None:
        """RUNNING when the map grew while looking (a room seen through a door): its frontiers come first."""
        if self.planner is None or self.frontier_rounds >= MAX_FRONTIER_ROUNDS:
            return None
        if not self._frontier_places(self.frontiers_left):
            return None
        self.frontier_rounds += 1
        self.frontiers_done = False
        # the stuck timer restarts: the robot moved and looked meanwhile, unseen by Explore;
        # kept from before the looks, it ended the new round "stuck" at once where it stopped
        self.reset_progress(now, pose)
        self.emit("search_frontiers_again", round=self.frontier_rounds)
        return self.running("new frontiers on the map: exploring on")

    def _next_view_goals(self, grid: OccupancyGrid, pose: Pose2D) -> list[ViewGoal]:
        """Places to look at unseen floor from, in tour order: near the robot first, else on the whole floor.

        Patches no place was found for are given up (counted in ``cover_skipped``).
        """
        assert self.coverage is not None
        p = self.params
        goals: list[ViewGoal] = []
        unplaced: list[set[tuple[int, int]]] = []
        if p.view_window > 0:  # the floor near the robot first: labelled in a window only
            goals, _ = view_goals(self.coverage, grid, (pose.x, pose.y), known_path_lengths,
                                  p.footprint_radius, min_area_m2=p.view_min_area,
                                  cost_rate=p.cost_rate, radius=p.view_window)
        if not goals:
            goals, unplaced = view_goals(self.coverage, grid, (pose.x, pose.y), known_path_lengths,
                                         p.footprint_radius, min_area_m2=p.view_min_area,
                                         cost_rate=p.cost_rate)
        for patch in unplaced:
            self.coverage.skip(patch)
            self.cover_skipped += 1
        return tour_view_goals(grid, goals) if p.order == "tour" else goals

    def _send_view_goal(self, goal: ViewGoal, now: float) -> Status:
        """Drive to a place to look at unseen floor from, facing that floor."""
        yaw = math.atan2(goal.target[1] - goal.y, goal.target[0] - goal.x)
        self.cover_goal = goal
        self.cover_goals += 1
        self.cover_handle = self.context.robot.navigate_to(Pose2D(goal.x, goal.y, yaw),
                                                           Tolerance(0.3, 2.0 * math.pi))
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
        return self.running("looking around")

    def _cover_look(self, grid: OccupancyGrid, pose: Pose2D, now: float) -> Status:
        """The look where the goal was reached (``look``); then what stayed unseen near it is given up."""
        assert self.coverage is not None and self.cover_goal is not None
        if self.arc is None:
            self.arc = self._arc_for(grid, pose, now)
        if self._arc_step(pose, now):
            return self.running("looking at the floor not yet seen")
        self.cover_state = "select"
        # what the camera still has not seen within reach of here is hidden from the floor: given up
        self._skip_hidden(grid, pose, self.cover_goal.target)
        return self.running("looked around")

    def _give_up_view(self, grid: OccupancyGrid, pose: Pose2D, why: str) -> Status:
        """The place to look from was not reached: the unseen cells near its patch's centre are given up."""
        assert self.coverage is not None and self.cover_goal is not None
        goal = self.cover_goal
        self._skip_near(grid, goal.target, (pose.x, pose.y))
        self.cover_skipped += 1
        self.cover_state = "select"
        self.emit("search_view_given_up", x=round(goal.x, 3), y=round(goal.y, 3), reason=why)
        return self.running(f"gave up a place to look from ({why})")
