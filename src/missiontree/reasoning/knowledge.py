"""What objects are for and what words mean, read from the shipped knowledge file (no model, no network).

``missiontree/data/intent_knowledge.json`` is built offline by ``tools/build_intent_knowledge.py`` from
WordNet 3.0 and affordances written per *label* (each object class: the needs it serves and how well).
It holds:

- ``labels``: label → ``serves`` {need: strength in [0, 1]} (a bottle serves ``drink`` 1.0, a sink 0.4);
- ``need_words``: word → {need: weight}: the words of each need's WordNet senses and of the senses
  related to them (similar-to, derivations, hyponyms: "famished", "beverage", "e-mail");
- ``label_words``: word → the label it names (a label's own WordNet words and its hyponyms': couch,
  armchair); ``general_words``: word → the labels a more general word covers (seat, furniture), read
  only when the request says no need;
- ``forms``: irregular inflections of those words (WordNet's exception lists);
- ``compounds``: WordNet compound nouns that contain an object word without being that object (a
  "filter bed" is no bed), read whole as something unknown.

:meth:`Knowledge.read` turns a request into a :class:`Reading` (the needs it expresses and the labels it
names, each with the word that said it); :meth:`Knowledge.score` says how well a label serves it.
Words outside the file are left to the caller's embedding fallback.
"""

from __future__ import annotations

import json
import os
import re
from dataclasses import dataclass, field
from functools import lru_cache
from importlib import resources
from typing import Any

from missiontree.errors import ConfigError
from missiontree.file_limits import read_input_text

KNOWLEDGE_FILE = "data/intent_knowledge.json"
#: Largest knowledge file read (8 MiB; the shipped one is about 0.2 MiB), checked before it is read whole.
MAX_KNOWLEDGE_BYTES = 8 * 2**20
_WORD = re.compile(r"[a-z]+")
#: A label serving a request at least this well is a strong choice: it serves it outright, not as a
#: stand-in (a bookshelf 0.9 for reading, a refrigerator 0.7 for thirst; a sink 0.4 is a weak one).
STRONG = 0.7
#: A need word's own weight (a word of one of the need's senses, in one of its most frequent senses) ...
DIRECT = 1.0
#: ... and the weight of a far link (a similar-to of a similar-to, a deep hyponym), read only when no
#: word of the request names a need directly.
FAR = 0.7
#: Strength with which a more general word (a hypernym: seat, furniture, device) names the labels under it.
GENERAL_NAMED = 0.8
#: Share of each further need a label serves that adds to its score (see :meth:`Knowledge.score`).
COMBINED = 0.25
#: Words that carry no need or object of their own (pronouns, articles, auxiliaries, request verbs).
FUNCTION_WORDS = frozenset(
    "i im i'm me my mine myself you your we us our it its a an the this that these those some any to of "
    "for in on at by with from and or but so very really quite just too also now then there here please "
    "am is are was were be been being do does did have has had will would shall should can could may "
    "might must want wanted wants need needs needed like would love feel feeling felt get getting got "
    "go going take bring fetch find show lead guide where what which who somewhere something anything "
    "thing things bit little lot kind sort piece right let ll ve re d s t not no".split())
#: Suffix rules (WordNet's morphy, and the adverb's -ly) to find a word's dictionary form.
SUFFIXES = (("ies", "y"), ("es", "e"), ("es", ""), ("s", ""), ("ed", "e"), ("ed", ""), ("ing", "e"),
            ("ing", ""), ("ier", "y"), ("iest", "y"), ("er", ""), ("est", ""), ("men", "man"),
            # adverbs read as their adjectives ("sleepily" is said of the sleepy)
            ("ily", "y"), ("ly", ""))
#: Words after which a participle says a state one is in ("I'm rested", "I feel fed up"); the adverbs
#: of degree between them are skipped ("I'm so rested").
COPULAS = frozenset("am im is are was were be been being feel feels feeling felt get gets getting got"
                    .split())
DEGREE = frozenset("so very really quite totally completely fully well all just".split())
#: A need word read at this weight or more is the need's own activity or state ("rest", "feed",
#: "poop"); its participle said of oneself tells the need was met, not that one has it.
ACTIVITY = 0.85



def normalise(text: str) -> str:
    """Lower-case ``text`` and keep only its words.

    The one word rule of the reasoners (:mod:`~missiontree.reasoning.phrases` uses it too): lives
    here, below the phrases that read this module's lexicon, so the two do not import each other.
    """
    return " ".join(_WORD.findall(text.lower()))

@dataclass(frozen=True)
class Reading:
    """What a request says in the knowledge's terms.

    Attributes:
        needs: need → (strength, the word that expresses it).
        named: label → (strength, the word that names it): its own words, or a general word covering it.
        unknown: Content words the knowledge does not know (left to the embedding fallback).
        compounds: Compounds naming something else than the object word inside them ("filter bed").
        met: Participles saying a need was met ("rested"): no fallback reads a need into them.
    """

    needs: dict[str, tuple[float, str]] = field(default_factory=dict)
    named: dict[str, tuple[float, str]] = field(default_factory=dict)
    unknown: tuple[str, ...] = ()
    compounds: tuple[str, ...] = ()
    met: tuple[str, ...] = ()

    @property
    def empty(self) -> bool:
        """True when the request expresses no known need and names no known object."""
        return not self.needs and not self.named


class Knowledge:
    """The knowledge document with lookups (see the module docstring).

    Args:
        document: The parsed knowledge file.
    """

    def __init__(self, document: dict[str, Any]) -> None:
        self.needs: dict[str, str] = dict(document["needs"])
        self.serves: dict[str, dict[str, float]] = {
            label: {n: float(v) for n, v in entry["serves"].items()}
            for label, entry in document["labels"].items()}
        self.need_words: dict[str, dict[str, float]] = document["need_words"]
        self.label_words: dict[str, str] = document["label_words"]
        self.general_words: dict[str, list[str]] = document["general_words"]
        self.forms: dict[str, str] = document["forms"]
        self.compounds: frozenset[str] = frozenset(document.get("compounds", ()))
        every = (*self.need_words, *self.label_words, *self.general_words, *self.compounds)
        self._longest = max(len(w.split()) for w in every)

    @property
    def labels(self) -> list[str]:
        """Every label the knowledge describes."""
        return sorted(self.serves)

    def lemma(self, word: str) -> str | None:
        """The dictionary form of ``word`` the knowledge knows ("emails" → "email"), None if none."""
        for form in (word, self.forms.get(word, "")):
            if form and self._known(form):
                return form
        for suffix, ending in SUFFIXES:
            if word.endswith(suffix) and len(word) > len(suffix) + 1:
                base = word[: len(word) - len(suffix)] + ending
                if self._known(base):
                    return base
                doubled = suffix in ("ed", "ing") and len(base) > 2 and base[-1] == base[-2]
                if doubled and self._known(base[:-1]):
                    return base[:-1]  # "napping" -> "nap"
        return None

    def _known(self, word: str) -> bool:
        return word in self.need_words or word in self.label_words or word in self.general_words

    def read(self, text: str) -> Reading:
        """The needs ``text`` expresses and the labels it names (longest phrases first)."""
        words = normalise(text.replace("'", "")).split()
        needs: dict[str, tuple[float, str]] = {}
        named: dict[str, tuple[float, str]] = {}
        general: dict[str, tuple[float, str]] = {}   # labels a more general word covers (seat, device)
        unknown: list[str] = []
        compounds: list[str] = []
        met: list[str] = []
        i = 0
        while i < len(words):
            for n in range(min(self._longest, len(words) - i), 0, -1):
                phrase = " ".join(words[i:i + n])
                if n > 1 and phrase in self.compounds:  # "filter bed": something else than a bed
                    compounds.append(phrase)
                    unknown.append(phrase)
                    i += n - 1
                    break
                if n == 1 and phrase in FUNCTION_WORDS:
                    key = None
                else:
                    key = self.lemma(phrase) if n == 1 else (phrase if self._known(phrase) else None)
                if key is not None and n == 1 and self._met(words, i, key):
                    met.append(phrase)  # "I'm rested", "I'm fed up", "I feel pooped": the activity is done
                    continue
                if key is None:
                    if n == 1 and phrase not in FUNCTION_WORDS and len(phrase) > 2:
                        unknown.append(phrase)
                    continue
                for need, weight in self.need_words.get(key, {}).items():
                    if weight > needs.get(need, (0.0, ""))[0]:
                        needs[need] = (float(weight), phrase)
                if key in self.label_words:
                    label = self.label_words[key]
                    strength = 1.0 if key == label else 0.9
                    if strength > named.get(label, (0.0, ""))[0]:
                        named[label] = (strength, phrase)
                for label in self.general_words.get(key, []):
                    if GENERAL_NAMED > general.get(label, (0.0, ""))[0]:
                        general[label] = (GENERAL_NAMED, phrase)
                i += n - 1
                break
            i += 1
        if any(weight >= DIRECT for weight, _ in needs.values()):
            # a word that names a need outright outweighs another word's far echo of a different one
            # ("tired" is rest; its second-degree similar-to link to boredom is not read beside it)
            needs = {need: read for need, read in needs.items() if read[0] > FAR}
        if not needs:
            # a general word names what is under it only when the request says no need: "a seat" is
            # any seat, but in "in any case, I'm thirsty" the case is no suitcase to be brought to
            named = {**general, **named}
        return Reading(needs, named, tuple(unknown), tuple(compounds), tuple(met))

    def _met(self, words: list[str], i: int, key: str) -> bool:
        """Whether ``words[i]`` is a participle of a need's own verb said of oneself: the need was met.

        "I'm rested" is not tired and "I'm fed up" is not hungry: a word read only through its
        inflection (-ed, or an irregular past such as "fed") to a need's own activity or state
        (weight :data:`ACTIVITY` or more), right after a copula (:data:`COPULAS`, adverbs of degree
        skipped), says the need is behind. A weaker, causing verb still says it ("I'm tuckered out":
        tucker, to tire someone).
        """
        word = words[i]
        if key == word or not (word.endswith("ed") or self.forms.get(word) == key):
            return False
        if max(self.need_words.get(key, {}).values(), default=0.0) < ACTIVITY:
            return False
        j = i - 1
        while j >= 0 and words[j] in DEGREE:
            j -= 1
        return j >= 0 and words[j] in COPULAS

    def score(self, label: str, reading: Reading) -> tuple[float, str]:
        """How well ``label`` serves the reading, and why ("drink (thirsty)").

        The best thing the label does for the request counts whole; each other need of the request it
        also serves adds a quarter of its part (to wash *clothes* a washing machine serves both the
        washing and the clothes, a sink only the washing). 1.0 is a label that serves it outright.
        """
        parts: list[tuple[float, str]] = []
        if label in reading.named:
            strength, word = reading.named[label]
            parts.append((strength, f"named ({word})"))
        for need, (strength, word) in reading.needs.items():
            value = strength * self.serves.get(label, {}).get(need, 0.0)
            if value > 0:
                parts.append((value, f"{need} ({word})"))
        if not parts:
            return 0.0, ""
        parts.sort(key=lambda part: -part[0])
        total = parts[0][0] + COMBINED * sum(value for value, _ in parts[1:])
        return round(total, 3), parts[0][1]

    def servers(self, need: str) -> list[str]:
        """Labels that serve ``need`` fully or nearly (strength ≥ 0.9), for reasons."""
        return sorted(label for label, serves in self.serves.items() if serves.get(need, 0.0) >= 0.9)


def read_knowledge(path: str | os.PathLike[str]) -> Knowledge:
    """The knowledge file at ``path``, read bounded (:data:`MAX_KNOWLEDGE_BYTES`).

    Raises:
        ConfigError: The file is too large, not UTF-8, unreadable or not a knowledge document.
    """
    text = read_input_text(path, MAX_KNOWLEDGE_BYTES, "intent knowledge file",
                           "the intent knowledge file is JSON", ConfigError)
    try:
        return Knowledge(json.loads(text))
    except (ValueError, KeyError, TypeError, AttributeError) as exc:
        raise ConfigError(f"{path}: not an intent knowledge document ({type(exc).__name__})") from None


@lru_cache(maxsize=1)
def knowledge() -> Knowledge:
    """The shipped knowledge (read once per process)."""
    with resources.as_file(resources.files("missiontree").joinpath(KNOWLEDGE_FILE)) as path:
        return read_knowledge(path)
