"""Build the intent benchmark's test-split words: paraphrases from WordNet, not written by the team.

    apt-get install wordnet-base
    python -m tools.build_intent_test_commands     # writes benchmarks/data/intent_test_words.json

Written once from the templates below and not adjusted to make figures better. Sources:

- **Need paraphrases**: the senses of the need words of the dev split's commands (thirsty, tired,
  bored, hungry, a drink, sit, sleep, lie down, read, a film, rain, print a document), each with the
  objects the dev split judges to satisfy it. Each sense gives up to eight words: its WordNet
  synonyms, its hypernyms' head words, an adjective's state nouns (thirst) and similar-to words; each
  goes into a template of its part of speech that no dev command uses. The judgement is the dev
  sense's (a hypernym can make a command vaguer than its sense; it is judged as the sense all the
  same).
- **Object names**: each label's WordNet synonyms (judged: that label) and its hypernyms' head words
  (judged: every label whose sense lies under it).
- **Absent things**: artifact nouns from WordNet that are no label's sense, kind or family, taken at a
  fixed stride (judged: nothing satisfies them).

The benchmark adds referential commands by colour, room and relation from each test world's graph.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from tools.build_intent_knowledge import COLOURS, LABELS, sense
from tools.wordnet_db import WordNet

OUT = Path(__file__).resolve().parents[1] / "benchmarks" / "data" / "intent_test_words.json"

DRINK = ["bottle", "cup", "refrigerator", "sink"]
REST = ["sofa", "chair", "bed", "stool", "bench"]
FUN = ["tv", "laptop", "book", "bookshelf"]
FOOD = ["refrigerator", "microwave", "oven", "dining table"]

#: The senses of the dev commands' need words and the objects the dev split judges to satisfy them.
DEV_SENSES: list[tuple[str, list[str]]] = [
    ("thirsty.a.2", DRINK),
    ("beverage.n.1", DRINK),
    ("drink.v.1", DRINK),
    ("tired.a.1", REST),
    ("sit.v.1", REST),
    ("rest.v.2", REST),
    ("lie down.v.1", REST),
    ("bored.s.1", FUN),
    ("hungry.a.1", FOOD),
    ("sleep.v.1", ["bed", "sofa"]),
    ("read.v.1", ["book", "bookshelf"]),
    ("movie.n.1", ["tv", "laptop"]),
    ("rain.n.1", ["umbrella"]),
    ("print.v.4", ["printer"]),
    ("document.n.1", ["printer"]),
]

#: Templates by part of speech; none is the shape of a dev command.
TEMPLATES = {
    "a": ["Honestly, I feel so {w} right now.", "Ugh, I'm {w} again."],
    "s": ["Honestly, I feel so {w} right now.", "Ugh, I'm {w} again."],
    "v": ["Is there somewhere I could {w}?", "Help me {w}, would you?"],
    "n": ["Any chance of some {w} around here?", "Where would I go for {w}?"],
}
SYNONYM_TEMPLATE = "Could you take me to a {w}?"
HYPERNYM_TEMPLATE = "Any {w} will do, take me to one."
#: Words a need sense gives at most (its synonyms, hypernym, state noun, then similar words).
PER_SENSE = 8
#: Every how many-th artifact noun is taken as an absent thing, and how many.
ABSENT_STRIDE, ABSENT_COUNT = 97, 24


def need_paraphrases(wn: WordNet) -> list[dict[str, object]]:
    """Commands from the dev need senses' WordNet neighbours."""
    out: list[dict[str, object]] = []
    seen: set[str] = set()
    for spec, satisfied in DEV_SENSES:
        synset = sense(wn, spec)
        own = spec.rsplit(".", 2)[0]
        words: list[tuple[str, str, str]] = [(w, synset.pos, "synonym") for w in synset.lemmas]
        for near in wn.related(synset, "@"):
            words.append((near.lemmas[0], near.pos, "hypernym"))
        if synset.pos in ("a", "s"):  # an adjective's state noun (thirst); other derivations name agents
            for near in wn.related(synset, "+"):
                words += [(w, near.pos, "derivation") for w in near.lemmas]
        for near in wn.related(synset, "&"):
            words += [(w, near.pos, "similar") for w in near.lemmas]
        words = [w for w in words if w[0] != own]
        for i, (word, pos, how) in enumerate(words[:PER_SENSE]):
            if word in seen:
                continue
            seen.add(word)
            templates = TEMPLATES[pos]
            out.append({"command": templates[i % len(templates)].format(w=word), "satisfied_by": satisfied,
                        "source": f"{spec} {how} {word}"})
    return out


def object_names(wn: WordNet) -> list[dict[str, object]]:
    """Commands naming a label by a WordNet synonym or a hypernym."""
    synsets = {label: sense(wn, spec) for label, (spec, _) in LABELS.items()}
    closures = {label: {s.key for s in wn.hypernym_closure(synset)} for label, synset in synsets.items()}
    out: list[dict[str, object]] = []
    seen: set[str] = set(LABELS)
    for label, synset in synsets.items():
        for word in synset.lemmas:
            if word not in seen:
                seen.add(word)
                out.append({"command": SYNONYM_TEMPLATE.format(w=word), "satisfied_by": [label],
                            "source": f"{label} synonym {word}"})
        for hypernym in wn.related(synset, "@"):
            under = sorted(other for other, keys in closures.items() if hypernym.key in keys)
            word = hypernym.lemmas[0]
            if word not in seen:
                seen.add(word)
                out.append({"command": HYPERNYM_TEMPLATE.format(w=word), "satisfied_by": under,
                            "source": f"{label} hypernym {word}"})
    return out


def absent_things(wn: WordNet) -> list[dict[str, object]]:
    """Commands naming artifacts no label is, is a kind of, or stands under."""
    synsets = {label: sense(wn, spec) for label, (spec, _) in LABELS.items()}
    excluded: set[str] = set()
    for synset in synsets.values():
        excluded.add(synset.key)
        excluded |= {s.key for s in wn.hypernym_closure(synset)}
        excluded |= {s.key for s, _ in wn.hyponyms(synset, 6)}
    artifacts = [s for s, _ in wn.hyponyms(sense(wn, "artifact.n.1"), 4) if s.key not in excluded]
    artifacts.sort(key=lambda s: s.key)
    out: list[dict[str, object]] = []
    artifacts = [s for s in artifacts if s.lemmas[0] not in COLOURS]
    for synset in artifacts[::ABSENT_STRIDE][:ABSENT_COUNT]:
        word = synset.lemmas[0]
        out.append({"command": SYNONYM_TEMPLATE.format(w=word), "satisfied_by": [],
                    "source": f"absent {synset.name}"})
    return out


def main() -> int:
    """Write the test words file."""
    wn = WordNet()
    document = {
        "about": "Built by tools/build_intent_test_commands.py from WordNet 3.0; do not edit by hand.",
        "needs": need_paraphrases(wn),
        "objects": object_names(wn),
        "absent": absent_things(wn),
    }
    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.write_text(json.dumps(document, indent=1) + "\n", encoding="utf-8")
    print(f"wrote {OUT}: " + ", ".join(f"{k} {len(v)}" for k, v in document.items() if isinstance(v, list)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
