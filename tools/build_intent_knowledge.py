"""Build ``missiontree/data/intent_knowledge.json``: what each object class is for, and the words of needs.

    apt-get install wordnet-base                       # WordNet 3.0 under /usr/share/wordnet
    python -m tools.build_intent_knowledge             # writes the knowledge file
    python -m tools.build_intent_knowledge --show      # also prints the seed senses, for review

The offline intent reasoner (:mod:`missiontree.reasoning.knowledge`) reads the file and needs nothing
else at run time. Two sources, both written per *label* or per *need*, never per command:

- **Affordances** (:data:`LABELS`): for each object class the system knows, its WordNet sense and the
  needs it serves with a strength (a bottle serves ``drink`` fully, a sink a little).
- **Need senses** (:data:`NEEDS`): for each need, a short description (the embedding fallback compares
  requests with it) and the WordNet senses that express it (``thirsty.a.2``: "feeling a need or desire
  to drink"). The lexicon is grown from them through WordNet's relations: the sense's own words,
  similar-to, derivations, attributes, also-see and entailments, and hyponyms to a stated depth
  (``beverage.n.1`` down to coffee, lemonade and cocoa), each step weaker.
- **Label words**: each label's sense's words and its hyponyms' words name that label (couch, armchair);
  its hypernyms up to two levels name every label under them (seat: chair, sofa, bench, stool).
- **Compounds**: WordNet's compound nouns that contain an object word without being one (filter bed),
  so that the runtime reads them whole, as something it does not know.

Senses are written ``word.pos.N`` (the N-th sense of ``word`` as WordNet orders them, most frequent
first) and printed with their glosses by ``--show``.
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from pathlib import Path

from missiontree.perception.colour import ALIASES, COLOUR_NAMES
from tools.wordnet_db import DEFAULT_ROOT, Synset, WordNet

OUT = Path(__file__).resolve().parents[1] / "src" / "missiontree" / "data" / "intent_knowledge.json"

#: need -> (description for the embedding fallback, [(sense, hyponym depth)]).
NEEDS: dict[str, tuple[str, list[tuple[str, int]]]] = {
    "drink": (
        "thirsty: wanting a drink of water, juice, coffee or tea",
        [
            ("thirsty.a.2", 0),
            ("thirst.n.1", 1),
            ("water.n.6", 0),
            ("drinking water.n.1", 0),
            ("drink.n.1", 1),
            ("drink.v.1", 2),
            ("beverage.n.1", 3),
            ("sip.v.1", 0),
            ("quench.v.1", 0),
        ],
    ),
    "eat": (
        "hungry: wanting to eat food, a meal or a snack",
        [
            ("hungry.a.1", 0),
            ("hunger.n.1", 1),
            ("eat.v.1", 2),
            ("eat.v.2", 1),
            ("food.n.1", 1),
            ("food.n.2", 2),
            ("meal.n.1", 2),
            ("snack.v.1", 0),
            ("starve.v.1", 0),
        ],
    ),
    "rest": (
        "tired: wanting to sit down, relax and rest",
        [
            ("tired.a.1", 0),
            ("fatigue.n.1", 1),
            ("rest.v.2", 1),
            ("sit.v.1", 1),
            ("sit.v.3", 1),
            ("relax.v.1", 1),
            ("seat.v.1", 0),
            ("tire.v.2", 0),
            ("exhausted.s.2", 0),
            ("weary.a.1", 0),
        ],
    ),
    "sleep": (
        "sleepy: wanting to lie down and sleep or nap",
        [
            ("sleepy.s.1", 0),
            ("sleep.v.1", 2),
            ("sleep.n.1", 1),
            ("nap.v.1", 0),
            ("lie down.v.1", 0),
            ("drowsy.s.1", 0),
            ("sleepiness.n.1", 0),
        ],
    ),
    "entertainment": (
        "bored: wanting entertainment, a film, a show or a game",
        [
            ("bored.s.1", 0),
            ("boredom.n.1", 0),
            ("entertainment.n.1", 2),
            ("play.v.5", 0),
            ("amuse.v.1", 0),
            ("amuse.v.2", 0),
            ("entertain.v.1", 0),
            ("movie.n.1", 2),
            ("television program.n.1", 1),
            ("watch.v.3", 0),
            ("game.n.2", 1),
            ("fun.n.1", 0),
            ("play.v.1", 1),
        ],
    ),
    "read": (
        "wanting to read a book, a novel or a story",
        [("read.v.1", 1), ("novel.n.1", 0), ("reading.n.1", 0), ("literature.n.1", 0)],
    ),
    "work": (
        "wanting to work on a computer: write emails, documents, browse the internet",
        [
            ("work.v.1", 0),
            ("electronic mail.n.1", 0),
            ("e-mail.v.1", 0),
            ("computer.n.1", 0),
            ("browse.v.3", 0),
            ("internet.n.1", 0),
            ("type.v.1", 0),
            ("compute.v.1", 0),
            ("program.v.2", 0),
            ("study.v.5", 0),
            ("homework.n.1", 0),
            ("spreadsheet.n.1", 0),
            ("online.a.2", 0),
        ],
    ),
    "print": (
        "wanting to print a document on paper",
        [("print.v.4", 1), ("printout.n.1", 0), ("document.n.1", 0), ("photocopy.v.1", 0)],
    ),
    "wash": (
        "wanting to wash hands, rinse or clean dishes with tap water",
        [
            ("wash.v.2", 1),
            ("wash.v.1", 0),
            ("rinse.v.1", 0),
            ("dirty.a.1", 0),
            ("tap water.n.1", 0),
            ("dishwashing.n.1", 0),
        ],
    ),
    "bathe": (
        "wanting to take a shower or a bath",
        [("bathe.v.1", 0), ("shower.v.3", 0), ("bath.n.1", 0), ("shower.n.1", 0), ("bathe.v.3", 0)],
    ),
    "toilet": (
        "needing the toilet",
        [("urinate.v.1", 1), ("defecate.v.1", 0), ("toilet.n.2", 0), ("toilet.n.1", 0)],
    ),
    "rain": (
        "keeping dry in the rain",
        [("rain.n.1", 1), ("rain.v.1", 1), ("wet.a.1", 0), ("drizzle.n.1", 0), ("storm.n.1", 1)],
    ),
    "carry": (
        "carrying belongings on a trip",
        [("carry.v.1", 0), ("pack.v.1", 0), ("luggage.n.1", 0), ("belongings.n.1", 0), ("hike.v.2", 0)],
    ),
    "dispose": (
        "throwing rubbish away",
        [("rubbish.n.1", 1), ("discard.v.1", 0), ("litter.n.2", 0), ("waste.n.1", 0)],
    ),
    "cook": (
        "cooking or heating food",
        [
            ("cook.v.1", 1),
            ("cook.v.2", 0),
            ("bake.v.1", 0),
            ("reheat.v.1", 0),
            ("heat.v.1", 0),
            ("roast.v.1", 0),
            ("toast.v.1", 0),
        ],
    ),
    "clothes": ("storing or changing clothes", [("clothing.n.1", 1), ("dress.v.1", 0), ("change.v.5", 0)]),
    "plant": (
        "looking at or watering plants",
        [("plant.n.2", 0), ("flower.n.1", 0), ("greenery.n.1", 0), ("houseplant.n.1", 0)],
    ),
    "communicate": (
        "calling or messaging someone",
        [("call.v.3", 0), ("telephone.v.1", 0), ("phone call.n.1", 0)],
    ),
    "talk": (
        "talking to someone",
        [("talk.v.1", 0), ("chat.v.1", 0), ("conversation.n.1", 0), ("lonely.a.1", 0)],
    ),
    "travel": (
        "travelling far away by car, plane or bike",
        [
            ("travel.v.2", 1),
            ("travel.v.3", 0),
            ("fly.v.1", 0),
            ("fly.v.3", 0),
            ("drive.v.1", 0),
            ("ride.v.2", 0),
            ("trip.n.1", 0),
            ("journey.n.1", 0),
        ],
    ),
    "swim": ("swimming", [("swim.v.1", 0), ("swimming.n.1", 0)]),
    "music": (
        "playing or listening to music",
        [("music.n.1", 1), ("sing.v.2", 0), ("play.v.3", 0), ("play.v.7", 0)],
    ),
    "medical": (
        "being hurt or sick and needing medicine",
        [
            ("hurt.v.6", 0),
            ("sick.a.1", 0),
            ("medicine.n.2", 1),
            ("bleed.v.1", 0),
            ("ill.a.1", 0),
            ("headache.n.2", 0),
            ("nauseated.a.1", 0),
        ],
    ),
    "groom": (
        "looking at oneself, brushing teeth or hair",
        [("brush.v.1", 0), ("toothbrush.n.1", 0), ("comb.v.1", 0), ("shave.v.1", 0), ("groom.v.2", 0)],
    ),
    "laundry": ("washing dirty clothes", [("laundry.n.1", 0), ("launder.v.1", 0)]),
    "leave": ("going out of the building", [("leave.v.1", 0), ("go out.v.1", 0), ("go out.v.2", 0)]),
    "pet": ("playing with or walking a pet", [("pet.n.1", 1)]),
    "time": ("knowing the time", [("clock time.n.1", 0), ("late.a.2", 0)]),
    "decorate": ("decorating a room", [("decorate.v.1", 0), ("decoration.n.1", 0)]),
}

#: label -> (WordNet sense, {need: strength}, present in scenes the robot maps (False: only named to
#: say that a need calls for something the scene lacks)).
LABELS: dict[str, tuple[str, dict[str, float]]] = {
    "bottle": ("bottle.n.1", {"drink": 1.0}),
    "cup": ("cup.n.1", {"drink": 1.0}),
    "wine glass": ("wineglass.n.1", {"drink": 0.9}),
    "bowl": ("bowl.n.3", {"eat": 0.6}),
    "refrigerator": ("refrigerator.n.1", {"eat": 1.0, "drink": 0.7}),
    "sink": ("sink.n.1", {"wash": 1.0, "drink": 0.4, "groom": 0.4}),
    "sofa": ("sofa.n.1", {"rest": 1.0, "sleep": 0.7, "entertainment": 0.2}),
    "chair": ("chair.n.1", {"rest": 1.0}),
    "bench": ("bench.n.1", {"rest": 1.0}),
    "stool": ("stool.n.1", {"rest": 0.8}),
    "bed": ("bed.n.1", {"sleep": 1.0, "rest": 0.8}),
    "tv": ("television receiver.n.1", {"entertainment": 1.0}),
    "laptop": ("laptop.n.1", {"work": 1.0, "entertainment": 0.7, "communicate": 0.6, "print": 0.3}),
    "book": ("book.n.2", {"read": 1.0, "entertainment": 0.7}),
    "bookshelf": ("bookshelf.n.1", {"read": 0.9, "entertainment": 0.6}),
    "backpack": ("backpack.n.1", {"carry": 1.0}),
    "handbag": ("bag.n.4", {"carry": 0.9}),
    "suitcase": ("bag.n.6", {"carry": 1.0, "travel": 0.4}),
    "umbrella": ("umbrella.n.1", {"rain": 1.0}),
    "potted plant": ("pot plant.n.1", {"plant": 1.0, "decorate": 0.8}),
    "vase": ("vase.n.1", {"plant": 0.6, "decorate": 0.8}),
    "table": ("table.n.2", {"eat": 0.5, "work": 0.5}),
    "dining table": ("dining table.n.1", {"eat": 0.75}),
    "desk": ("desk.n.1", {"work": 0.75}),
    "counter": ("counter.n.1", {"cook": 0.6, "eat": 0.4}),
    "oven": ("oven.n.1", {"cook": 1.0, "eat": 0.7}),
    "microwave": ("microwave.n.2", {"cook": 1.0, "eat": 0.8}),
    "toaster": ("toaster.n.2", {"cook": 0.8, "eat": 0.6}),
    "toilet": ("toilet.n.2", {"toilet": 1.0}),
    "trash can": ("ashcan.n.1", {"dispose": 1.0}),
    "printer": ("printer.n.3", {"print": 1.0}),
    "wardrobe": ("wardrobe.n.1", {"clothes": 1.0}),
    "cell phone": ("cellular telephone.n.1", {"communicate": 1.0, "entertainment": 0.4}),
    "clock": ("clock.n.1", {"time": 1.0}),
    "remote": ("remote control.n.1", {"entertainment": 0.5}),
    "keyboard": ("computer keyboard.n.1", {"work": 0.5}),
    "mouse": ("mouse.n.4", {"work": 0.4}),
    "person": ("person.n.1", {"talk": 1.0}),
    "teddy bear": ("teddy.n.1", {"entertainment": 0.5}),
    "sports ball": ("ball.n.1", {"entertainment": 0.6}),
    "toothbrush": ("toothbrush.n.1", {"groom": 1.0}),
    # common things scenes often lack: a need they serve better than anything present goes unserved
    "shower": ("shower.n.1", {"bathe": 1.0, "wash": 0.5}),
    "bathtub": ("bathtub.n.1", {"bathe": 1.0}),
    "washing machine": ("washer.n.3", {"laundry": 1.0, "clothes": 0.5}),
    "swimming pool": ("swimming pool.n.1", {"swim": 1.0}),
    "car": ("car.n.1", {"travel": 1.0}),
    "airplane": ("airplane.n.1", {"travel": 1.0}),
    "bicycle": ("bicycle.n.1", {"travel": 0.8}),
    "telephone": ("telephone.n.1", {"communicate": 1.0}),
    "piano": ("piano.n.1", {"music": 1.0}),
    "stove": ("stove.n.1", {"cook": 1.0, "eat": 0.6}),
    "mirror": ("mirror.n.1", {"groom": 0.8}),
    "door": ("door.n.1", {"leave": 1.0}),
    "first aid kit": ("first-aid kit.n.1", {"medical": 1.0}),
    "dog": ("dog.n.1", {"pet": 1.0}),
}

#: Labels whose objects WordNet files under a second sense too: the bookshelf of a room is WordNet's
#: bookcase (a piece of furniture with shelves), beside its bookshelf (a shelf on which to keep books).
MORE_SENSES: dict[str, tuple[str, ...]] = {"bookshelf": ("bookcase.n.1",)}

#: Colour words are attributes, never the name of a class.
COLOURS = frozenset(COLOUR_NAMES) | frozenset(ALIASES)
#: Weight of a word by how it was reached from a need's sense.
OWN, RELATED, SECOND, HYPONYM = 1.0, 0.85, 0.7, (0.85, 0.8, 0.75)
#: Weight of a word reached through a less frequent sense of it (see :func:`_rare`), and how far down
#: its senses that may be.
RARE, RARE_SENSES = 0.7, 4
#: The needs that are states of the body one says one is in ("I'm thirsty", "I'm beat").
STATE_NEEDS = frozenset({"drink", "eat", "rest", "sleep"})
#: Weight of a word whose most frequent sense's definition says the need ("tipple: drink moderately"):
#: above the reasoner's strong threshold (0.7), so that a label serving the need fully serves it.
GLOSS = 0.75
#: A definition is read for a need word in its first this many words (its genus or its verb).
GLOSS_WORDS = 5
#: The needs a definition is read for: bodily states and pastimes people say they have.
GLOSS_NEEDS = frozenset({"drink", "eat", "rest", "sleep", "wash", "bathe", "toilet"})
#: Definition words that turn the need around ("awake: not in a state of sleep"): not read past them.
#: ("lack of food" is hunger, so "lack" is no negation).
NEGATIONS = frozenset({"not", "no", "never", "free", "unable"})
#: A word reached from a need sense (not one of its own words) means the need only when the sense it
#: was reached through is among its this many most frequent senses.
FREQUENT_SENSES = 2
#: Relations from a sense to senses whose words mean the same need.
RELATIONS = ("&", "+", "=", "^", "*", ">", "$", "\\")
#: Words too general to say anything about a need on their own (light verbs, quantities).
GENERAL = frozenset(
    {
        "be",
        "have",
        "get",
        "take",
        "make",
        "do",
        "go",
        "come",
        "give",
        "put",
        "set",
        "use",
        "want",
        "need",
        "like",
        "feel",
        "let",
        "keep",
        "run",
        "turn",
        "hold",
        "move",
        "place",
        "thing",
        "something",
        "some",
        "one",
        "time",
        "way",
        "part",
        "piece",
        "bit",
        "lot",
        "stuff",
        "kind",
        "sort",
        "work",
        "act",
        "up",
        "out",
        "down",
        "off",
        "state",
        "see",
        "catch",
        "can",
        "wear",
        "fix",
        "ready",
        "go away",
        "john",
        "product",
        "production",
        "creation",
        "cause",
        "causal agent",
        "causal agency",
        "being",
        "organism",
        "support",
        "instrumentation",
        "artefact",
        "matter",
        "object",
        "unit",
        "whole",
        "artifact",
        "instrumentality",
        "device",
        "container",
        "structure",
        "system",
        "equipment",
        "article",
        "point",
        "line",
        "order",
    }
)


def sense(wn: WordNet, spec: str) -> Synset:
    """The synset of ``word.pos.N``."""
    word, pos, number = spec.rsplit(".", 2)
    found = wn.synsets(word, pos)
    index = int(number) - 1
    if index >= len(found):
        raise SystemExit(f"{spec}: WordNet has {len(found)} senses of {word!r} as {pos}")
    return found[index]


def _add(table: dict[str, dict[str, float]], word: str, key: str, weight: float) -> None:
    if word in GENERAL or len(word) < 2 or weight <= 0:
        return
    entry = table.setdefault(word, {})
    entry[key] = round(max(entry.get(key, 0.0), weight), 2)


def _frequent(wn: WordNet, word: str, synset: Synset) -> bool:
    """Whether ``synset`` is among the :data:`FREQUENT_SENSES` most frequent senses of ``word``.

    A word reached through a rare sense of it ("cut", a cut of meat) does not mean the need.
    """
    return synset in wn.synsets(word.replace(" ", "_"), synset.pos)[:FREQUENT_SENSES]


def _rare(wn: WordNet, word: str, synset: Synset, need: str) -> float:
    """The weight of a word reached from a need through a less frequent sense of it: :data:`RARE` or 0.

    An adjective said of oneself about a bodily state (:data:`STATE_NEEDS`) means it in that sense
    when the sense is among its :data:`RARE_SENSES` most frequent: "I'm dead" (similar to tired), "I'm
    empty" (similar to hungry); weakly (only a class serving the need fully serves it, and only when
    no word of the request names a need outright). Nouns and verbs in a rare sense mean something
    else first ("shake", "say", "stick") and colour words never mean a need.
    """
    if need not in STATE_NEEDS or synset.pos not in ("a", "s") or word in COLOURS:
        return 0.0
    senses = wn.synsets(word.replace(" ", "_"), "a")
    return RARE if synset in senses[:RARE_SENSES] else 0.0


def need_words(wn: WordNet, show: bool) -> dict[str, dict[str, float]]:
    """Map words to {need: weight}, grown from the need senses through WordNet's relations."""
    words: dict[str, dict[str, float]] = {}
    for need, (_, seeds) in NEEDS.items():
        for spec, depth in seeds:
            synset = sense(wn, spec)
            if show:
                print(f"{need:14} {spec:26} {synset.lemmas[:4]} -- {synset.gloss[:70]}")
            for lemma in synset.lemmas:
                _add(words, lemma, need, OWN)
            for near in wn.related(synset, *RELATIONS):
                for lemma in near.lemmas:
                    weight = RELATED if _frequent(wn, lemma, near) else _rare(wn, lemma, near, need)
                    _add(words, lemma, need, weight)
                if near.pos in ("a", "s"):
                    for far in wn.related(near, "&"):
                        for lemma in far.lemmas:
                            if _frequent(wn, lemma, far):
                                _add(words, lemma, need, SECOND)
            for hyponym, level in wn.hyponyms(synset, depth):
                for lemma in hyponym.lemmas:
                    weight = (HYPONYM[level - 1] if _frequent(wn, lemma, hyponym)
                              else _rare(wn, lemma, hyponym, need))
                    _add(words, lemma, need, weight)
    # a word means the need(s) it is closest to: "tired" is a seed of rest, and only echoes boredom
    return {w: {n: v for n, v in needs.items() if v == max(needs.values())} for w, needs in words.items()}


def _definition(gloss: str) -> list[str]:
    """The first words of a gloss's definition (before its examples), lower case."""
    text = gloss.split(";")[0].split('"')[0].lower()
    return re.findall(r"[a-z]+(?:-[a-z]+)?", text)


def gloss_words(wn: WordNet, words: dict[str, dict[str, float]],
                named: set[str]) -> dict[str, dict[str, float]]:
    """Adjectives and verbs the lexicon lacks whose most frequent sense is *defined* by a need.

    WordNet defines "tipple" as "drink moderately but regularly" and "wolfish" as "devouring or craving
    food in great quantities": such a word, whose first sense's definition names within its first
    :data:`GLOSS_WORDS` words a word of a seed sense of exactly one of the :data:`GLOSS_NEEDS` whose
    most frequent sense that seed is, means that need at :data:`GLOSS`. Nouns are not read this way (a noun
    mentioning water is no drink), nor needs whose words are everyday verbs (carry, type, plant).
    """
    own: dict[str, set[str]] = {}
    for need, (_, seeds) in NEEDS.items():
        for spec, _ in seeds if need in GLOSS_NEEDS else ():
            synset = sense(wn, spec)
            for lemma in synset.lemmas:  # a word whose most frequent sense is the need's ("water" is not)
                if len(lemma) > 3 and lemma not in GENERAL and wn.synsets(lemma, synset.pos)[:1] == [synset]:
                    own.setdefault(lemma, set()).add(need)
    own = {w: needs for w, needs in own.items() if len(needs) == 1}
    found: dict[str, dict[str, float]] = {}
    for pos in ("a", "v"):
        for lemma in wn._index[pos]:  # noqa: SLF001 - the reader's own table
            word = lemma.replace("_", " ")
            if (word in words or word in named or word in GENERAL or word in COLOURS or len(word) < 3
                    or word.startswith(("un", "in", "non"))):
                continue
            first = wn.synsets(lemma, pos)[:1]
            if not first:
                continue
            reach = _definition(first[0].gloss)[:GLOSS_WORDS]
            for i, token in enumerate(reach):
                if token in NEGATIONS:
                    break
                pair = f"{token} {reach[i + 1]}" if i + 1 < len(reach) else ""
                bases = [b.replace("_", " ") for p in ("n", "v") for b in wn.base_forms(token, p)]
                hit = next((own[w] for w in (pair, token, *bases) if w in own), None)
                if hit:
                    found[word] = {need: GLOSS for need in hit}
                    break
    return found


#: Words of :data:`GENERAL` that still name the things under them when said as the object asked for ("the
#: container", "some equipment"); the rest ("being", "product", "article") say too little in a request.
CATEGORY_WORDS = frozenset({"container", "device", "equipment", "instrumentality", "instrumentation",
                            "artifact", "artefact", "organism"})
#: A hypernym names the labels under it only from this depth below WordNet's root on (artifact, living
#: thing and what is below them): "object", "whole" and "entity" name everything and so nothing.
MIN_GENERAL_DEPTH = 4


def _depth(wn: WordNet, synset: Synset, memo: dict[str, int]) -> int:
    """The length of the shortest hypernym chain from ``synset`` up to WordNet's root."""
    if synset.key not in memo:
        memo[synset.key] = 0
        ups = wn.related(synset, "@", "@i")
        memo[synset.key] = 1 + min(_depth(wn, up, memo) for up in ups) if ups else 0
    return memo[synset.key]


def label_words(wn: WordNet) -> tuple[dict[str, str], dict[str, list[str]]]:
    """(word -> label it names, word -> labels a more general word covers).

    A label's own sense's words name it; a kind of it (a hyponym, two levels down) names the label
    nearest above it ("escritoire", a kind of desk, names the desk although a desk is a kind of
    table). Every hypernym of a label down from :data:`MIN_GENERAL_DEPTH` names all the labels under it
    (seat: chair, sofa, bench, stool; personal computer: laptop), when that is among the two most
    frequent senses of the word ("set" is a group before it is a television set). A word naming two
    classes in senses a rank apart or less names neither (:func:`_frequent_label`).
    """
    names: dict[str, str] = {}
    general: dict[str, set[str]] = {}
    senses = [(label, sense(wn, spec)) for label, (spec, _) in LABELS.items()]
    senses += [(label, sense(wn, spec)) for label, specs in MORE_SENSES.items() for spec in specs]
    synsets = {label: sense(wn, spec) for label, (spec, _) in LABELS.items()}
    for label in synsets:
        names.setdefault(label, label)
    for label, synset in senses:  # a label's own words first, then hyponyms' words
        for lemma in synset.lemmas:
            if lemma not in GENERAL:
                names.setdefault(lemma, label)
    nearest: dict[str, tuple[int, str]] = {}
    own = {synset.key for _, synset in senses}
    below: dict[str, set[str]] = {synset.key: {label} for label, synset in senses}   # sense -> labels
    for label, synset in senses:
        # kinds of people are roles, not what a camera sees ("red" is a kind of radical)
        for hyponym, level in wn.hyponyms(synset, 0 if label == "person" else 2):
            below.setdefault(hyponym.key, set()).add(label)
            if hyponym.key in own:
                continue
            for lemma in hyponym.lemmas:
                if lemma not in GENERAL and lemma not in COLOURS and lemma not in names:
                    if lemma not in nearest or level < nearest[lemma][0]:
                        nearest[lemma] = (level, label)
    names.update({lemma: label for lemma, (_, label) in nearest.items()})
    # label -> the labels that are kinds of it (a desk is a kind of table)
    kinds = {label: {other for other, key in ((o, sy.key) for o, sy in senses) if other != label
                     and label in below.get(key, set())} for label in synsets}
    for lemma in [w for w in names if w not in synsets]:
        named = _frequent_label(wn, lemma, below, kinds)
        if named is None:
            del names[lemma]  # "davenport": a sofa, then a desk
        else:
            names[lemma] = named  # "couch": a sofa first, a psychiatrist's bed only in its third sense
    closures_of = [(label, wn.hypernym_closure(synset)) for label, synset in senses]
    memo: dict[str, int] = {}
    accepted: set[tuple[str, str]] = set()   # (word, hypernym) pairs that name what is under them
    for _, closure in closures_of:
        for level, hypernym in enumerate(closure):
            if _depth(wn, hypernym, memo) < MIN_GENERAL_DEPTH:
                continue
            for lemma in hypernym.lemmas:
                if lemma in names or lemma in COLOURS or lemma in GENERAL - CATEGORY_WORDS:
                    continue
                # a label's two nearest hypernyms in any sense (a seat, a vessel); farther ones in a
                # frequent sense of the word
                if level < 2 or _frequent(wn, lemma, hypernym):
                    accepted.add((lemma, hypernym.key))
    for label, closure in closures_of:
        keys = {hypernym.key for hypernym in closure}
        for lemma, key in accepted:
            if key in keys:
                general.setdefault(lemma, set()).add(label)
    return names, {w: sorted(ls) for w, ls in general.items()}


def _frequent_label(wn: WordNet, word: str, below: dict[str, set[str]],
                    kinds: dict[str, set[str]]) -> str | None:
    """The label ``word`` names in its most frequent sense that names one; None when two are as frequent.

    A sense names a label when it is the label's own sense or a kind of it (two levels down), the
    nearest label only (a writing desk is a desk, though a desk is a kind of table). A word naming a
    class in one sense and another class only in a sense two or more ranks rarer names the first
    ("couch": a sofa, a psychiatrist's bed third); one whose senses name two classes a rank apart or
    less ("davenport": a sofa, then a desk; "throne": a chair of state, then a toilet) names neither:
    it is not guessed at.
    """
    ranked: list[tuple[int, str]] = []
    for rank, synset in enumerate(wn.synsets(word.replace(" ", "_"), "n")):
        labels = below.get(synset.key, set())
        ranked += [(rank, label) for label in labels if not any(o in kinds[label] for o in labels)]
    if not ranked:
        return None
    first_rank, first = ranked[0]
    if any(label != first and rank <= first_rank + 1 for rank, label in ranked):
        return None
    return first


def irregular_forms(wn: WordNet, words: set[str]) -> dict[str, str]:
    """Irregular inflections (WordNet's exception lists) of lexicon words: "slept" -> "sleep"."""
    forms: dict[str, str] = {}
    for pos in ("n", "v", "a"):
        for inflected, bases in wn._exc[pos].items():  # noqa: SLF001 - the reader's own table
            for base in bases:
                text = base.replace("_", " ")
                if text in words and inflected.replace("_", " ") not in words:
                    forms.setdefault(inflected.replace("_", " "), text)
    return forms


def _plain(word: str) -> str:
    """A word as the runtime reads requests: hyphens are spaces ("world-weary" -> "world weary")."""
    return " ".join(word.replace("-", " ").split())


def compounds(wn: WordNet, known: set[str], objects: set[str]) -> list[str]:
    """WordNet's compound nouns that contain an object word but are no known word themselves.

    "filter bed" is not a bed and "lighting fixture" not a plumbing fixture: read as a whole, such a
    compound names something this knowledge does not know, instead of the object its words contain.
    """
    found = set()
    for lemma in wn._index["n"]:  # noqa: SLF001 - the reader's own table
        words = _plain(lemma.replace("_", " "))
        if " " in words and words not in known and any(w in objects for w in words.split()):
            found.add(words)
    return sorted(found)


def build(root: Path, show: bool = False) -> dict[str, object]:
    """The knowledge document."""
    wn = WordNet(root)
    words = need_words(wn, show)
    names, general = label_words(wn)
    words = {**gloss_words(wn, words, set(names) | set(general)), **words}
    words = {_plain(w): v for w, v in words.items()}
    names = {_plain(w): label for w, label in names.items()}
    general = {_plain(w): labels for w, labels in general.items()}
    forms = irregular_forms(wn, set(words) | set(names) | set(general))
    objects = {w for w in (*names, *general) if " " not in w}
    return {
        "about": "Built by tools/build_intent_knowledge.py from WordNet 3.0 (Princeton University, "
        "WordNet 3.0 license) and per-label affordances; do not edit by hand.",
        "needs": {need: description for need, (description, _) in NEEDS.items()},
        "labels": {label: {"serves": serves} for label, (_, serves) in LABELS.items()},
        "need_words": dict(sorted(words.items())),
        "label_words": dict(sorted(names.items())),
        "general_words": dict(sorted(general.items())),
        "forms": dict(sorted(forms.items())),
        "compounds": compounds(wn, set(words) | set(names) | set(general), objects),
    }


def main(argv: list[str] | None = None) -> int:
    """Build and write the knowledge file."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--wordnet", type=Path, default=DEFAULT_ROOT)
    parser.add_argument("--out", type=Path, default=OUT)
    parser.add_argument("--show", action="store_true", help="print each need sense with its gloss")
    args = parser.parse_args(argv)
    document = build(args.wordnet, args.show)
    args.out.write_text(json.dumps(document, sort_keys=False, separators=(",", ":")) + "\n", encoding="utf-8")
    sizes = {k: len(v) for k, v in document.items() if isinstance(v, dict)}
    print(f"wrote {args.out} ({args.out.stat().st_size // 1024} KiB): {sizes}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
