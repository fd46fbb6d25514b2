"""FleetExplore: one robot's share of a fleet exploring one unknown place together (docs/fleet.md).

Every robot's copy of the tree holds a FleetExplore leaf. It is
:class:`~missiontree.behaviours.explore.Explore` (the same planner, goals, re-plans, tries and
honest ends) with two things shared through ``context.fleet``:

- the map it plans on is the fleet's (:class:`~missiontree.behaviours.fleet_map.FleetMap`: every
  robot's lidar), so a room one robot has seen is no frontier for another;
- its candidates pass the fleet's frontier claims
  (:class:`~missiontree.behaviours.fleet_map.FrontierClaims`): a place another robot heads for is
  not offered, places near it are discounted, and the goal this robot sends is claimed
  (``fleet_claim``).

The fleet is done only when no reachable frontier is left for *any* robot: a robot that finds
nothing left for itself while others still hold claims waits (RUNNING, re-checking every
``wait_period`` s) -- those robots may still open new frontiers, or be lost and hand theirs back.
Its end is then Explore's: SUCCESS "explored" when nothing reachable is left, FAILURE "partial: ..."
when frontiers were given up while the map shows a way. A robot whose pose stops coming (killed,
the machinery gone) fails "robot lost": the fleet records it and its claim is released.
Without a fleet (one robot) it is Explore.
"""

from __future__ import annotations

import math

from pydantic import BaseModel, Field

from missiontree.behaviours.explore import Explore
from missiontree.behaviours.fleet_map import claim_place, claims_for, fleet_context, lost_reason
from missiontree.engine.leaf import Status
from missiontree.mapping.exploration import ExplorationPlanner

__all__ = ["FleetExplore"]


class FleetExplore(Explore):
    """Explore with the fleet: one merged map, frontiers claimed, done when none is left for any robot."""

    class Params(Explore.Params):
        wait_period: float = Field(
            2.0, gt=0, description="While the others hold every frontier left, look again this often (s).")
        max_pose_age: float = Field(
            10.0, gt=0, description="Fail (the robot is lost) when its pose is older than this (s).")

    params: Params

    def __init__(self, name: str, params: BaseModel | None = None) -> None:
        super().__init__(name, params)
        self.waiting_until = -math.inf
        self.waits = 0

    def on_setup(self) -> None:
        """Plan on the fleet's merged map (the robot's own context without a fleet)."""
        super().on_setup()
        if self.ctx is not None:
            self.ctx = fleet_context(self.ctx)

    def make_planner(self) -> ExplorationPlanner:
        """Explore's planner, its candidates passing the fleet's claims."""
        planner = super().make_planner()
        claims = claims_for(self.context, self.params.sensor_range)
        return claims.wrap(planner, self.context.robot.name) if claims is not None else planner

    def initialise(self) -> None:
        """Explore's start; not waiting."""
        super().initialise()
        self.waiting_until = -math.inf

    def update(self) -> Status:
        """Explore's step; the goal in hand claimed; 'nothing left' waits while others hold claims."""
        robot = self.context.robot
        now = robot.now()
        lost = lost_reason(robot, self.handle, self.params.max_pose_age) if self.context.fleet else ""
        if lost:  # its claim stays until the fleet releases it (fleet_claim_released)
            return self.fail(f"robot lost: {lost}")
        if now < self.waiting_until:
            return self.running(self.feedback_message)
        status = super().update()
        claims = claims_for(self.context, self.params.sensor_range)
        if claims is None:
            return status
        self._claim(self.target.target if self.handle is not None and self.target is not None else None)
        finished = status is Status.SUCCESS or (status is Status.FAILURE and self.outcome == "partial"
                                                and not self.time_budget_spent)
        busy = claims.busy_others(robot.name)
        if finished and busy:
            self.waits += 1
            self.waiting_until = now + self.params.wait_period
            stamped = robot.pose()
            self.reset_progress(now, stamped.pose if stamped is not None else None)
            self.outcome = "stopped"
            return self.running(f"nothing left for this robot; waiting while {', '.join(busy)} "
                                f"explore{'s' if len(busy) == 1 else ''}")
        return status

    def terminate(self, new_status: Status) -> None:
        """Explore's end; the claim handed back (a lost robot's is released by the fleet)."""
        if not self.failure_reason.startswith("robot lost"):
            self._claim(None)
        super().terminate(new_status)

    def _claim(self, place: tuple[float, float] | None) -> None:
        claim_place(self.ctx, self.params.sensor_range, place, self.target)
