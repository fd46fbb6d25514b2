"""Referential phrases read without a language model: label + attributes + spatial relation.

"the grey backpack in front of the sofa" → ``ReferenceParse(label="backpack", attributes=["grey"],
relation="in_front_of", anchor="sofa")``. The label and the anchor must be among the labels the
caller knows (the scene's object classes, or room types for ``in the kitchen``); synonyms and
plurals are folded (couch → sofa, mugs → cup). Attributes are colour names (canonical, as
:mod:`missiontree.perception.colour` names them) and size words.
"""

from __future__ import annotations

from collections.abc import Iterable
from functools import lru_cache

from missiontree.perception.colour import ALIASES, COLOUR_NAMES, canonical_colour
from missiontree.reasoning.knowledge import knowledge, normalise
from missiontree.reasoning.schemas import ReferenceParse

#: Words people use for a class, folded to the name detectors and worlds use.
SYNONYMS: dict[str, str] = {
    "couch": "sofa", "settee": "sofa", "mug": "cup", "glass": "cup", "television": "tv",
    "telly": "tv", "fridge": "refrigerator", "rucksack": "backpack", "bag": "backpack",
    "notebook": "laptop", "computer": "laptop", "plant": "potted plant", "desk": "table",
    "water bottle": "bottle", "flask": "bottle", "armchair": "chair",
    "human": "person", "man": "person", "woman": "person", "people": "person",
}

#: Relation phrases, longest first so "to the left of" wins over "left of".
RELATION_PHRASES: tuple[tuple[str, str], ...] = (
    ("to the left of", "left_of"), ("to the right of", "right_of"), ("in front of", "in_front_of"),
    ("on top of", "on"), ("next to", "next_to"), ("close to", "near"), ("left of", "left_of"),
    ("right of", "right_of"), ("behind", "behind"), ("beside", "next_to"), ("near", "near"),
    ("by", "near"), ("inside", "in"), ("on", "on"), ("in", "in"),
)

SIZE_WORDS: dict[str, str] = {"small": "small", "little": "small", "tiny": "small", "big": "large",
                              "large": "large", "huge": "large", "tall": "tall", "medium": "medium"}

#: Places a relation may name that are not things to find ("the backpack on the floor").
GENERIC_PLACES = frozenset({"floor", "ground", "here", "there", "room", "house", "building", "left", "right",
                            "me", "you", "it", "way", "moment", "morning", "evening", "minute"})
_FILLER = frozenset({"the", "a", "an", "my", "this", "that", "your", "our", "please", "now"})


def fold_label(label: str) -> str:
    """The canonical name of a class word: synonyms folded, a plural 's' dropped when that helps.

    Beyond :data:`SYNONYMS`, the words WordNet gives a known class (its synonyms and kinds: settee,
    armchair) fold to it too (:func:`label_words`).
    """
    word = normalise(label).replace("_", " ")
    if word in SYNONYMS:
        return SYNONYMS[word]
    if word.endswith("s") and word[:-1] in SYNONYMS:
        return SYNONYMS[word[:-1]]
    words = _lexicon()
    if word not in words and word.endswith("s") and word[:-1] in words:
        return words[word[:-1]]
    return words.get(word, word)


@lru_cache(maxsize=1)
def _lexicon() -> dict[str, str]:
    """Map each word to the label it names, from the shipped knowledge (empty when it cannot be read)."""
    try:
        return dict(knowledge().label_words)
    except (OSError, ValueError, KeyError):
        return {}


@lru_cache(maxsize=1)
def label_words() -> dict[str, tuple[str, ...]]:
    """Map each label to the other words that name it (from the shipped knowledge)."""
    by_label: dict[str, list[str]] = {}
    for word, label in _lexicon().items():
        if word != label:
            by_label.setdefault(label, []).append(word)
    return {label: tuple(words) for label, words in by_label.items()}


def find_label(text: str, labels: Iterable[str]) -> tuple[str, int] | None:
    """The known label mentioned in ``text`` (longest match wins) and where it starts, or None.

    A word names the label that is its own first: "desk" is the desk when the scene lists desks and
    tables, and folds to the table only when it lists no desk.
    """
    words = normalise(text)
    padded = f" {words} "
    candidates: list[tuple[int, int, str]] = []
    for form, label in _label_forms(tuple(labels)).items():
        at = padded.find(f" {form} ")
        if at >= 0 and form:
            candidates.append((-len(form), at, label))
    if not candidates:
        return None
    _, at, label = min(candidates)
    return label, at


@lru_cache(maxsize=64)
def _label_forms(labels: tuple[str, ...]) -> dict[str, str]:
    """Each word (and its plural) that names one of ``labels``, to that label, by priority.

    A label's own name first, then the words the knowledge gives that very label, then the synonyms
    folded to it, then the words of what it folds to.
    """
    known = label_words()
    ranked: dict[str, tuple[int, str]] = {}

    def add(word: str, label: str, rank: int) -> None:
        for form in (word, word + "s", word + "es"):
            if form and (form not in ranked or rank < ranked[form][0]):
                ranked[form] = (rank, label)

    for label in labels:
        own, canonical = normalise(label).replace("_", " "), fold_label(label)
        add(own, label, 0)
        for word in known.get(own, ()):
            add(word, label, 1)
        add(canonical, label, 2)
        for synonym, target in SYNONYMS.items():
            if target in (own, canonical):
                add(synonym, label, 2 if target == own else 3)
        for word in known.get(canonical, ()):
            add(word, label, 3)
    return {form: label for form, (_, label) in ranked.items()}


def colour_words(text: str) -> list[str]:
    """Canonical colour names mentioned in ``text``, in order."""
    known = set(COLOUR_NAMES) | set(ALIASES)
    seen: list[str] = []
    for word in normalise(text).split():
        if word in known:
            name = canonical_colour(word)
            if name not in seen:
                seen.append(name)
    return seen


def size_words(text: str) -> list[str]:
    """Size words mentioned in ``text`` (small, large, tall, medium), in order."""
    return [SIZE_WORDS[w] for w in normalise(text).split() if w in SIZE_WORDS]


def split_relation(text: str) -> tuple[str, str | None, str]:
    """Split "the X <relation> the Y" into (X part, relation, Y part); (text, None, "") without one."""
    words = f" {normalise(text)} "
    best: tuple[int, str, str] | None = None
    for phrase, relation in RELATION_PHRASES:
        at = words.find(f" {phrase} ")
        if at > 0 and (best is None or at < best[0] or (at == best[0] and len(phrase) > len(best[1]))):
            best = (at, phrase, relation)
    if best is None:
        return words.strip(), None, ""
    at, phrase, relation = best
    return words[:at].strip(), relation, words[at + len(phrase) + 2:].strip()


def _without(words: str, label: str, labels: list[str]) -> str:
    """``words`` with the phrase that names ``label`` taken out (so "toilet" is not also read as a room)."""
    form = next((f for f, named in sorted(_label_forms(tuple(labels)).items(), key=lambda kv: -len(kv[0]))
                 if named == label and f" {f} " in f" {words} "), None)
    return f" {words} ".replace(f" {form} ", " ", 1).strip() if form else words


def parse_reference(text: str, labels: Iterable[str], places: Iterable[str] = ()) -> ReferenceParse | None:
    """Parse a referential phrase; None when it names none of ``labels``.

    Args:
        text: The phrase ("I want the grey backpack", "find the laptop in front of the sofa").
        labels: Object classes the caller knows.
        places: Other anchors a relation may name (room names such as ``kitchen``).
    """
    labels = list(labels)
    places = list(places)
    target_part, relation, anchor_part = split_relation(text)
    found = find_label(target_part, labels)
    if found is None:
        # "in the kitchen, the cup": try the whole phrase before giving up.
        found = find_label(text, labels)
        if found is None:
            return None
        relation, anchor_part, target_part = None, "", normalise(text)
    label, _ = found
    anchor: str | None = None
    if relation is not None:
        anchor_found = find_label(anchor_part, labels) or find_label(anchor_part, places)
        named = [w for w in anchor_part.split() if w not in _FILLER]
        if anchor_found is None and named and named[-1] not in GENERIC_PLACES:
            # "the umbrella in the bedroom" where there is no bedroom: the relation names something
            # unknown, so nothing can satisfy it (dropping it would answer "any umbrella").
            anchor = named[-1]
        elif anchor_found is None:
            relation = None
        else:
            anchor = anchor_found[0]
    if relation is None and places:
        # "go to the bathroom and find the sink": a room named beside the object, with no relation word
        room = find_label(_without(normalise(text), label, labels), places)
        if room is not None and fold_label(room[0]) != fold_label(label):
            relation, anchor = "in", room[0]
    attributes = colour_words(target_part) + size_words(target_part)
    return ReferenceParse(label=label, attributes=attributes, relation=relation, anchor=anchor)
