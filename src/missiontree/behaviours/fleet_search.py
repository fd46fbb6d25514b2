"""Fleet search: the robots of a fleet look for one object together; the first confirmed find ends it for all.

Every robot's copy of ``trees/fleet_find_object.yaml`` runs the single robot's search
(``trees/find_object.yaml``) with three fleet leaves (docs/fleet.md):

- :class:`FleetLocate` is :class:`~missiontree.behaviours.search_locate.Locate` on the fleet's
  merged map (:class:`~missiontree.behaviours.fleet_map.FleetMap`), its exploration goals passing the
  fleet's frontier claims (no two robots on one frontier; a lost robot's claim is released), and the
  floor the cameras have looked at shared (a room one robot's camera covered is not looked at again
  by another). Candidates come from the fleet's one scene graph
  (:class:`~missiontree.behaviours.fleet_scene.FleetBuildSceneGraph`). A robot that has nothing left
  to explore or look at ("not found") waits while other robots still search: they may still open
  frontiers or see the target; the fleet's "not found" is said only when no live robot searches.
- :class:`FleetFound` (after the approach and confirmation): this robot confirmed the target; the
  :class:`SearchBoard` records the find and its finder (``fleet_found``).
- :class:`FleetSearchWatch` (beside the search): SUCCESS as soon as another robot confirmed the
  target ("robot1 found ..."), which halts this robot's search.

Without a fleet (one robot) the leaves are Locate, a plain record of the find, and a watch that never ends.
"""

from __future__ import annotations

import math
from typing import Annotated, Any

from pydantic import BaseModel, Field

from missiontree.behaviours.fleet_map import claim_place, claims_for, fleet_context, lost_reason
from missiontree.behaviours.search_common import rejected_entries
from missiontree.behaviours.search_locate import Locate
from missiontree.engine.context import MissionContext
from missiontree.engine.leaf import Leaf, Status
from missiontree.engine.ports import Input
from missiontree.mapping.exploration import ExplorationPlanner

#: The kind of the entries a fleet robot's Locate sees as rejected for the time of its step only.
HELD = "fleet_held"

__all__ = ["FleetFound", "FleetLocate", "FleetSearchWatch", "SearchBoard", "search_board"]


class SearchBoard:
    """The fleet's search state: who still searches, who gave up and why, the first confirmed find."""

    def __init__(self) -> None:
        self.searching: set[str] = set()
        #: robot -> its "not found" reason.
        self.not_found: dict[str, str] = {}
        self.lost: set[str] = set()
        #: The first confirmed find: {"robot", "t", "x", "y", "label", "id", ...}; None before.
        self.found: dict[str, Any] | None = None
        #: Later confirmations by other robots (the same find, or a second object of the kind).
        self.also: list[dict[str, Any]] = []
        #: robot -> the candidate it is approaching and checking now.
        self.held: dict[str, dict[str, Any]] = {}
        #: Candidates a robot's check rejected as not the target: {"robot", "id", "label", "x", "y", ...}.
        self.rejected: list[dict[str, Any]] = []

    def start(self, robot: str) -> None:
        """``robot`` is searching."""
        if robot not in self.lost:
            self.searching.add(robot)
            self.not_found.pop(robot, None)

    def give_up(self, robot: str, reason: str) -> None:
        """``robot`` has nothing left to explore or look at."""
        self.searching.discard(robot)
        self.not_found[robot] = reason

    def others_searching(self, robot: str) -> list[str]:
        """The other live robots still searching."""
        return sorted(r for r in self.searching if r != robot and r not in self.lost)

    def lose(self, robot: str, reason: str) -> bool:
        """``robot`` is lost: it searches no more, its candidate goes back on offer (True: work taken)."""
        self.lost.add(robot)
        self.searching.discard(robot)
        self.held.pop(robot, None)
        return True

    def hold(self, robot: str, candidate: dict[str, Any] | None) -> None:
        """``robot`` approaches ``candidate`` now (None: none)."""
        if candidate is None or robot in self.lost:
            self.held.pop(robot, None)
        else:
            self.held[robot] = dict(candidate)

    def note_rejected(self, robot: str, entries: list[dict[str, Any]]) -> None:
        """``robot``'s rejections of candidates as not the target (kind ``wrong``), kept once each."""
        known = {(e.get("id"), e.get("robot")) for e in self.rejected}
        for e in entries:
            if e.get("kind", "wrong") == "wrong" and (e.get("id"), robot) not in known:
                self.rejected.append({**e, "robot": robot})

    def ruled_out_for(self, robot: str) -> list[dict[str, Any]]:
        """Candidates ``robot`` should not take: held by another robot, or rejected by another's check."""
        out = [{"id": c.get("id"), "label": c.get("label"), "x": c.get("x"), "y": c.get("y"),
                "reason": f"{other} is checking it", "kind": HELD} for other, c in self.held.items()
               if other != robot and other not in self.lost]
        out += [{**e, "kind": HELD, "reason": f"{e['robot']} rejected it: {e.get('reason', '')}"}
                for e in self.rejected if e.get("robot") != robot]
        return out

    def confirm(self, robot: str, found: dict[str, Any]) -> bool:
        """Record ``robot``'s confirmed find; True when it is the first."""
        if self.found is None:
            self.found = {"robot": robot, **found}
            return True
        self.also.append({"robot": robot, **found})
        return False

    def report(self) -> dict[str, Any]:
        """The find and its finder, who gave up and why (summary.json's fleet section)."""
        return {"found": self.found, "also_confirmed": list(self.also), "not_found": dict(self.not_found),
                "lost": sorted(self.lost), "searching": sorted(self.searching),
                "rejected": [{k: e.get(k) for k in ("robot", "id", "reason")} for e in self.rejected]}


def search_board(context: MissionContext) -> SearchBoard | None:
    """The fleet's search board (made on first use; told of losses); None without a fleet."""
    fleet = context.fleet
    if fleet is None:
        return None

    def make() -> SearchBoard:
        board = SearchBoard()
        fleet.on_loss(board.lose)
        return board

    made: SearchBoard = fleet.shared("search_board", make)
    return made


class FleetLocate(Locate):
    """Locate with the fleet: one merged map, frontiers claimed, camera coverage and scene graph shared."""

    class Params(Locate.Params):
        wait_period: float = Field(
            2.0, gt=0, description="While the others still search and this robot has nothing left, look "
            "again this often (s).")
        max_pose_age: float = Field(
            10.0, gt=0, description="Fail (the robot is lost) when its pose is older than this (s).")

    params: Params

    def __init__(self, name: str, params: BaseModel | None = None) -> None:
        super().__init__(name, params)
        self.waiting_until = -math.inf

    def on_setup(self) -> None:
        """Locate's setup on the fleet's map; the camera's coverage shared by the fleet."""
        super().on_setup()
        if self.ctx is None or self.ctx.fleet is None:
            return
        self.ctx = fleet_context(self.ctx)
        mine = self.coverage
        self.coverage = self.ctx.fleet.shared("view_coverage", lambda: mine)

    def make_planner(self) -> ExplorationPlanner:
        """Locate's planner (kept across rounds), its candidates passing the fleet's claims."""
        planner = super().make_planner()
        claims = claims_for(self.context, self.params.sensor_range)
        return claims.wrap(planner, self.context.robot.name) if claims is not None else planner

    def initialise(self) -> None:
        """Locate's start; this robot counts as searching."""
        super().initialise()
        self.waiting_until = -math.inf
        board = search_board(self.context)
        if board is not None:
            board.start(self.context.robot.name)
            board.hold(self.context.robot.name, None)  # a new round: the last candidate was checked

    def update(self) -> Status:
        """Locate's step, the goal in hand claimed; 'not found' waits while other robots search."""
        robot = self.context.robot
        board = search_board(self.context)
        if board is None:
            return super().update()
        now = robot.now()
        lost = lost_reason(robot, self.handle, self.params.max_pose_age)
        if lost:  # its claim stays until the fleet releases it (fleet_claim_released)
            return self.fail(f"robot lost: {lost}")
        if now < self.waiting_until:
            return self.running(self.feedback_message)
        status = self._step_with(board)
        self._claim(self.target.target if self.handle is not None and self.target is not None else None)
        if status is Status.FAILURE and self.failure_reason.startswith("not found"):
            board.give_up(robot.name, self.failure_reason)
            others = board.others_searching(robot.name)
            if others:
                self.waiting_until = now + self.params.wait_period
                stamped = robot.pose()
                self.reset_progress(now, stamped.pose if stamped is not None else None)
                return self.running(f"nothing left for this robot to look at; waiting while "
                                    f"{', '.join(others)} search{'es' if len(others) == 1 else ''}")
            return status
        if status is Status.SUCCESS:
            board.start(robot.name)
            board.hold(robot.name, self.read("candidate", None))
        return status

    def _step_with(self, board: SearchBoard) -> Status:
        """Locate's step with the candidates others hold or rejected ruled out (for this step only)."""
        name = self.context.robot.name
        mine = [e for e in rejected_entries(self.read("rejected", [])) if e.get("kind") != HELD]
        board.note_rejected(name, mine)
        self.write("rejected", mine + board.ruled_out_for(name))
        try:
            return super().update()
        finally:
            self.write("rejected", [e for e in rejected_entries(self.read("rejected", []))
                                    if e.get("kind") != HELD])

    def terminate(self, new_status: Status) -> None:
        """Locate's end; the claim handed back (a lost robot's is released by the fleet)."""
        if not self.failure_reason.startswith("robot lost"):
            self._claim(None)
        super().terminate(new_status)

    def _claim(self, place: tuple[float, float] | None) -> None:
        claim_place(self.ctx, self.params.sensor_range, place, self.target)


class FleetFound(Leaf):
    """This robot confirmed the target: record the find for the fleet (``fleet_found``); SUCCESS."""

    class Params(BaseModel):
        candidate: Annotated[str, Input("the candidate confirmed: id, label, colour, x, y", type="dict")] = (
            "search_candidate")

    params: Params

    def update(self) -> Status:
        """Record the find on the fleet's board; SUCCESS naming the finder."""
        robot = self.context.robot
        seen = self.read("candidate", {}) or {}
        found = {"t": round(robot.now(), 2), "id": seen.get("id"), "label": seen.get("label"),
                 "colour": seen.get("colour"), "x": seen.get("x"), "y": seen.get("y")}
        board = search_board(self.context)
        first = board.confirm(robot.name, found) if board is not None else True
        self.emit("fleet_found", finder=robot.name, first=first, **found)
        self.context.report("fleet_search", board.report() if board is not None
                            else {"found": {"robot": robot.name, **found}})
        where = _where(found)
        if first:
            what = " ".join(str(w) for w in (found["colour"], found["label"]) if w)
            return self.succeed(f"found by {robot.name}: {what}{where}")
        assert board is not None and board.found is not None
        return self.succeed(f"{robot.name} confirmed it too; {board.found['robot']} found it first{where}")


class FleetSearchWatch(Leaf):
    """RUNNING until another robot of the fleet confirmed the target; then SUCCESS naming the finder."""

    class Params(BaseModel):
        pass

    def update(self) -> Status:
        """SUCCESS once another robot's find is on the board (never without a fleet)."""
        board = search_board(self.context)
        if board is None or board.found is None or board.found["robot"] == self.context.robot.name:
            return self.running("searching")
        found = board.found
        self.emit("fleet_search_ended", finder=found["robot"])
        what = " ".join(str(w) for w in (found.get("colour"), found.get("label")) if w)
        return self.succeed(f"{found['robot']} found the {what}{_where(found)}; this robot's search ended")


def _where(found: dict[str, Any]) -> str:
    x, y = found.get("x"), found.get("y")
    return f" at ({x:.2f}, {y:.2f})" if isinstance(x, int | float) and isinstance(y, int | float) else ""
