"""What a fleet's exploring and searching robots share: one map fed by every lidar, and frontier claims.

- :class:`FleetMap` (``context.fleet.shared("fleet_map", ...)``): every robot's learned map merged
  into one occupancy grid, recomputed only when some robot's map changed. A cell is known when any
  robot knows it; it is occupied when more robots read it occupied than free (a robot seen by
  another's lidar is an obstacle in that map only until the other one drives through the spot).
  Each robot still *navigates* on its own learned map (unknown cells traversable, as Nav2 does on a
  SLAM map): the merged map decides where to go and when the fleet is done, not how to drive.
- :class:`FleetRobot`: the robot a fleet leaf sees -- its own robot, but ``occupancy()`` is the
  fleet's merged map.
- :class:`FrontierClaims` (``context.fleet.shared("frontier_claims", ...)``): the auction. A robot
  that sends a goal claims its frontier place; the others' candidates within ``claim_radius`` of a
  claim are dropped (no two robots on one frontier) and those within ``sensor_range`` of one are
  discounted by how much their views would overlap (the utility reduction of coordinated
  exploration), so the robots spread out. Each robot takes its best remaining candidate by its own
  rule (gain against path cost, or the nearest by path). A lost robot's claim is released
  (``fleet_claim_released``) and its frontier goes back on offer.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import replace
from typing import Any

import numpy as np

from missiontree.behaviours.motion import robot_lost
from missiontree.engine.context import MissionContext
from missiontree.mapping.exploration import Candidate, ExplorationPlanner
from missiontree.robot.actions import INFRASTRUCTURE, ActionHandle
from missiontree.types import OccupancyGrid, Pose2D

__all__ = ["FleetMap", "FleetRobot", "FrontierClaims", "claims_for", "fleet_context", "lost_reason",
           "merge_grids"]

#: A map cell at or above this value counts as occupied when maps are merged.
OCCUPIED_FROM = 50


def merge_grids(grids: list[OccupancyGrid]) -> OccupancyGrid:
    """One grid over all of ``grids`` (same resolution): known where any is, occupied by majority.

    Grids may have different origins and sizes (a learned map grows when a scan reaches past it);
    the result covers their union.
    """
    if len(grids) == 1:
        return grids[0]
    res = grids[0].resolution
    ox = min(g.origin.x for g in grids)
    oy = min(g.origin.y for g in grids)
    placed = []
    rows = cols = 0
    for g in grids:
        if not math.isclose(g.resolution, res, rel_tol=1e-6):
            raise ValueError(f"maps of different resolutions cannot be merged ({g.resolution} vs {res})")
        r0 = int(round((g.origin.y - oy) / res))
        c0 = int(round((g.origin.x - ox) / res))
        placed.append((r0, c0, g.data))
        rows = max(rows, r0 + g.data.shape[0])
        cols = max(cols, c0 + g.data.shape[1])
    occupied = np.zeros((rows, cols), np.int16)
    free = np.zeros((rows, cols), np.int16)
    for r0, c0, data in placed:
        window = (slice(r0, r0 + data.shape[0]), slice(c0, c0 + data.shape[1]))
        occupied[window] += data >= OCCUPIED_FROM
        free[window] += (data >= 0) & (data < OCCUPIED_FROM)
    merged = np.full((rows, cols), -1, np.int8)
    merged[free > 0] = 0
    merged[occupied > free] = 100
    merged.flags.writeable = False
    return OccupancyGrid(max(g.stamp for g in grids), res, Pose2D(ox, oy, 0.0), merged)


class FleetMap:
    """Every robot's learned map, merged on demand (see module doc)."""

    def __init__(self) -> None:
        self.robots: dict[str, Any] = {}
        self._inputs: tuple[OccupancyGrid, ...] = ()
        self._merged: OccupancyGrid | None = None
        #: How often the merged map was recomputed (cost accounting for the benchmark).
        self.merges = 0

    def add(self, name: str, robot: Any) -> None:
        """Feed ``robot``'s map (its ``occupancy()``) into the fleet's map from now on."""
        self.robots[name] = robot

    def grid(self) -> OccupancyGrid | None:
        """The merged map now (None while no robot has a map)."""
        grids = tuple(g for g in (r.occupancy() for r in self.robots.values()) if g is not None)
        if not grids:
            return None
        if len(grids) != len(self._inputs) or any(a is not b for a, b in zip(grids, self._inputs)):  # noqa: B905
            self._inputs = grids
            self._merged = merge_grids(list(grids))
            self.merges += 1
        return self._merged


class FleetRobot:
    """A robot whose ``occupancy()`` is the fleet's merged map; everything else is its own."""

    def __init__(self, robot: Any, fleet_map: FleetMap) -> None:
        self._robot = robot
        self._map = fleet_map

    def occupancy(self) -> OccupancyGrid | None:
        """The fleet's map (every robot's lidar)."""
        return self._map.grid()

    def own_occupancy(self) -> OccupancyGrid | None:
        """This robot's own learned map."""
        return self._robot.occupancy()

    def __getattr__(self, name: str) -> Any:
        return getattr(self._robot, name)


class _FleetContext:
    """A mission context whose ``robot`` is a :class:`FleetRobot`; all else is the robot's own context."""

    def __init__(self, inner: MissionContext, robot: FleetRobot) -> None:
        object.__setattr__(self, "_inner", inner)
        object.__setattr__(self, "robot", robot)

    def __getattr__(self, name: str) -> Any:
        return getattr(self._inner, name)

    def __setattr__(self, name: str, value: Any) -> None:
        setattr(self._inner, name, value)  # context.scene set by a scene builder: seen by all leaves

    def mark(self, kind: str, x: float, y: float, label: str = "") -> None:
        """The robot's own context's marker."""
        self._inner.mark(kind, x, y, label)


def fleet_context(context: MissionContext) -> MissionContext:
    """``context`` with the fleet's merged map as the robot's map (``context`` itself without a fleet)."""
    if context.fleet is None or isinstance(context, _FleetContext):
        return context
    robot = context.robot
    fleet_map: FleetMap = context.fleet.shared("fleet_map", FleetMap)
    fleet_map.add(robot.name, robot)
    return _FleetContext(context, FleetRobot(robot, fleet_map))  # type: ignore[return-value]


class FrontierClaims:
    """Which robot is heading for which place; candidates filtered and discounted by others' claims.

    Args:
        claim_radius: A candidate this close (m) to another robot's claim is not offered.
        sensor_range: Views this far apart overlap (m); a candidate's score is discounted by the
            overlap with the nearest other claim.
        overlap_discount: The discount at full overlap (0: none, 1: the whole score).
        emit: Fleet-level event sink (``fleet_claim_released``).
    """

    def __init__(self, claim_radius: float = 1.0, sensor_range: float = 4.0, overlap_discount: float = 0.6,
                 emit: Callable[..., None] | None = None) -> None:
        self.claim_radius = claim_radius
        self.sensor_range = sensor_range
        self.overlap_discount = overlap_discount
        self.emit = emit
        #: robot -> the place (x, y) it is heading for.
        self.claims: dict[str, tuple[float, float]] = {}
        self.lost: set[str] = set()
        #: Claims handed back by lost robots: {"robot", "x", "y"}.
        self.released: list[dict[str, Any]] = []

    def claim(self, robot: str, place: tuple[float, float] | None) -> None:
        """``robot`` heads for ``place`` now (None: for nothing)."""
        if robot in self.lost:
            return
        if place is None:
            self.claims.pop(robot, None)
        else:
            self.claims[robot] = (float(place[0]), float(place[1]))

    def others(self, robot: str) -> list[tuple[float, float]]:
        """The places the other (live) robots claim."""
        return [p for r, p in self.claims.items() if r != robot and r not in self.lost]

    def busy_others(self, robot: str) -> list[str]:
        """The other robots holding a claim."""
        return [r for r in self.claims if r != robot and r not in self.lost]

    def release(self, robot: str, reason: str) -> bool:
        """``robot`` is lost: its claim goes back on offer. True: the others take its work."""
        self.lost.add(robot)
        place = self.claims.pop(robot, None)
        if place is not None:
            entry = {"robot": robot, "x": round(place[0], 3), "y": round(place[1], 3)}
            self.released.append(entry)
            if self.emit is not None:
                self.emit("fleet_claim_released", reason=reason, **entry)
        return True

    def filter(self, robot: str, found: list[Candidate]) -> list[Candidate]:
        """``found`` without others' claimed places, discounted near them, best first again."""
        taken = self.others(robot)
        if not taken:
            return found
        kept = []
        for c in found:
            near = min(_near(c, p) for p in taken)
            if near <= self.claim_radius:
                continue
            overlap = max(0.0, 1.0 - near / self.sensor_range) if self.sensor_range > 0 else 0.0
            kept.append(replace(c, score=c.score - abs(c.score) * self.overlap_discount * overlap))
        kept.sort(key=lambda c: -c.score)
        return kept

    def wrap(self, planner: ExplorationPlanner, robot: str) -> ExplorationPlanner:
        """``planner`` whose ``candidates`` leave out and discount the others' claims (once per planner)."""
        if getattr(planner, "_fleet_claims", None) is self:
            return planner
        plain = planner.candidates

        def candidates(grid: OccupancyGrid, robot_xy: tuple[float, float], *args: Any,
                       **kwargs: Any) -> list[Candidate]:
            return self.filter(robot, plain(grid, robot_xy, *args, **kwargs))

        setattr(planner, "candidates", candidates)  # noqa: B010 -- an instance's method, composed
        setattr(planner, "_fleet_claims", self)  # noqa: B010
        return planner

    def report(self) -> dict[str, Any]:
        """The claims now and those released by lost robots (the summary's dispatcher section)."""
        return {"claims": {r: [round(p[0], 3), round(p[1], 3)] for r, p in self.claims.items()},
                "lost": sorted(self.lost), "released": list(self.released)}


def _near(c: Candidate, place: tuple[float, float]) -> float:
    """Distance from a candidate (its goal or the place it is to see, the nearer) to ``place``."""
    d_goal = math.hypot(c.x - place[0], c.y - place[1])
    tx, ty = c.target
    if math.isnan(tx):
        return d_goal
    return min(d_goal, math.hypot(tx - place[0], ty - place[1]))


def claims_for(context: MissionContext, sensor_range: float) -> FrontierClaims | None:
    """The fleet's frontier claims (made on first use, released on a robot's loss); None without a fleet."""
    fleet = context.fleet
    if fleet is None:
        return None

    def make() -> FrontierClaims:
        events = fleet.events
        claims = FrontierClaims(sensor_range=sensor_range,
                                emit=events.emit if events is not None else None)
        fleet.on_loss(claims.release)
        return claims

    made: FrontierClaims = fleet.shared("frontier_claims", make)
    return made


def claim_place(context: MissionContext | None, sensor_range: float, place: tuple[float, float] | None,
                target: Candidate | None) -> None:
    """Claim ``place`` for the context's robot (None hands its claim back; no fleet: nothing).

    A place whose x is NaN (a goal without a frontier of its own) is claimed at ``target``, where
    the robot is heading.
    """
    if context is None:
        return
    claims = claims_for(context, sensor_range)
    if claims is None:
        return
    if place is not None and math.isnan(place[0]) and target is not None:
        place = (target.x, target.y)
    claims.claim(context.robot.name, place)


def lost_reason(robot: Any, handle: ActionHandle | None, max_pose_age: float) -> str:
    """Why a fleet robot counts as lost now ("" when not).

    Its goal ended for want of the machinery (an infrastructure result: killed, the action server
    gone), or its pose is older than ``max_pose_age`` s.
    """
    if handle is not None and handle.status().done:
        result = handle.result()
        if result is not None and result.kind == INFRASTRUCTURE:
            return f"its goal ended: {result.reason or handle.status().value}"
    return robot_lost(robot, max_pose_age)
