"""Where to look next in the search: Locate, a candidate of the target or exploration until one is seen.

:class:`Locate` gives a candidate of the target from what is known -- the live semantic map that
``BuildSceneGraph`` fuses every frame into (a candidate seen once is not forgotten when the robot
turns away) or a loaded scene graph -- else explores, frontiers ordered by where the target is likely
(:mod:`missiontree.reasoning.search_priors`: a cup -> kitchen first) and by their gain, until a
candidate appears; once no frontier is left (or the exploration ended partial), it goes to look at
the reachable floor the camera has not had in view, back to frontiers that appear meanwhile
(:mod:`~missiontree.behaviours.search_look`). A candidate that could not be reached is offered once
more when nothing is left to explore or look at. FAILURE "not found" when the reachable space is
explored and looked at and no candidate is left, or the time budget is spent.

The exploration it builds on lives beside it: :mod:`~missiontree.behaviours.search_resume`
(``ResumeExplore``, kept across the search's rounds; ``PriorPlanner``) and
:mod:`~missiontree.behaviours.search_look` (``LookExplore``, the look at the unseen floor); both are
importable from here.

Tick-log events: ``search_candidate``, ``search_priors`` (whose ranking of the rooms is used: the
language model's, or the offline table's and why), ``search_time_budget`` (and those of
``LookExplore``, ``ResumeExplore`` and ``Explore``).
"""

from __future__ import annotations

import math
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import BaseModel, Field

from missiontree.behaviours.intent import find_scene_graph
from missiontree.behaviours.search_common import REJECT_RADIUS, read_target, rejected_entries
from missiontree.behaviours.search_look import LookExplore
from missiontree.behaviours.search_resume import PriorPlanner, ResumeExplore
from missiontree.engine.leaf import Status
from missiontree.engine.ports import Output
from missiontree.errors import MissionTreeError
from missiontree.mapping.exploration import Candidate as Frontier
from missiontree.mapping.exploration import ExplorationPlanner
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

__all__ = ["Locate", "LookExplore", "PriorPlanner", "ResumeExplore"]

#: An instance whose colour the semantic map's majority vote settled over this many frames is not
#: looked at closer for another colour (when nothing else is left, ones seen in fewer frames are).
TRUSTED_COLOUR_FRAMES = 10
#: A candidate that could not be reached comes back (at most UNREACHED_AGAIN times) once the known map
#: within UNREACHED_NEAR_M of it grew by UNREACHED_GROWTH_M2 since it was last offered.
UNREACHED_NEAR_M = 1.0
UNREACHED_GROWTH_M2 = 1.0
UNREACHED_AGAIN = 2


class Locate(LookExplore):
    """A candidate of the target: from the semantic map or a loaded graph, else explore where it is likely.

    SUCCESS with ``search_candidate`` written as soon as an object of the target's class that was
    not rejected is known (colour matches first, then colour unknown: a glimpse, a place where the
    detector saw the class a few times without it becoming an object, is approached for a closer
    look like an object of unknown colour). Otherwise explores (frontiers
    by gain, weighted by the room priors) until one is seen. When nothing is left to explore, a
    candidate rejected only because it could not be reached is offered once more (the map has grown
    since), and objects of the class whose other colour rests on fewer than
    :data:`TRUSTED_COLOUR_FRAMES` frames are looked at; FAILURE "not found" when none is left.
    """

    class Params(LookExplore.Params):
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
        approach_time: float = Field(
            40.0,
            ge=0,
            description="With a time budget: seconds after it by which an approach must have reached its "
            "candidate (the candidate's `deadline`; Approach gives it up after), so the mission ends with "
            "a verdict inside its limit.",
        )
        max_candidates: int = Field(
            0,
            ge=0,
            description="Candidates offered before the verdict 'not found' names them (0: no limit); set it "
            "below the enclosing Retry's attempts, so a search out of candidates ends with this verdict.",
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
        #: id of a candidate rejected as unreached -> (known m^2 near it when last offered, times again)
        self.unreached_known: dict[str, tuple[float, int]] = {}
        self.base_replan: float | None = None
        self.first_start: float | None = None
        self.budget_spent = False
        self.offered = 0

    def on_setup(self) -> None:
        """Read the target against the detector's classes and load the graph file, if any."""
        # py_trees' blackboard outlives a mission in the same process (batch runs, benchmarks): the
        # rejected candidates start empty with each mission, never inherited from another one.
        self.write("rejected", [])
        super().on_setup()
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
        if self.first_start is None:
            self.first_start = self.context.robot.now()
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
        if self.params.max_candidates and self.offered >= self.params.max_candidates:
            return self._not_found()
        found = self._pick(with_mismatch=self.exhausted and not self.budget_spent)
        if found is not None:
            return self._found(found)
        if self.exhausted:
            return self._not_found()
        if self._out_of_time():
            return self._exhausted()
        if not self.frontiers_done:
            self._scale_replan()
        status = self.look_step()
        if status == Status.FAILURE:
            what = self.goal.text if self.goal else "?"
            return self.fail(f"searching for the {what}: {self.failure_reason}")
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
            self.stop_looking()
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

    def _exhausted(self) -> Status:
        """Nothing left to explore or look at: a candidate once more, or not found."""
        self.exhausted = True
        found = self._pick(with_mismatch=not self.budget_spent)
        return self._found(found) if found is not None else self._not_found()

    def _found(self, found: dict[str, Any]) -> Status:
        if found.pop("again", False):
            self.offered_again.add(str(found["id"]))
        grown = found.pop("grown", None)
        if grown is not None:
            self.unreached_known[str(found["id"])] = grown
        self.offered += 1
        if self.params.time_budget and self.first_start is not None:
            end = self.first_start + self.params.time_budget + self.params.approach_time
            found["deadline"] = round(end, 1)
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
        if self.params.max_candidates and self.offered >= self.params.max_candidates:
            known += f"; {self.offered} candidates were looked at, the most offered"
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
        return self.fail(  # a verdict: running the search again only repeats it
            f"not found: no {self.goal.text} in the reachable space explored{known}"
            + (f" ({len(tried)} candidates rejected: {shown})" if tried else ""),
            verdict=True,
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
        scene = self.ctx.scene if self.ctx is not None else None
        for inst in list(scene.map) if scene is not None else []:
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
        for label, x, y in list(scene.doubtful) if scene is not None else []:
            # seen a few times, not made an object (far, oblique, brief): a closer look decides
            if fold_label(label) != fold_label(goal.label):
                continue
            entry = {
                "id": f"glimpse_{label}_{x:.1f}_{y:.1f}",
                "label": label,
                "colour": "unknown",
                "x": round(float(x), 3),
                "y": round(float(y), 3),
                "source": "glimpse",
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
            grown = self._unreached_grown(entry)
            if grown is not None:
                entry = {**entry, "grown": grown}
            elif not self.exhausted or self.budget_spent or str(entry["id"]) in self.offered_again:
                return -1, 0.0, entry
            else:
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

    def _unreached_grown(self, entry: dict[str, Any]) -> tuple[float, int] | None:
        """(known m^2 near it, times offered again) when an unreached candidate's surroundings grew.

        A candidate seen in space not yet mapped ("outside the known map") is unreachable only
        until the map reaches it: on a large floor the robot mapped it moments later, a metre
        away, and it was never offered again before the time budget ended the search.
        """
        grid = self.last_grid
        if grid is None:
            return None
        key = str(entry["id"])
        known = known_near(grid, float(entry["x"]), float(entry["y"]), UNREACHED_NEAR_M)
        before, times = self.unreached_known.setdefault(key, (known, 0))
        if times >= UNREACHED_AGAIN or known - before < UNREACHED_GROWTH_M2:
            return None
        return known, times + 1

    def _prior(self, frontier: Frontier) -> float:
        """Likelihood of the target beyond a frontier: its room's type and the objects seen near it."""
        if not self.priors:
            return 0.0
        scene = self.ctx.scene if self.ctx is not None else None
        seen = [(i.label, i.xy) for i in scene.map] if scene is not None else []
        room_type = None
        for room in scene.rooms if scene is not None else []:
            if _inside(room.polygon, frontier.x, frontier.y):
                room_type = room.type
                break
        return region_score((frontier.x, frontier.y), self.priors, seen, room_type)


def known_near(grid: Any, x: float, y: float, radius: float) -> float:
    """Known area (m^2, free or occupied) of ``grid`` within ``radius`` m of (x, y)."""
    res = grid.resolution
    r0, c0 = grid.world_to_cell(x, y)
    k = int(math.ceil(radius / res))
    h, w = grid.data.shape
    rs, re_, cs, ce = max(0, r0 - k), min(h, r0 + k + 1), max(0, c0 - k), min(w, c0 + k + 1)
    if rs >= re_ or cs >= ce:
        return 0.0
    rr, cc = np.mgrid[rs:re_, cs:ce]
    disc = (rr - r0) ** 2 + (cc - c0) ** 2 <= k * k
    return float(np.count_nonzero((grid.data[rs:re_, cs:ce] >= 0) & disc)) * res * res


def _inside(polygon: Any, x: float, y: float) -> bool:
    """Point in polygon (even-odd rule); False for an empty polygon."""
    pts = [(float(p[0]), float(p[1])) for p in polygon]
    inside = False
    for (x1, y1), (x2, y2) in zip(pts, pts[1:] + pts[:1], strict=True):
        if (y1 > y) != (y2 > y) and x < x1 + (y - y1) * (x2 - x1) / (y2 - y1):
            inside = not inside
    return inside
