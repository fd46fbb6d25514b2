"""Intent navigation: go where the user means, over the scene graph (the NAIS paper's phase 2, checked).

The tree sequences it (``trees/go_to_intent.yaml``), each step a node of the tick log:

- :class:`ReadIntent` (here): the language model reads the command over the graph and answers
  candidate object ids through a schema; weak choices are rejected; on a live graph that gained
  objects while candidates failed, the command is read again (up to :data:`REREADS` times).
- :class:`~missiontree.behaviours.intent_choose.ChooseIntentTarget`: every candidate checked
  against the graph and the map and ranked (best tier, then path length); the best written as the
  candidate the shared subtree ``subtrees/approach_confirm.yaml`` approaches, faces, looks for and
  confirms (the one :mod:`find_object <missiontree.behaviours.search>` includes too).
- :class:`~missiontree.behaviours.intent_choose.ServeIntent`: the object served, recorded with why.

Only a strong choice is ever driven to or served — the command names the object's class, or the
shipped knowledge says the class serves it at least :data:`~missiontree.reasoning.knowledge.STRONG`;
a weak one the model names (a potted plant for "a cosmetic") is rejected with its score. The steps
share the command's reading through the blackboard key ``intent_state`` (:class:`IntentState`
fields; the tree empties it for each command). Goals come only from graph coordinates and the map,
never from the model's text.

Tick-log events: ``intent_interpreted``, ``intent_reread``, ``intent_unsure``, ``candidate_rejected``.
"""

from __future__ import annotations

from typing import Annotated, Any

from pydantic import BaseModel, Field

from missiontree.behaviours.intent_files import find_scene_graph, record_outcome
from missiontree.engine.leaf import Leaf, Status
from missiontree.engine.ports import Input, Output
from missiontree.errors import ConfigError
from missiontree.reasoning.calls import CallStatus, ModelCall, model_caller
from missiontree.reasoning.intent import graph_objects, look_for, prompt_objects
from missiontree.reasoning.knowledge import STRONG, Reading, knowledge
from missiontree.reasoning.need_embedding import by_embedding, embedded_reading
from missiontree.reasoning.phrases import fold_label
from missiontree.reasoning.prompts import intent_messages
from missiontree.reasoning.schemas import IntentResolution

#: Times a command is read again over a live graph that gained objects while candidates failed.
REREADS = 2


class IntentLeaf(Leaf):
    """What the intent steps share: the command's reading (``state``), the doubted objects, the record.

    ``state`` is a dict: ``text``, ``scene`` (the :class:`~missiontree.reasoning.intent.SceneObjects`
    the command was read over), ``file`` (a graph file, not the live graph), ``because`` (the model's
    reason), ``named`` (the class a referential command names), ``wanted`` (the asked-for attributes),
    ``confirm_only``, ``ids`` (strong candidates left), ``tried`` ([id, why] pairs), ``seen`` (rejected
    entries already read), ``rereads``, ``reading`` (the knowledge's reading of the command).
    """

    class Params(BaseModel):
        command: Annotated[str, Input("the command to serve", type="str")] = "intent_command"
        state: Annotated[str, Output("the command's reading, shared by the intent steps (the tree empties "
                                     "it for each command)", type="dict")] = "intent_state"
        doubtful: Annotated[str, Output("ids doubted after a look (read back by later commands)",
                                        type="list[str]")] = "intent_doubtful"

    params: Params

    def state(self) -> dict[str, Any]:
        """The command's reading so far (empty before the command is read)."""
        value = self.read("state")
        return dict(value) if isinstance(value, dict) else {}

    def doubtful(self) -> list[str]:
        """Ids doubted so far in this mission."""
        value = self.read("doubtful")
        return [str(v) for v in value] if isinstance(value, list) else []

    def record(self, record: dict[str, Any]) -> None:
        """Add the command's outcome to summary.json's ``outcome`` and ``<run_dir>/intent_served.json``."""
        failed = record_outcome(self.ctx, record)
        if failed:
            self.emit("intent_record_failed", **failed)

    def not_served(self, state: dict[str, Any], why: str, tried: bool = True) -> Status:
        """FAILURE (a verdict: trying again cannot change it), recorded with why."""
        record: dict[str, Any] = {"command": state.get("text", ""), "status": "not served", "reason": why}
        if tried:
            record["chosen_because"] = state.get("because", "")
            record["tried"] = [{"object": oid, "why": reason} for oid, reason in state.get("tried", [])]
        self.record(record)
        return self.fail(why, verdict=True)

    def strength_of(self, state: dict[str, Any], raw: str) -> tuple[float, str]:
        """How surely an object labelled ``raw`` serves the command, by the shipped knowledge.

        A referential command that names the class is served by it outright; a need is scored by
        :meth:`~missiontree.reasoning.knowledge.Knowledge.score` (0 when the knowledge does not
        understand the command: then nothing vouches for the choice).
        """
        label = fold_label(raw)
        named = str(state.get("named", ""))
        if named and fold_label(named) == label:
            return 1.0, f"the command names a {raw}"
        kb = knowledge()
        score, why = kb.score(label if label in kb.serves else raw, self.reading(state))
        text = state.get("text", "")
        return score, (f"{raw} serves {why}" if why else f"nothing known says a {raw} serves {text!r}")

    def reading(self, state: dict[str, Any]) -> Reading:
        """The command in the knowledge's terms, by its words or else by the embedder role's clear match."""
        cached = state.get("reading")
        if isinstance(cached, Reading):
            return cached
        kb = knowledge()
        reading = kb.read(str(state.get("text", "")))
        if reading.empty:
            try:
                embedder = self.context.model("embedder")
            except ConfigError:
                embedder = None
            if embedder is not None:
                reading = embedded_reading(embedder, str(state.get("text", "")), reading, kb)
        state["reading"] = reading
        return reading

    def by_embedding(self, state: dict[str, Any]) -> bool:
        """Whether the command was understood only by embedding similarity (a weaker reading)."""
        return not state.get("named") and by_embedding(self.reading(state))


class ReadIntent(IntentLeaf):
    """Read the command over the scene graph: the language model's candidates, weak ones rejected.

    Runs once per command, and again when a live graph gained objects while candidates failed (the
    blue chair seen on the way to a chair the camera had listed grey). FAILURE (a verdict) when there
    is no command or graph, the model does not answer, or nothing strong enough is named.
    """

    class Params(IntentLeaf.Params):
        scene_graph: str = Field(
            "",
            description="A scene graph file in the NAIS JSON shape, or a shipped name under "
            "config/scene_graphs/ (office); empty: the live graph built earlier in the mission "
            "(context.scene, see BuildSceneGraph).",
        )
        rejected: Annotated[str, Input("candidates the approach rejected (unreached, wrong) for this command",
                                       type="list[dict]")] = "intent_rejected"

    params: Params

    def __init__(self, name: str, params: BaseModel | None = None) -> None:
        super().__init__(name, params)
        self.file_graph: Any = None
        self.call: ModelCall | None = None
        self.asked: dict[str, Any] = {}

    def on_setup(self) -> None:
        """Load the graph file (a missing or malformed file fails here, before the first tick)."""
        if self.params.scene_graph:
            from missiontree.semantics.scene_graph import SceneGraph

            self.file_graph = SceneGraph.load(find_scene_graph(self.params.scene_graph))
        # py_trees' blackboard outlives a mission in the same process (batch runs, benchmarks): doubt
        # starts empty with each mission, never inherited from another one.
        self.write("doubtful", [])

    def initialise(self) -> None:
        """Take what the approach rejected since the last round; ask the model when a reading is due."""
        self.call = None
        state = self.absorbed(self.state())
        self.asked = state
        if not state:
            text = str(self.read("command", "") or "").strip()
            graph = self.file_graph if self.file_graph is not None else self._live_graph()
            self.asked = {"text": text, "file": self.file_graph is not None, "tried": [], "seen": 0,
                          "rereads": 0, "ids": []}
            if text and graph is not None:
                self._ask(graph)
            return
        live = None if state.get("file") else self._live_graph()
        due = state.get("failed") and state["rereads"] < REREADS
        if due and live is not None and self._grew(state, live):
            self.asked = {**state, "rereads": state["rereads"] + 1}
            self.emit("intent_reread", command=state["text"], reason="the live graph gained objects")
            self._ask(live)

    def absorbed(self, state: dict[str, Any]) -> dict[str, Any]:
        """``state`` with the candidates rejected since it was written added to ``tried`` (and doubt)."""
        if not state:
            return state
        entries = self.read_entries("rejected")
        fresh = entries[int(state.get("seen", 0)):]
        if not fresh:
            return {**state, "failed": False}
        wrong = [str(e.get("id")) for e in fresh if e.get("kind") == "wrong"]
        if wrong:
            self.write("doubtful", [*self.doubtful(), *wrong])
        tried = [*state["tried"], *([str(e.get("id")), str(e.get("reason", ""))] for e in fresh)]
        return {**state, "tried": tried, "seen": len(entries), "failed": True,
                "driven": int(state.get("driven", 0)) + len(fresh)}

    def _ask(self, graph: Any) -> None:
        scene = graph_objects(graph)
        self.asked["scene"] = scene
        listing = prompt_objects(scene, exclude=self.doubtful())
        self.call = model_caller(self.context).chat(
            "llm", intent_messages(self.asked["text"], listing), IntentResolution, node=self.name)

    def update(self) -> Status:
        """Wait for the model's answer (when one was asked for), then split it into strong and weak."""
        state = self.asked
        if not state.get("text"):
            return self.fail(f"no command to serve (the blackboard key {self.params.command!r} is empty)",
                             verdict=True)
        if "scene" not in state:
            return self.fail("no scene graph: build one earlier in the mission or give a file with "
                             "--set scene_graph=path/to/graph.json", verdict=True)
        if self.call is None:
            self.write("state", state)
            return self.succeed(f"{len(state['ids'])} candidates left for {state['text']!r}")
        status = self.call.status()
        if not status.done:
            return self.running(f"interpreting the command: {state['text']!r}")
        call, self.call = self.call, None
        if status is not CallStatus.SUCCEEDED:
            return self.not_served(state, f"the language model did not answer for {state['text']!r}: "
                                   f"{call.error()}", tried=False)
        return self._interpreted(state, call.result().value)

    def _interpreted(self, state: dict[str, Any], answer: IntentResolution) -> Status:
        text = state["text"]
        ref = answer.reference
        ids = [str(i) for i in answer.candidates]
        state.update(because=answer.reason, named=ref.label if ref is not None else "",
                     wanted=" ".join(ref.attributes) if ref is not None else "", confirm_only=False)
        self.emit("intent_interpreted", command=text, candidates=ids, reason=answer.reason,
                  reference=ref.model_dump() if ref is not None else None)
        done = {oid for oid, _ in state["tried"]}
        if state["rereads"]:  # read again over a grown graph: what was tried is not tried again
            ids = [i for i in ids if i not in done]
        if not ids:
            ids = [i for i in self._look_at_all(state, answer) if i not in done]
        if not ids and state["rereads"]:
            return self.not_served(state, give_up_reason(state))
        if not ids:
            why = f"nothing in the map satisfies {text!r}: {answer.reason or 'no candidate'}"
            return self.not_served(state, why, tried=False)
        strong, weak = self._strong_ids(state, ids)
        for oid, why in weak:
            state["tried"] = [*state["tried"], [oid, why]]
            self.emit("candidate_rejected", command=text, object=oid, reason=why)
        if not strong:
            shown = "; ".join(f"{oid}: {reason}" for oid, reason in weak[:6])
            return self.not_served(state, f"nothing in the map satisfies {text!r} strongly enough to serve "
                                   f"({shown})")
        state["ids"] = strong
        self.write("state", state)
        return self.succeed(f"{len(strong)} candidates for {text!r}: {', '.join(strong)}")

    def _look_at_all(self, state: dict[str, Any], answer: IntentResolution) -> list[str]:
        """On a live graph, the objects of the named class when none has the asked-for attributes.

        A live graph's colours are the camera's reading from wherever the robot passed (a blue chair
        seen from behind in shadow is listed grey); a look from a standoff pose decides instead. These
        objects are served only when a look confirms the attributes (``confirm_only``), never
        unconfirmed. A graph file is the user's word and is taken as it is.
        """
        ref = answer.reference
        if state.get("file") or ref is None or not ref.attributes or ref.relation is not None:
            return []
        doubtful = set(self.doubtful())
        ids = [o.id for o in state["scene"].objects.values()
               if fold_label(o.label) == fold_label(ref.label) and o.id not in doubtful]
        if ids:
            wanted = look_for(ref.label, ref.attributes)
            state["confirm_only"] = True
            state["because"] = (f"{answer.reason}; the live graph's colours come from the camera, so each "
                                f"{ref.label} is looked at and served only if a look sees a {wanted}")
            self.emit("intent_unsure", command=state["text"], candidates=ids, reason=state["because"])
        return ids

    def _strong_ids(self, state: dict[str, Any], ids: list[str]) -> tuple[list[str], list[tuple[str, str]]]:
        """The model's ids split into (strong choices, [(weak id, why)]); ids not in the graph stay."""
        strong: list[str] = []
        weak: list[tuple[str, str]] = []
        for oid in ids:
            obj = state["scene"].objects.get(oid)
            if obj is None:  # not in the graph: the ranking rejects it with that reason
                strong.append(oid)
                continue
            score, why = self.strength_of(state, obj.label)
            if score >= STRONG:
                strong.append(oid)
            else:
                weak.append((oid, f"a weak choice: {why} ({score:.2f} < {STRONG:g})"))
        return strong, weak

    def _grew(self, state: dict[str, Any], graph: Any) -> bool:
        """Whether ``graph`` lists an object the scene the command was read over lacks."""
        return bool(set(graph_objects(graph).objects) - set(state["scene"].objects))

    def _live_graph(self) -> Any:
        """The graph a BuildSceneGraph earlier in the mission keeps (None without one)."""
        scene = self.ctx.scene if self.ctx is not None else None
        return scene.graph if scene is not None else None

    def terminate(self, new_status: Status) -> None:
        """Cancel the model call in flight."""
        if self.call is not None:
            self.call.cancel()
            self.call = None


def give_up_reason(state: dict[str, Any]) -> str:
    """Why a command is not served after its candidates failed: each tried one and why (six shown)."""
    tried = state.get("tried", [])
    text = state.get("text", "")
    if not tried:
        return f"nothing in the map satisfies {text!r}"
    shown = "; ".join(f"{oid}: {why}" for oid, why in tried[:6])
    more = f" and {len(tried) - 6} more" if len(tried) > 6 else ""
    return f"no candidate for {text!r} could be reached and confirmed ({shown}{more})"
