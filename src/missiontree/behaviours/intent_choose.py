"""The intent's choice and its record: rank the candidates left, pick one; serve the one confirmed.

:class:`ChooseIntentTarget` checks the candidates the command's reading left (in the graph, on the
map, reachable: :func:`~missiontree.reasoning.intent.plan_candidates`, on a background job so the
tick never waits) and writes the best — the strongest tier first (a TV before a laptop for boredom),
the shortest path within a tier — as the candidate the shared subtree approaches and confirms: its
id, label, place, the standoff ``goal`` the ranking planned, what a look must see (``wanted``) and
``unchecked``, why it may not be served unconfirmed ("" when it may: a strong choice not read by
embedding alone, and not one of the objects a live graph's colours could not vouch for).
:class:`ServeIntent` records what the subtree found: the object, why it was chosen, its score and
whether a look confirmed it, in the ``served`` key, the ``intent_served`` event, summary.json's
``outcome.intent`` and ``<run_dir>/intent_served.json``.

Tick-log events: ``candidate_rejected``, ``intent_ambiguous``, ``candidates_ranked``,
``intent_served``.
"""

from __future__ import annotations

from typing import Annotated, Any

from pydantic import BaseModel, Field

from missiontree.behaviours.approach_steps import camera_view
from missiontree.behaviours.background import Background, waits
from missiontree.behaviours.intent import IntentLeaf, give_up_reason
from missiontree.engine.leaf import Status
from missiontree.engine.ports import Input, Output
from missiontree.reasoning.intent import Candidate, Ranking, look_for, nearest_note, plan_candidates
from missiontree.reasoning.knowledge import STRONG


class ChooseIntentTarget(IntentLeaf):
    """The best candidate left, checked and ranked from where the robot is now, written to ``candidate``.

    FAILURE (a verdict, recorded) when none is left or ``max_candidates`` were driven to.
    """

    class Params(IntentLeaf.Params):
        max_candidates: int = Field(5, ge=1, description="Candidates to drive to before giving up.")
        robot_radius: float = Field(
            0.17, gt=0, description="Footprint radius for standoff poses and paths (m).")
        allow_unknown: bool = Field(False, description="Plan through unknown cells of the map.")
        candidate: Annotated[str, Output("the candidate chosen: id, label, x, y, z, goal, wanted, unchecked",
                                         type="dict")] = "intent_candidate"

    params: Params

    def __init__(self, name: str, params: BaseModel | None = None) -> None:
        super().__init__(name, params)
        self.job: Background | None = None
        self.now: dict[str, Any] = {}

    def initialise(self) -> None:
        """The ranking starts at the first tick."""
        self.job = None
        self.now = self.state()

    def update(self) -> Status:
        """Rank the candidates left on a background job, then take the best."""
        state = self.now
        if not state.get("text"):
            return self.fail("no command read (run ReadIntent first)")
        if self.job is None:
            stamped = self.context.robot.pose()
            if stamped is None:
                return self.fail("the robot has no pose yet; cannot rank candidates")
            if not state["ids"]:
                return self.not_served(state, give_up_reason(state))
            robot = self.context.robot
            self.job = Background(plan_candidates, list(state["ids"]), state["scene"], robot.occupancy(),
                                  stamped.pose, self.params.robot_radius, self.doubtful(),
                                  self.params.allow_unknown, camera_view(robot.rgbd()),
                                  wait=waits(self.context))
        done, ranking, error = self.job.poll()
        if not done:
            return self.running("checking and ranking candidates")
        self.job = None
        if error:
            return self.fail(f"ranking the candidates failed: {error}", verdict=True)
        assert isinstance(ranking, Ranking)
        return self._ranked(state, ranking)

    def _ranked(self, state: dict[str, Any], ranking: Ranking) -> Status:
        text = state["text"]
        planned = {oid for oid, _ in state["tried"]}
        for rejection in ranking.rejected:
            if rejection.id not in planned:
                state["tried"] = [*state["tried"], [rejection.id, rejection.reason]]
                self.emit("candidate_rejected", command=text, object=rejection.id, reason=rejection.reason)
        note = nearest_note(ranking, state["scene"])
        if note:
            self.emit("intent_ambiguous", command=text, note=note,
                      candidates=[c.id for c in ranking.candidates])
        self.emit("candidates_ranked", command=text, by="path_length", candidates=[
            {**c.as_dict(), "score": self.strength_of(state, c.label)[0]} for c in ranking.candidates])
        if not ranking.candidates or int(state.get("driven", 0)) >= self.params.max_candidates:
            return self.not_served(state, give_up_reason(state))
        best = min(ranking.candidates, key=lambda c: (-self.strength_of(state, c.label)[0], c.path_length))
        state["ids"] = [i for i in state["ids"] if i != best.id]
        self.write("candidate", self._candidate(state, best))
        self.write("state", state)
        return self.succeed(f"{best.id} ({best.label}, {best.path_length:.1f} m by path)")

    def _candidate(self, state: dict[str, Any], best: Candidate) -> dict[str, Any]:
        """The subtree's candidate: place, planned goal, what a look must see, whether it may go unchecked."""
        obj = state["scene"].objects[best.id]
        wanted = look_for(best.label, str(state.get("wanted", "")).split())
        score, why = self.strength_of(state, best.label)
        if state.get("confirm_only"):
            unchecked = f"the graph does not say it is a {wanted}"
        elif score < STRONG:
            unchecked = f"it was a weak choice ({why}, {score:.2f} < {STRONG:g})"
        elif self.by_embedding(state):
            unchecked = f"the command was understood only by embedding ({why})"
        else:
            unchecked = ""
        goal = best.goal
        return {"id": best.id, "label": best.label, "x": best.xy[0], "y": best.xy[1], "z": obj.z,
                "goal": {"x": goal.x, "y": goal.y, "yaw": goal.yaw}, "wanted": wanted, "unchecked": unchecked,
                "command": state["text"], "path_length": round(best.path_length, 3),
                "straight_line": round(best.straight_line, 3)}

    def terminate(self, new_status: Status) -> None:
        """Drop a ranking in flight."""
        if self.job is not None:
            self.job.cancel()
            self.job = None


class ServeIntent(IntentLeaf):
    """SUCCESS at the object the subtree found, recorded: why it was chosen, whether it was confirmed."""

    class Params(IntentLeaf.Params):
        candidate: Annotated[str, Input("the candidate approached", type="dict")] = "intent_candidate"
        found: Annotated[str, Input("what the look found: confirmed, note", type="dict")] = "intent_found"
        served: Annotated[str, Output("the command served: object, label, why it was chosen, whether it "
                                      "was confirmed", type="dict")] = "intent_served"

    params: Params

    def update(self) -> Status:
        """Record the command served and succeed."""
        state, cand, found = self.state(), self.read("candidate"), self.read("found")
        if not state or not isinstance(cand, dict) or not isinstance(found, dict):
            return self.fail("nothing found to serve (run ChooseIntentTarget and the approach first)")
        confirmed = bool(found.get("confirmed"))
        score, why = self.strength_of(state, cand["label"])
        note = str(found.get("note", ""))
        if not confirmed:
            note = f"{note}; a strong choice: {why} {score:.2f}"
        because = str(state.get("because", ""))
        record = {"command": state["text"], "object": cand["id"], "label": cand["label"],
                  "chosen_because": because, "score": score, "score_because": why, "confirmed": confirmed,
                  "note": note, "tried": [{"object": oid, "why": reason} for oid, reason in state["tried"]]}
        self.write("served", record)
        self.emit("intent_served", **record)
        self.record({**record, "status": "served"})
        shown = "confirmed" if confirmed else "NOT confirmed"
        return self.succeed(f"at {cand['id']} ({cand['label']}, {shown}: {note}); chosen because "
                            f"{because or 'the model named it'}")
