"""The offline language-model stand-in for intent: needs through affordances, references through parsing.

It answers the NAIS interpretation conversation (:func:`missiontree.reasoning.prompts.intent_messages`)
with an :class:`~missiontree.reasoning.schemas.IntentResolution` naming scene object ids, with no
network and no GPU:

- A **need** ("I am thirsty", "I need to answer some emails") is read with the shipped knowledge
  (:mod:`missiontree.reasoning.knowledge`: WordNet words of each need, affordances written per label):
  each class of the scene scores how well it serves what the request says (a bottle 1.0 for thirst, a
  sink 0.4); every class serving it at least ``STRONG`` is a candidate, best class first. A
  request none of whose words the knowledge knows is matched to a need's
  description by MiniLM embedding, and only a clear match counts (``NEED_MATCH``), at a weaker
  strength. A request that expresses no need and names no known object ("bring me a unicorn") is
  served by nothing; so is one whose need only a class the scene lacks serves ("take a shower"). A
  class serving a weaker second need is not offered beside the stated one, and a word saying two
  needs equally ("a documentary": to watch or to print) keeps only the classes serving both, or
  chooses nothing: an ambiguous request is not guessed at.
- A **reference** ("the grey backpack in front of the sofa") is parsed into label + attributes +
  spatial relation (:mod:`missiontree.reasoning.phrases`) and the objects are filtered by label,
  by colour/size attribute and by the relation to an anchor object or room.

Which object is nearest, and so the goal, is the caller's choice (NAIS node 5).

Provider name ``offline_llm``; options: ``embedder`` (role of the embedder, default ``embedder``),
``affordances`` (label → description, added to the defaults; kept for referential class names),
``margin`` (0.05: how far the embedding fallback's best need must lead the next), ``min_score``
(kept for configuration compatibility); the constructor also takes ``absent_margin`` (0.1: a class the
scene lacks that serves the request this much better than anything present means nothing serves it).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

from pydantic import BaseModel

from missiontree.errors import ModelError
from missiontree.perception.colour import canonical_colour
from missiontree.reasoning.knowledge import STRONG, Knowledge, Reading, knowledge, normalise
from missiontree.reasoning.need_embedding import embedded_reading
from missiontree.reasoning.phrases import fold_label, parse_reference, split_relation
from missiontree.reasoning.prompts import parse_intent_messages
from missiontree.reasoning.protocols import Embedder, Message
from missiontree.reasoning.schemas import IntentResolution, ReferenceParse
from missiontree.semantics.relations import RELATIONS, Body, RelationParams, compute_relations

#: What each object class is for, in one line (what an embedding of a need should land near).
AFFORDANCES: dict[str, str] = {
    "bottle": "a bottle of water or juice to drink from",
    "cup": "a cup for drinking coffee, tea or water",
    "sink": "a sink with a tap for washing hands and dishes",
    "refrigerator": "a refrigerator full of food to eat and cold drinks",
    "sofa": "a sofa to relax, rest and nap on when tired",
    "chair": "a chair to sit down and rest on when tired",
    "bed": "a bed to lie down and sleep in when tired",
    "tv": "a television to watch films and shows for entertainment when bored",
    "book": "a book to read for entertainment when bored",
    "laptop": "a laptop computer to work on, browse the internet or play games when bored",
    "backpack": "a backpack for carrying your things",
    "umbrella": "an umbrella that keeps you dry in the rain",
    "potted plant": "a potted plant that decorates the room",
    "table": "a table to put things on, eat or work at",
    "toilet": "a toilet in the bathroom",
    "person": "a person to talk to",
    "counter": "a kitchen counter to prepare food on",
    "oven": "an oven to cook and bake food",
    "microwave": "a microwave to heat up food",
    "stool": "a stool to sit on",
    "trash can": "a trash can to throw rubbish away",
    "desk": "a desk to work at",
    "dining table": "a dining table to eat meals at",
    "printer": "a printer to print documents",
    "bookshelf": "a bookshelf full of books to read when bored",
    # common things a scene may lack: a need they fit better than anything present goes unserved
    "shower": "a shower to wash and bathe the whole body under running water",
    "bathtub": "a bathtub to take a bath in",
    "washing machine": "a washing machine to wash dirty clothes and laundry",
    "swimming pool": "a swimming pool to swim in",
    "car": "a car to drive somewhere far away",
    "airplane": "an airplane or rocket to fly in",
    "bicycle": "a bicycle to ride outside",
    "telephone": "a telephone to call someone",
    "toothbrush": "a toothbrush to brush your teeth",
    "piano": "a piano to play music on",
    "stove": "a stove to cook food on",
    "mirror": "a mirror to look at yourself",
    "door": "a door to leave the house",
    "first aid kit": "a first aid kit with medicine and bandages when hurt or sick",
    "dog": "a pet dog to play with and walk",
}

#: Kept for configuration compatibility: candidates are now the classes serving a request at least
#: :data:`~missiontree.reasoning.knowledge.STRONG` (a bottle 1.0 and a cup 1.0 for thirst, not a sink 0.4).
SERVE_MIN = STRONG
KNOWN_MARGIN = 0.25



class OfflineLanguageModel:
    """A :class:`LanguageModel` stand-in answering intent questions about a scene (see module docstring).

    Args:
        embedder: The text embedder ranking affordances.
        affordances: Extra or replacement label → description entries.
        margin: Classes scoring within this of the best class are candidates too.
        min_score: Below this cosine similarity nothing in the scene serves the need.
        absent_margin: Nothing serves the need either when a known class the scene lacks (a shower)
            fits it by this much better than the best class present.
        name: Provider name for events and errors.
    """

    def __init__(
        self,
        embedder: Embedder,
        affordances: Mapping[str, str] | None = None,
        margin: float = 0.05,
        min_score: float = 0.25,
        name: str = "offline_llm",
        absent_margin: float = 0.1,
    ) -> None:
        self.name = name
        self.embedder = embedder
        self.affordances = {**AFFORDANCES, **{fold_label(k): v for k, v in (affordances or {}).items()}}
        self.margin = float(margin)
        self.min_score = float(min_score)
        self.absent_margin = float(absent_margin)
        self.knowledge: Knowledge = knowledge()

    def check(self) -> str:
        """Check the embedder; return a one-line description."""
        return f"offline intent stand-in over {self.embedder.check()}"

    def chat(self, messages: Sequence[Message], schema: type[BaseModel] | None = None) -> str:
        """Answer an intent conversation with IntentResolution (or ReferenceParse) JSON."""
        try:
            request, objects = parse_intent_messages(messages)
        except ValueError as exc:
            raise ModelError(
                f"{self.name}: cannot read the conversation ({exc}); the offline stand-in answers only "
                "prompts built by missiontree.reasoning.prompts.intent_messages — configure an LLM "
                "provider (openai) for other questions") from None
        if schema is ReferenceParse:
            labels = sorted({str(o.get("label", "")) for o in objects} | set(self.affordances))
            parsed = parse_reference(request, labels, _rooms(objects))
            if parsed is None:
                raise ModelError(f"{self.name}: {request!r} names no known object class")
            return parsed.model_dump_json()
        if schema is not None and schema is not IntentResolution:
            raise ModelError(
                f"{self.name}: cannot answer with the {schema.__name__} schema (only IntentResolution "
                "and ReferenceParse); configure an LLM provider (openai) for this question")
        return self.resolve(request, objects).model_dump_json()

    # -- resolution ------------------------------------------------------------------------------

    def resolve(self, request: str, objects: Sequence[Mapping[str, Any]]) -> IntentResolution:
        """The objects satisfying ``request``: a reference if it names a class, else a need."""
        objects = [o for o in objects if "id" in o and "label" in o]
        labels = sorted({str(o["label"]) for o in objects})
        reading = self.knowledge.read(request)
        if reading.compounds and reading.empty:
            # its only object words sit inside a compound naming something else ("a filter bed")
            return IntentResolution(candidates=[], reason=(
                f"no object in the scene serves {request!r}: it names a {reading.compounds[0]}, which is "
                "no object this reasoner knows"))
        reference = parse_reference(request, labels, _rooms(objects)) if labels else None
        if reference is not None:
            return self._resolve_reference(reference, objects)
        return self._resolve_need(request, objects, labels)

    def _resolve_need(self, request: str, objects: Sequence[Mapping[str, Any]],
                      labels: list[str]) -> IntentResolution:
        if not labels:
            return IntentResolution(candidates=[], reason="the scene holds no objects")
        kb = self.knowledge
        reading = kb.read(request)
        how = "knowledge"
        if reading.empty:
            reading, how = self._embedded_reading(request, reading), "embedding"
        if reading.empty:
            unknown = f" (words it does not know: {', '.join(reading.unknown)})" if reading.unknown else ""
            if reading.met:
                unknown += f" ({', '.join(reading.met)}: a need said to be met, not had)"
            return IntentResolution(candidates=[], reason=(
                f"no object in the scene serves {request!r}: it expresses no need and names no object "
                f"this reasoner knows{unknown}"))
        present = {label for label in labels} | {fold_label(label) for label in labels}
        scores = {label: kb.score(label if label in kb.serves else fold_label(label), reading)
                  for label in labels}
        order = sorted(labels, key=lambda label: (-scores[label][0], label))
        best = scores[order[0]][0]
        absent = [(kb.score(label, reading), label) for label in kb.labels if label not in present]
        (lacking, lacking_why), lacking_label = max(absent, default=((0.0, ""), ""))
        said = ", ".join(f"{need} ({word})" for need, (_, word) in sorted(reading.needs.items()))
        said = said or ", ".join(sorted({word for _, word in reading.named.values()}))
        if lacking_why and self._serves_same(order[0], lacking_why, reading):
            lacking = 0.0  # a laptop for boredom without a TV: the same need, served less well but served
        if best < STRONG or lacking > best + self.absent_margin:
            ranked = ", ".join(f"{label} {scores[label][0]:.2f}" for label in order[:3])
            wants = (f"; it calls for a {lacking_label} ({lacking_why}), which the scene lacks"
                     if lacking > max(STRONG, best + self.absent_margin) else "")
            return IntentResolution(candidates=[], reason=(
                f"no object in the scene serves {request!r}: it asks for {said}{wants} (best present: "
                f"{ranked}; {STRONG:.2f} needed, by {how})"))
        # every class that serves it strongly, best first: when the best one cannot be reached (no
        # place to stand by the TV), the next tier (the laptop for boredom) is still on offer
        chosen = [label for label in order if scores[label][0] >= STRONG]
        chosen, split = _one_reading(chosen, scores, reading, kb)
        if split:
            return IntentResolution(candidates=[], reason=(
                f"no object chosen for {request!r}: {split}, and nothing present serves both strongly "
                "(an ambiguous request is not guessed at)"))
        ids = [str(o["id"]) for label in chosen for o in objects if o["label"] == label]
        ranked = ", ".join(f"{label} {scores[label][0]:.2f}" for label in order[:4])
        serve = "serves" if len(chosen) == 1 else "serve"
        why = scores[chosen[0]][1]
        reason = f"{'/'.join(chosen)} {serve} {why} (by {how}; ranked: {ranked})"
        return IntentResolution(candidates=ids, reason=reason)

    def _serves_same(self, present: str, lacking_why: str, reading: Reading) -> bool:
        """Whether the best present class strongly serves the need a lacking class wins by.

        A class the scene lacks vetoes the present ones only when it answers a part of the request
        they do not (a washing machine washes the *clothes*, a sink only washes; a shower is named);
        when the present class serves the same need strongly (a laptop for boredom, the TV lacking), it
        stands in.
        """
        need = lacking_why.split(" (", 1)[0]
        if need == "named" or need not in reading.needs:
            return False
        label = present if present in self.knowledge.serves else fold_label(present)
        return reading.needs[need][0] * self.knowledge.serves.get(label, {}).get(need, 0.0) >= STRONG

    def _embedded_reading(self, request: str, known: Reading) -> Reading:
        """The need a request's words leave unsaid, by embedding similarity (see :func:`embedded_need`)."""
        return embedded_reading(self.embedder, request, known, self.knowledge, self.margin)

    def _resolve_reference(
        self, ref: ReferenceParse, objects: Sequence[Mapping[str, Any]]
    ) -> IntentResolution:
        matching = _of_label(objects, ref.label)
        described = [o for o in matching if all(_has_attribute(o, a) for a in ref.attributes)]
        what = " ".join([*ref.attributes, ref.label])
        if not described:
            seen = sorted({a for o in matching for a in _attributes(o)})
            return IntentResolution(candidates=[], reference=ref, reason=(
                f"no {what} in the scene ({len(matching)} {ref.label} with attributes {seen})"))
        if ref.relation is None or ref.anchor is None:
            return IntentResolution(candidates=[str(o["id"]) for o in described], reference=ref,
                                    reason=f"{len(described)} {what} in the scene")
        anchors = _of_label(objects, ref.anchor)
        in_room = [o for o in described if str(o.get("room", "")).lower() == ref.anchor.lower()]
        if not anchors and ref.relation == "in":
            return IntentResolution(candidates=[str(o["id"]) for o in in_room], reference=ref,
                                    reason=f"{len(in_room)} {what} in the {ref.anchor}")
        distances = [(_relation_distance(o, anchors, ref.relation, objects), o) for o in described]
        scored = [(d, o) for d, o in distances if d is not None]
        scored.sort(key=lambda pair: (pair[0], str(pair[1]["id"])))
        relation = ref.relation.replace("_", " ")
        return IntentResolution(candidates=[str(o["id"]) for _, o in scored], reference=ref, reason=(
            f"{len(scored)} {what} {relation} a {ref.anchor}" if scored
            else f"no {what} {relation} a {ref.anchor} ({len(anchors)} {ref.anchor} in the scene)"))


#: A class serving another need than the best class's is offered beside it only when the request says
#: that need this nearly as strongly ("I'm thirsty and bored": both; "watch a documentary": not the
#: printer, which serves the documentary's other sense, print, read at 0.85 beside watching at 1.0).
NEED_MARGIN = 0.05


def _need_of(why: str) -> str:
    """The need (or ``named``) a score's reason gives first: "drink (thirsty)" -> "drink"."""
    return why.split(" (", 1)[0]


def _one_reading(chosen: list[str], scores: Mapping[str, tuple[float, str]],
                 reading: Reading, kb: Knowledge) -> tuple[list[str], str]:
    """The chosen classes that serve what the request says most surely, or why it says two things at once.

    A class kept beside the best one serves the same need (the laptop beside the TV for boredom), or
    another need the request says within :data:`NEED_MARGIN` as strongly by another word ("I'm
    thirsty and bored"). When one word alone says two needs equally ("a documentary": watching, or
    printing; "muddy": washing, or rain) and different classes serve each, only the classes serving
    both strongly are kept ("swallow": the refrigerator); when there is none the request is
    ambiguous: the second item says so, and nothing is chosen (an abstention, not a guess).
    """
    if not chosen or not reading.needs:
        return chosen, ""
    top = _need_of(scores[chosen[0]][1])
    if top not in reading.needs:
        return chosen, ""
    strength, word = reading.needs[top]
    kept = [chosen[0]]
    for label in chosen[1:]:
        need = _need_of(scores[label][1])
        if need == top or need not in reading.needs:
            kept.append(label)
            continue
        other, other_word = reading.needs[need]
        if other < strength - NEED_MARGIN:
            continue  # a weaker echo of another need: not offered
        if other_word == word:
            both = [c for c in chosen if min(kb.serves.get(fold_label(c), kb.serves.get(c, {})).get(n, 0.0)
                                             for n in (top, need)) >= STRONG]
            return both, "" if both else f"'{word}' says {top} or {need} equally ({chosen[0]} or {label})"
        kept.append(label)
    return kept, ""


def _of_label(objects: Sequence[Mapping[str, Any]], label: str) -> list[Mapping[str, Any]]:
    """The objects listed as ``label`` itself; when none is, those whose label folds to the same class.

    A scene that lists desks and tables keeps them apart ("the desk" is no table), while a scene
    listing a "couch" still answers "the sofa".
    """
    own = [o for o in objects if normalise(str(o["label"])) == normalise(label)]
    return own or [o for o in objects if fold_label(str(o["label"])) == fold_label(label)]


def _rooms(objects: Sequence[Mapping[str, Any]]) -> list[str]:
    return sorted({str(o["room"]) for o in objects if o.get("room")})


def _attributes(obj: Mapping[str, Any]) -> list[str]:
    """Attribute words of a scene object: ``attributes`` (list or text), ``colour``/``color``, ``size``."""
    words: list[str] = []
    raw = obj.get("attributes", [])
    if isinstance(raw, str):
        raw = raw.replace(",", " ").split()
    if isinstance(raw, Mapping):
        raw = list(raw.values())
    for key in ("colour", "color", "size", "description"):
        if obj.get(key):
            text = str(obj[key])
            if key == "description":  # the object's own words only: "a cup by the blue bottle" is not blue
                text = split_relation(text)[0]
            raw = [*raw, *text.replace(",", " ").split()]
    for word in raw:
        words.append(canonical_colour(str(word)))
    return words


def _has_attribute(obj: Mapping[str, Any], attribute: str) -> bool:
    return canonical_colour(attribute) in _attributes(obj)


def _xy(obj: Mapping[str, Any]) -> tuple[float, float] | None:
    try:
        return float(obj["x"]), float(obj["y"])
    except (KeyError, TypeError, ValueError):
        return None


def _relation_distance(obj: Mapping[str, Any], anchors: Sequence[Mapping[str, Any]],
                       relation: str, objects: Sequence[Mapping[str, Any]] = ()) -> float | None:
    """Distance to the nearest anchor the relation holds for, None when it holds for none.

    A relation holds when the scene graph has the edge (``near`` and ``next_to`` either way round:
    the graph relates the smaller object to the larger), or when the relations' own geometry
    (:func:`missiontree.semantics.relations.compute_relations`) finds it from the listed positions,
    rooms and sizes. Nearness alone never makes "on" or "in front of" true.
    """
    accepted = _ACCEPTS.get(relation, frozenset({relation}))
    symmetric = relation in _SYMMETRIC
    oid = str(obj.get("id"))
    held: set[str] = set()
    for anchor in anchors:
        aid = str(anchor.get("id"))
        if aid == oid:
            continue
        if any(_edge_to(edge, anchor, accepted) for edge in obj.get("relations", None) or []):
            held.add(aid)
        elif symmetric and any(_edge_to(edge, obj, accepted) for edge in anchor.get("relations", None) or []):
            held.add(aid)
    geometric = [(e.source_id, e.target_id) for e in compute_relations(_bodies(objects or [obj, *anchors]))
                 if e.relation in accepted]
    for source, target in geometric:
        if source == oid:
            held.add(target)
        elif symmetric and target == oid:
            held.add(source)
    for anchor in anchors:
        if str(anchor.get("id")) != oid and _sided(obj, anchor, relation):
            held.add(str(anchor.get("id")))
    where = _xy(obj)
    distances = []
    for anchor in anchors:
        if str(anchor.get("id")) not in held:
            continue
        at = _xy(anchor)
        distances.append(math.hypot(where[0] - at[0], where[1] - at[1]) if where and at else 0.0)
    return min(distances) if distances else None


#: Relations a request's relation is satisfied by (anything the graph relates is near).
_ACCEPTS: dict[str, frozenset[str]] = {"near": frozenset(RELATIONS), "next_to": frozenset({"next_to"})}
#: Relations that hold either way round.
_SYMMETRIC = frozenset({"near", "next_to"})


def _sided(obj: Mapping[str, Any], anchor: Mapping[str, Any], relation: str) -> bool:
    """A side relation by the relations' geometry when the listing gives the anchor's facing (``yaw``).

    As :mod:`missiontree.semantics.relations` decides it: within its ``near_gap``, and clearly
    (``side_ratio``) along the anchor's front-back or left-right axis; left and right as seen by
    someone in front of the anchor looking at it.
    """
    yaw, where, at = anchor.get("yaw"), _xy(obj), _xy(anchor)
    if relation not in _SIDES or not isinstance(yaw, int | float) or where is None or at is None:
        return False
    p = RelationParams()
    [src, anc] = _bodies([obj, anchor])
    dx, dy = where[0] - at[0], where[1] - at[1]
    gap = math.hypot(dx, dy) - max(src.w, src.d) / 2 - max(anc.w, anc.d) / 2
    if gap > p.near_gap:
        return False
    along = dx * math.cos(yaw) + dy * math.sin(yaw)
    own_left = -dx * math.sin(yaw) + dy * math.cos(yaw)
    if abs(along) >= p.side_ratio * abs(own_left):
        found = "in_front_of" if along > 0 else "behind"
    elif abs(own_left) >= p.side_ratio * abs(along):
        found = "right_of" if own_left > 0 else "left_of"
    else:
        return False
    return found == relation


_SIDES = frozenset({"in_front_of", "behind", "left_of", "right_of"})


def _edge_to(edge: Any, anchor: Mapping[str, Any], accepted: frozenset[str]) -> bool:
    """Whether a listed relation edge names ``anchor`` with one of the ``accepted`` relations."""
    if not isinstance(edge, Mapping) or str(edge.get("relation", "")) not in accepted:
        return False
    if "target_id" in edge:
        return str(edge.get("target_id")) == str(anchor.get("id"))
    return fold_label(str(anchor.get("label", ""))) == fold_label(str(edge.get("target")))


def _bodies(objects: Sequence[Mapping[str, Any]]) -> list[Body]:
    """Bodies of the listed objects with coordinates (height and size when the listing gives them)."""
    bodies = []
    for o in objects:
        at = _xy(o)
        if at is None or "id" not in o:
            continue
        size = o.get("size")
        w, d, h = (0.0, 0.0, 0.0)
        if isinstance(size, list | tuple) and len(size) >= 3:
            w, d, h = (float(v) for v in size[:3])
        try:
            z = float(o.get("z", 0.0) or 0.0)
        except (TypeError, ValueError):
            z = 0.0
        bodies.append(Body(str(o["id"]), at[0], at[1], z, max(w, 0.05), max(d, 0.05), max(h, 0.05),
                           str(o["room"]) if o.get("room") else None))
    return bodies
