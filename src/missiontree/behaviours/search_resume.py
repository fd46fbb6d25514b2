"""The search's exploration kept across its rounds (ResumeExplore); frontiers ranked by the priors.

- :class:`ResumeExplore`: the ``Explore`` leaf kept across the rounds of a search (visited goals and
  blacklist survive a retry); it may stop after each goal reached (the report's MOVING_TO_SCAN: one
  scan point at a time) and fail "not found" once nothing is left. A goal given up on a half-learned
  map (a doorway judged blocked while its jambs were still unknown) is offered once more when the map
  around it has grown since, or the map now places its frontier's goal elsewhere.
- :class:`PriorPlanner`: the exploration planner whose frontiers are re-scored by where the target is
  likely, their goals moved off obstacles so the robot has room there.

``ResumeExplore`` uses ``Explore`` through its public interface only (``make_planner``,
``select_goal``, the ``on_goal_reached`` / ``on_give_up`` hooks, ``summary``).

Tick-log events: ``explore_retry``, ``explore_second_chance`` (and Explore's).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import cv2
import numpy as np
from pydantic import BaseModel, Field

from missiontree.behaviours.explore import Explore
from missiontree.engine.leaf import Status
from missiontree.mapping.exploration import Blacklisted, ExplorationPlanner
from missiontree.mapping.exploration import Candidate as Frontier
from missiontree.mapping.grid import free_mask, occupied_mask, unknown_mask
from missiontree.types import OccupancyGrid, Pose2D

#: Known area (m^2) counted around a goal given up, to tell whether the map there has grown since.
AROUND_M = 1.5
#: A retried goal's new place must lie this far (m) from the one given up, when the map did not grow.
MOVED_M = 0.1
#: How far (m) a frontier goal too near an obstacle may be moved to give the robot room.
NUDGE_M = 0.6


class PriorPlanner(ExplorationPlanner):
    """Exploration candidates re-scored by where the target is likely: score x (1 + weight x prior).

    A frontier goal nearer an obstacle than the robot's radius plus margin (on a half-learned map a
    doorway's goal often lands beside a jamb seen later; the navigation stack refuses such a goal)
    is moved to the nearest known-free cell within :data:`NUDGE_M` that has that room.

    The search looks with a camera: with :attr:`camera_unseen` set, a frontier's gain counts the
    floor the camera has not looked at near its goal beside the unknown area, and with :attr:`views`
    places from which such floor near the robot is looked at (kind ``view``) compete with the
    frontiers on the same gain-per-path score. Floor the lidar mapped and the camera never saw was
    otherwise gone to last, across the whole floor again. A goal in hand is left only for a clearly
    better one that is no farther away (:meth:`better`): no going back and forth between far goals.
    The candidates are offered in the planner's ``order`` after the prior: with ``tour``, the tour
    reaching the most prior-weighted gain soonest (:mod:`missiontree.mapping.tour`).
    """

    def __init__(self, bias: Any, weight: float, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.bias = bias
        self.weight = weight
        #: held(grid, x, y): whether a frontier place the lidar has seen still waits for the camera.
        self.held: Callable[[OccupancyGrid, float, float], bool] | None = None
        #: Set by the leaf while a goal is being driven to: that goal (it may be held).
        self.hold_active = False
        self.driving: Frontier | None = None
        #: camera_unseen(grid, x, y): floor (m^2) the camera has not looked at near a goal.
        self.camera_unseen: Callable[[OccupancyGrid, float, float], float] | None = None
        #: views(grid, robot_xy): places to look at unseen floor near the robot from (kind "view").
        self.views: Callable[[OccupancyGrid, tuple[float, float]], list[Frontier]] | None = None
        self._reach_mode = False

    def still_frontier(self, grid: OccupancyGrid, x: float, y: float, radius: float = 0.3) -> bool:
        """The lidar's answer; while driving, a place the camera has not looked at yet still counts.

        The search's coverage is the camera's: dropping a goal once the lidar had mapped its frontier
        (4 m ahead, before the camera came within range of that floor) sent the robot to another
        frontier and back for it later. Only the re-plan's test (at the blacklist's radius) is held;
        a goal reached or failed is judged by the lidar alone (its tries, its blacklisting).
        """
        if super().still_frontier(grid, x, y, radius):
            return True
        if not self.hold_active or self.held is None or radius < self.blacklist_radius:
            return False
        return bool(self.held(grid, x, y))

    def candidates(
        self, grid: Any, robot_xy: tuple[float, float], *args: Any, **kwargs: Any
    ) -> list[Frontier]:
        """The planner's candidates (goals given room), best first after the prior (options passed on).

        While driving, the goal driven to stays on offer (last) when the lidar has mapped its
        frontier but the camera has not looked there yet (:attr:`held`).
        """
        if args or kwargs:  # ignore_blacklist: super() comes back here for the ranking itself
            return super().candidates(grid, robot_xy, *args, **kwargs)
        found = super().candidates(grid, robot_xy, ordered=False)
        kept = [self.driving] if self._still_held(grid, found) and self.driving is not None else []
        looking = not self._reach_mode and self.strategy == "gain"
        if looking and self.camera_unseen is not None and found:
            found = [_with_camera_gain(c, self.camera_unseen(grid, c.x, c.y)) for c in found]
        views = self.views(grid, robot_xy) if looking and self.views is not None else []
        if not found and not views:
            return kept
        room = self.footprint_radius + self.goal_margin
        clear = clearance_map(grid) if found else None
        found = [_with_room(c, grid, clear, room) for c in found] if clear is not None else []
        found += views
        if self.weight > 0:
            found = [replace(c, score=c.score * (1.0 + self.weight * self.bias(c))) for c in found]
        if self.weight > 0 or views:
            found = sorted(found, key=lambda c: -c.score)
        if not self._reach_mode:
            found = self.in_order(grid, robot_xy, found)
        return found + kept

    def reach_candidates(self, grid: OccupancyGrid, robot_xy: tuple[float, float]) -> list[Frontier]:
        """The frontiers as the navigation's footprint sees them (no places to look from)."""
        self._reach_mode = True
        try:
            return super().reach_candidates(grid, robot_xy)
        finally:
            self._reach_mode = False

    def better(self, best: Frontier, current: Frontier | None, margin: float = 1.3) -> bool:
        """Leave the goal in hand only for a clearly better one no farther away (by path, +1 m).

        Two far goals scoring alike in turn (the prior and the camera's gain shifting as the robot
        drives) sent the robot 14 m one way and back again along an L corridor.
        """
        if current is None:
            return True
        return super().better(best, current, margin) and best.path_m <= current.path_m + 1.0

    def _still_held(self, grid: OccupancyGrid, found: list[Frontier]) -> bool:
        """Whether the goal driven to is gone from the lidar's frontiers but waits for the camera."""
        kept = self.driving
        if not self.hold_active or kept is None or kept.kind != "frontier" or self.held is None:
            return False
        if any(math.dist((c.x, c.y), (kept.x, kept.y)) <= 0.5 for c in found):
            return False
        return bool(self.held(grid, *kept.target))


def _with_camera_gain(c: Frontier, unseen_m2: float) -> Frontier:
    """``c`` with the camera's unseen floor near its goal added to its gain (its score scaled to match)."""
    if unseen_m2 <= 0 or c.kind != "frontier":
        return c
    gain = c.gain_m2 + unseen_m2
    scale = gain / c.gain_m2 if c.gain_m2 > 0 else 1.0
    return replace(c, gain_m2=gain, score=c.score * scale)


def clearance_map(grid: OccupancyGrid) -> np.ndarray:
    """Distance (m) of every cell to the nearest occupied cell."""
    occupied = occupied_mask(grid)
    return cv2.distanceTransform((~occupied).astype(np.uint8), cv2.DIST_L2, 5) * grid.resolution


def clearance_at(grid: OccupancyGrid, clear: np.ndarray, x: float, y: float) -> float:
    """Distance (m) from (x, y) to the nearest occupied cell (inf off the map)."""
    r, c = grid.world_to_cell(x, y)
    h, w = clear.shape
    return float(clear[r, c]) if 0 <= r < h and 0 <= c < w else math.inf


def _with_room(c: Frontier, grid: OccupancyGrid, clear: np.ndarray | None, room: float) -> Frontier:
    """``c`` with its goal moved to the nearest free cell within NUDGE_M that keeps ``room`` (m)."""
    if clear is None or c.kind != "frontier" or clearance_at(grid, clear, c.x, c.y) >= room:
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
        # the search's default (Explore's: 1.0 m^2). The scan point erosion stays Explore's 0.5 m:
        # 0.4 m left a 0.9 m door open, so the office was one region and the report's tree one round
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
