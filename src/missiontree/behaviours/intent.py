"""Intent navigation: go where the user means, over the scene graph (the NAIS paper's phase 2, checked).

:class:`GoToIntent` (leaf) serves one command (the
:class:`~missiontree.behaviours.commands.ServeCommands` decorator hands it each in turn): the
language model answers candidate object ids through a schema (a handle polled every tick); every id
is checked against the graph and the map and the survivors are ranked by path length
(:mod:`missiontree.reasoning.intent`, run on the model worker pool so the tick never waits); the
robot drives to a standoff pose facing the best one and looks: the detector must see the object
where the graph puts it and the vision-language model must confirm the asked-for attributes on a
crop of it. If not, the object is marked doubtful and the next candidate is tried (re-ranked from
where the robot now is). No candidate left → FAILURE with the reason. Goals come only from graph
coordinates and the map, never from the model's text.

Only a strong choice is ever driven to or served — the command names the object's class, or the
shipped knowledge says the class serves it at least :data:`~missiontree.reasoning.knowledge.STRONG`;
a weak one the model names (a potted plant for "a cosmetic") is rejected with its score, and with
no strong one left the command fails saying so. Candidates are tried best tier first (by that
score: the TV before the laptop for boredom), by path length within a tier, so that an object with
no place to stand by it hands over to the next tier. What was served goes to the ``served``
blackboard key, the ``intent_served`` event, ``<run_dir>/intent_served.json`` and summary.json's
``outcome.intent`` (through ``context.report``; one entry per command, served or not and why):
object, label, the model's reason, the knowledge's score and why, whether it was confirmed, and
what was tried before.

On a live graph the command is read again (up to :data:`REREADS` times) when a candidate fails and
the graph has gained objects since (the object asked for seen on the way to another). The look on
arrival is :mod:`missiontree.behaviours.intent_look`; the files read and written,
:mod:`missiontree.behaviours.intent_files`.

Tick-log events: ``intent_interpreted``, ``intent_reread``, ``intent_unsure``, ``approach_again``,
``candidate_rejected``, ``intent_ambiguous``,
``goal_sent``, ``goal_result``, ``object_verified``, ``object_doubtful``, ``intent_served``.
"""

from __future__ import annotations

import math
from typing import Annotated, Any

from pydantic import BaseModel, Field

from missiontree.behaviours.approach_steps import camera_view
from missiontree.behaviours.background import Background, waits
from missiontree.behaviours.intent_files import find_scene_graph, record_outcome
from missiontree.behaviours.intent_look import ArrivalLook, Step
from missiontree.engine.leaf import Status
from missiontree.engine.ports import Input, Output
from missiontree.errors import ConfigError
from missiontree.reasoning.calls import CallStatus, ModelCall, model_caller
from missiontree.reasoning.intent import (
    Candidate,
    Ranking,
    SceneObjects,
    graph_objects,
    look_for,
    nearest_note,
    plan_candidates,
    prompt_objects,
)
from missiontree.reasoning.knowledge import STRONG, Reading, knowledge
from missiontree.reasoning.need_embedding import by_embedding, embedded_reading
from missiontree.reasoning.phrases import fold_label
from missiontree.reasoning.prompts import intent_messages
from missiontree.reasoning.schemas import IntentResolution
from missiontree.robot.actions import ActionHandle, ActionStatus
from missiontree.types import RGBDFrame, Tolerance

#: Times a command is read again over a live graph that gained objects while candidates failed.
REREADS = 2
#: A goal aborted with the robot this close to it (m) counts as reached: the stack stopped just short.
NEAR_ENOUGH = 0.4


# -- GoToIntent ----------------------------------------------------------------------------------------


class GoToIntent(ArrivalLook):
    """Serve one command over the scene graph: candidates checked, ranked by path, driven to, looked at.

    FAILURE reasons name what went wrong: the model's answer, every candidate rejected with its reason,
    or every candidate looked at and not confirmed. A goal is always a standoff pose computed from a
    graph object's coordinates and the map; a graph's text is treated as data only.
    """

    class Params(BaseModel):
        scene_graph: str = Field(
            "",
            description="A scene graph file in the NAIS JSON shape, or a shipped name under "
            "config/scene_graphs/ (office); empty: the live graph built earlier in the mission "
            "(context.scene, see BuildSceneGraph).",
        )
        look: bool = Field(
            True,
            description="Look on arrival (detector + vision-language model) and try the "
            "next candidate when the object is not confirmed.",
        )
        max_candidates: int = Field(5, ge=1, description="Candidates to drive to before giving up.")
        robot_radius: float = Field(
            0.17, gt=0, description="Footprint radius for standoff poses and paths (m)."
        )
        allow_unknown: bool = Field(False, description="Plan through unknown cells of the map.")
        xy_tolerance: float = Field(
            0.15, gt=0, description="Distance to the standoff pose that counts as there (m)."
        )
        yaw_tolerance: float = Field(
            0.25, gt=0, description="Heading error accepted at the standoff pose (rad)."
        )
        goal_timeout: float = Field(
            180.0, gt=0, description="Give up on a candidate not reached in this many s."
        )
        look_timeout: float = Field(15.0, gt=0, description="Give up looking after this many seconds.")
        command: Annotated[str, Input("the command to serve", type="str")] = "intent_command"
        doubtful: Annotated[
            str, Output("ids marked doubtful after a look (read back by later commands)", type="list[str]")
        ] = "intent_doubtful"
        goal: Annotated[str, Output("the object and standoff goal being driven to", type="dict")] = (
            "intent_goal"
        )
        served: Annotated[
            str, Output("the command served: object, label, why it was chosen, whether it was confirmed",
                        type="dict")
        ] = "intent_served"

    params: Params

    def __init__(self, name: str, params: BaseModel | None = None) -> None:
        super().__init__(name, params)
        self.file_graph: Any = None
        self._read_cache: tuple[str, Reading] | None = None  # the command read by the knowledge, once
        self._reset()

    def _reset(self) -> None:
        self.step = Step.INTERPRET
        self.text = ""
        self.scene: SceneObjects | None = None
        self.call: ModelCall | None = None
        self.job: Background | None = None  # ranking the candidates or finding another place to stand
        self.handle: ActionHandle | None = None
        self.remaining: list[str] = []
        self.tried: list[tuple[str, str]] = []
        self.rejected: list[str] = []
        self.target: Candidate | None = None
        self.wanted = ""
        self.frame: RGBDFrame | None = None
        self.looks = 0
        self.started = 0.0
        self.second_look = False   # the current candidate has been looked at from a second place
        self.first_miss = ""
        self.reapproached = False
        self.approach_miss = ""
        self.first_unreached = ""  # why the first standoff goal of the current candidate was not reached
        self.because = ""          # the language model's reason for its candidates
        self.named = ""            # the class a referential command names ("" for a need)
        self.confirm_only = False  # candidates the graph does not vouch for: served only when a look confirms
        self.rereads = 0           # times the command was read again over a live graph that grew

    def on_setup(self) -> None:
        """Load the graph file (a missing or malformed file fails here, before the first tick)."""
        if self.params.scene_graph:
            from missiontree.semantics.scene_graph import SceneGraph

            self.file_graph = SceneGraph.load(find_scene_graph(self.params.scene_graph))
        # py_trees' blackboard outlives a mission in the same process (batch runs, benchmarks): doubt
        # starts empty with each mission, never inherited from another one.
        self.write("doubtful", [])

    # -- lifecycle -------------------------------------------------------------------------------

    def initialise(self) -> None:
        """Read the command and the graph, and ask the language model for candidates."""
        self._reset()
        self.text = str(self.read("command", "") or "").strip()
        graph = self.file_graph if self.file_graph is not None else self._live_graph()
        if not self.text or graph is None:
            return
        self._ask(graph)

    def _ask(self, graph: Any) -> None:
        """Ask the language model for candidates over ``graph`` (doubted objects left out)."""
        self.scene = graph_objects(graph)
        listing = prompt_objects(self.scene, exclude=self._doubtful())
        self.call = model_caller(self.context).chat(
            "llm", intent_messages(self.text, listing), IntentResolution, node=self.name
        )
        self.step = Step.INTERPRET

    def update(self) -> Status:
        """Advance the current step; every step returns at once."""
        if not self.text:
            return self.fail(f"no command to serve (the blackboard key {self.params.command!r} is empty)")
        if self.scene is None:
            return self.fail(
                "no scene graph: build one earlier in the mission or give a file with "
                "--set scene_graph=path/to/graph.json"
            )
        handlers = {
            Step.FACE: self._faced,
            Step.INTERPRET: self._interpreted,
            Step.PLAN: self._ranked,
            Step.DRIVE: self._driven,
            Step.FRAME: self._framed,
            Step.DETECT: self._detected,
            Step.CONFIRM: self._confirmed,
            Step.VIEWPOINT: self._viewpoint,
        }
        return handlers[self.step]()

    def terminate(self, new_status: Status) -> None:
        """Cancel the model call, the planning job and the goal in flight."""
        if self.call is not None:
            self.call.cancel()
            self.call = None
        if self.job is not None:
            self.job.cancel()
            self.job = None
        if self.step is Step.FACE and self.ctx is not None:
            self.ctx.robot.stop()
        if self.handle is not None:
            self.handle.cancel()
            self.handle = None
            if self.target is not None:
                self.emit("goal_result", status="canceled", reason="halted", object=self.target.id)

    # -- steps -----------------------------------------------------------------------------------

    def _interpreted(self) -> Status:
        assert self.call is not None and self.scene is not None
        status = self.call.status()
        if not status.done:
            return self.running(f"{Step.INTERPRET.value}: {self.text!r}")
        if status is not CallStatus.SUCCEEDED:
            return self.fail(f"the language model did not answer for {self.text!r}: {self.call.error()}")
        answer: IntentResolution = self.call.result().value
        self.call = None
        ids = [str(i) for i in answer.candidates]
        attributes = list(answer.reference.attributes) if answer.reference is not None else []
        self.wanted = " ".join(attributes)
        self.because = answer.reason
        self.named = answer.reference.label if answer.reference is not None else ""
        self.emit(
            "intent_interpreted",
            command=self.text,
            candidates=ids,
            reason=answer.reason,
            reference=answer.reference.model_dump() if answer.reference is not None else None,
        )
        if self.rereads:  # read again over a grown graph: what was tried is not tried again
            done = {oid for oid, _ in self.tried}
            ids = [i for i in ids if i not in done]
        if not ids:
            self.confirm_only = False
            ids = self._look_at_all(answer)
            ids = [i for i in ids if i not in {oid for oid, _ in self.tried}]
        if not ids and self.rereads:
            return self._give_up()
        if not ids:
            why = f"nothing in the map satisfies {self.text!r}: {answer.reason or 'no candidate'}"
            self._record({"command": self.text, "status": "not served", "reason": why})
            return self.fail(why)
        strong, weak = self._strong_ids(ids)
        for oid, why in weak:
            self.tried.append((oid, why))
            self.emit("candidate_rejected", command=self.text, object=oid, reason=why)
        if not strong:
            why = (f"nothing in the map satisfies {self.text!r} strongly enough to serve "
                   f"({'; '.join(f'{oid}: {reason}' for oid, reason in weak[:6])})")
            self._record({"command": self.text, "status": "not served", "reason": why,
                          "chosen_because": self.because,
                          "tried": [{"object": oid, "why": reason} for oid, reason in weak]})
            return self.fail(why)
        self.remaining = strong
        return self._plan()

    def _look_at_all(self, answer: IntentResolution) -> list[str]:
        """On a live graph, the objects of the named class when none has the asked-for attributes.

        A live graph's colours are the camera's reading from wherever the robot passed (a blue chair
        seen from behind in shadow is listed grey); a look from a standoff pose decides instead. These
        objects are served only when a look confirms the attributes (:attr:`confirm_only`), never
        unconfirmed. A graph file is the user's word and is taken as it is.
        """
        ref = answer.reference
        if self.file_graph is not None or ref is None or not ref.attributes or ref.relation is not None:
            return []
        assert self.scene is not None
        doubtful = set(self._doubtful())
        ids = [o.id for o in self.scene.objects.values()
               if fold_label(o.label) == fold_label(ref.label) and o.id not in doubtful]
        if ids:
            self.confirm_only = True
            wanted = look_for(ref.label, ref.attributes)
            self.because = (f"{answer.reason}; the live graph's colours come from the camera, so each "
                            f"{ref.label} is looked at and served only if a look sees a {wanted}")
            self.emit("intent_unsure", command=self.text, candidates=ids, reason=self.because)
        return ids

    def _strong_ids(self, ids: list[str]) -> tuple[list[str], list[tuple[str, str]]]:
        """The model's ids split into (strong choices, [(weak id, why)]).

        A served object must satisfy the command by the shipped knowledge (at least
        :data:`~missiontree.reasoning.knowledge.STRONG`) or be named by class: a weak stand-in (a
        potted plant for "a cosmetic") is never driven to, whatever a look would say.
        """
        assert self.scene is not None
        strong: list[str] = []
        weak: list[tuple[str, str]] = []
        for oid in ids:
            obj = self.scene.objects.get(oid)
            if obj is None:  # not in the graph: plan_candidates rejects it with that reason
                strong.append(oid)
                continue
            score, why = self._strength_of(obj.label)
            if score >= STRONG:
                strong.append(oid)
            else:
                weak.append((oid, f"a weak choice: {why} ({score:.2f} < {STRONG:g})"))
        return strong, weak

    def _plan(self) -> Status:
        assert self.scene is not None
        robot = self.context.robot
        stamped = robot.pose()
        if stamped is None:
            return self.fail("the robot has no pose yet; cannot rank candidates")
        self.job = Background(
            plan_candidates,
            list(self.remaining),
            self.scene,
            robot.occupancy(),
            stamped.pose,
            self.params.robot_radius,
            self._doubtful(),
            self.params.allow_unknown,
            camera_view(robot.rgbd()),
            wait=waits(self.context),
        )
        self.step = Step.PLAN
        return self.running(Step.PLAN.value)

    def _ranked(self) -> Status:
        assert self.job is not None and self.scene is not None
        done, ranking, error = self.job.poll()
        if not done:
            return self.running(Step.PLAN.value)
        self.job = None
        if error:
            return self.fail(f"ranking the candidates failed: {error}")
        assert isinstance(ranking, Ranking)
        for rejection in ranking.rejected:
            if rejection.id not in self.rejected:
                self.rejected.append(rejection.id)
                self.tried.append((rejection.id, rejection.reason))
                self.emit(
                    "candidate_rejected", command=self.text, object=rejection.id, reason=rejection.reason
                )
        note = nearest_note(ranking, self.scene)
        if note:
            self.emit(
                "intent_ambiguous",
                command=self.text,
                note=note,
                candidates=[c.id for c in ranking.candidates],
            )
        self.emit(
            "candidates_ranked",
            command=self.text,
            by="path_length",
            candidates=[{**c.as_dict(), "score": self._strength_of(c.label)[0]} for c in ranking.candidates],
        )
        driven = sum(1 for _, why in self.tried if why.startswith(("not confirmed", "not reached")))
        if not ranking.candidates or driven >= self.params.max_candidates:
            return self._give_up()
        self.second_look = False
        self.reapproached = False
        self.first_unreached = ""
        # the best tier first (a TV before a laptop for boredom), the shortest path within a tier
        best = min(ranking.candidates, key=lambda c: (-self._strength_of(c.label)[0], c.path_length))
        return self._drive_to(best)

    def _drive_to(self, candidate: Candidate) -> Status:
        robot = self.context.robot
        self.target = candidate
        self.remaining = [i for i in self.remaining if i != candidate.id]
        goal = candidate.goal
        self.started = robot.now()
        self.handle = robot.navigate_to(goal, Tolerance(self.params.xy_tolerance, self.params.yaw_tolerance))
        self.write(
            "goal",
            {"object": candidate.id, "label": candidate.label, "x": goal.x, "y": goal.y, "yaw": goal.yaw},
        )
        self.emit(
            "goal_sent",
            command=self.text,
            object=candidate.id,
            label=candidate.label,
            x=round(goal.x, 3),
            y=round(goal.y, 3),
            yaw=round(goal.yaw, 3),
            object_x=candidate.xy[0],
            object_y=candidate.xy[1],
            path_length=round(candidate.path_length, 3),
            straight_line=round(candidate.straight_line, 3),
            xy_tolerance=self.params.xy_tolerance,
            yaw_tolerance=self.params.yaw_tolerance,
        )
        if self.ctx is not None:
            self.ctx.mark("goal", goal.x, goal.y, candidate.id)
        self.step = Step.DRIVE
        return self.running(f"to {candidate.id} ({candidate.path_length:.1f} m by path)")

    def _driven(self) -> Status:
        assert self.handle is not None and self.target is not None
        status = self.handle.status()
        robot = self.context.robot
        if not status.done:
            if robot.now() - self.started > self.params.goal_timeout:
                self.handle.cancel()
                self.handle = None
                self.emit("goal_result", status="aborted", reason="timeout", object=self.target.id)
                return self._next(f"not reached within {self.params.goal_timeout:g} s")
            feedback = self.handle.feedback()
            left = f"{feedback.distance_remaining:.1f} m to go" if feedback is not None else status.value
            return self.running(f"to {self.target.id}: {left}")
        result = self.handle.result()
        self.handle = None
        reason = result.reason if result is not None else ""
        self.emit("goal_result", status=status.value, reason=reason, object=self.target.id)
        stamped = robot.pose()
        off = stamped.pose.distance_to(self.target.goal) if stamped is not None else math.inf
        if status is not ActionStatus.SUCCEEDED and not (
            status is ActionStatus.ABORTED and off <= NEAR_ENOUGH
        ):
            why = f"not reached ({status.value}: {reason or 'no reason given'})"
            if status is not ActionStatus.ABORTED:
                return self._next(why)
            if self.reapproached:
                return self._next(f"{self.first_unreached}; again from another side: {why}")
            self.first_unreached = why
            return self._approach_again(why)
        if not self.params.look:
            return self._served(False, "not looked at: look is off")
        self.started = robot.now()
        self.looks = 0
        self.step = Step.FACE
        return self._faced()

    # -- serving ---------------------------------------------------------------------------------

    def _served(self, confirmed: bool, note: str) -> Status:
        """SUCCESS at the target, recorded on the blackboard and in the tick log with why it was chosen."""
        assert self.target is not None
        if self.confirm_only and not confirmed:
            return self._doubt(f"not confirmed to be a {look_for(self.target.label, self.wanted.split())}, "
                               f"which the graph does not say it is ({note})")
        score, why = self._strength()
        record = {"command": self.text, "object": self.target.id, "label": self.target.label,
                  "chosen_because": self.because, "score": score, "score_because": why,
                  "confirmed": confirmed, "note": note,
                  "tried": [{"object": oid, "why": reason} for oid, reason in self.tried]}
        self.write("served", record)
        self.emit("intent_served", **record)
        self._record({**record, "status": "served"})
        state = "confirmed" if confirmed else "NOT confirmed"
        return self.succeed(f"at {self.target.id} ({self.target.label}, {state}: {note}); chosen because "
                            f"{self.because or 'the model named it'}")

    def _strength(self) -> tuple[float, str]:
        """How surely the target serves the command, by the shipped knowledge (not by the model's word).

        A referential command that names the target's class is served by it outright; a need is
        scored by :meth:`~missiontree.reasoning.knowledge.Knowledge.score` (0 when the knowledge does
        not understand the command: then nothing vouches for the choice).
        """
        assert self.target is not None
        return self._strength_of(self.target.label)

    def _strength_of(self, raw: str) -> tuple[float, str]:
        """:meth:`_strength` of an object labelled ``raw``."""
        label = fold_label(raw)
        if self.named and fold_label(self.named) == label:
            return 1.0, f"the command names a {raw}"
        kb = knowledge()
        score, why = kb.score(label if label in kb.serves else raw, self._reading())
        return score, (f"{raw} serves {why}" if why else f"nothing known says a {raw} serves {self.text!r}")

    def _reading(self) -> Reading:
        """The command in the knowledge's terms, by its words or else by embedding (once per command).

        Whatever model chose the object, the knowledge vouches for it; a command none of whose words
        the knowledge lists is read by the embedder role's clear match, when the models have one.
        """
        cached = self._read_cache
        if cached is not None and cached[0] == self.text:
            return cached[1]
        kb = knowledge()
        reading = kb.read(self.text)
        if reading.empty:
            try:
                embedder = self.context.model("embedder")
            except ConfigError:
                embedder = None
            if embedder is not None:
                reading = embedded_reading(embedder, self.text, reading, kb)
        self._read_cache = (self.text, reading)
        return reading

    def _by_embedding(self) -> bool:
        """Whether the command was understood only by embedding similarity (a weaker reading)."""
        return not self.named and by_embedding(self._reading())

    # -- failing over ----------------------------------------------------------------------------

    def _doubt(self, reason: str) -> Status:
        assert self.target is not None
        self.call = None
        oid = self.target.id
        marked = self._doubtful() + [oid]
        self.write("doubtful", marked)
        scene = self.context.scene
        if self.file_graph is None and scene is not None and oid in scene.map:
            scene.map.update(oid, self.context.robot.now(), announce=True, reason=reason, doubtful=True)
        self.emit("object_doubtful", command=self.text, object=oid, reason=reason)
        return self._next(f"not confirmed: {reason}")

    def _next(self, reason: str) -> Status:
        assert self.target is not None
        self.tried.append((self.target.id, reason))
        self.target = None
        live = None if self.file_graph is not None else self._live_graph()
        if live is not None and self.rereads < REREADS and self._grew(live):
            # the live graph gained objects while the robot drove and looked (the blue chair seen on the
            # way to a chair the camera had listed grey): the command is read again over it
            self.rereads += 1
            self.emit("intent_reread", command=self.text, reason="the live graph gained objects")
            self._ask(live)
            return self.running(f"{Step.INTERPRET.value} again over the grown graph: {self.text!r}")
        if not self.remaining:
            return self._give_up()
        return self._plan()

    def _grew(self, graph: Any) -> bool:
        """Whether ``graph`` lists an object the scene the command was read over lacks."""
        assert self.scene is not None
        return bool(set(graph_objects(graph).objects) - set(self.scene.objects))

    def _give_up(self) -> Status:
        if not self.tried:
            why = f"nothing in the map satisfies {self.text!r}"
        else:
            shown = "; ".join(f"{oid}: {why}" for oid, why in self.tried[:6])
            more = f" and {len(self.tried) - 6} more" if len(self.tried) > 6 else ""
            why = f"no candidate for {self.text!r} could be reached and confirmed ({shown}{more})"
        tried = [{"object": oid, "why": reason} for oid, reason in self.tried]
        self._record({"command": self.text, "status": "not served", "reason": why,
                      "chosen_because": self.because, "tried": tried})
        return self.fail(why)

    def _record(self, record: dict[str, Any]) -> None:
        """Add the command's outcome to summary.json's ``outcome`` and ``<run_dir>/intent_served.json``."""
        failed = record_outcome(self.ctx, record)
        if failed:
            self.emit("intent_record_failed", **failed)

    def _live_graph(self) -> Any:
        """The graph a BuildSceneGraph earlier in the mission keeps (None without one)."""
        scene = self.ctx.scene if self.ctx is not None else None
        return scene.graph if scene is not None else None

    def _doubtful(self) -> list[str]:
        try:
            value = self.bb.get(self.params.doubtful)
        except KeyError:
            return []
        return [str(v) for v in value] if isinstance(value, list) else []


