"""Reading a need the knowledge's words do not cover, by MiniLM embeddings (no network).

Shared by the offline language-model stand-in
(:mod:`missiontree.reasoning.providers.offline_llm`), which names candidates by it, and the intent
leaf, which asks how surely a chosen object serves the command
whatever model chose it. The knowledge (:mod:`missiontree.reasoning.knowledge`) reads words it lists;
a request none of whose words it lists ("I'd enjoy a photoplay tonight") is compared, by cosine
similarity of all-MiniLM-L6-v2 vectors, with each need's description and, word by word, with each
need's own words. Only a clear match counts, and its strength says how clear it was.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from functools import lru_cache

import numpy as np

from missiontree.reasoning.embedder import similarity
from missiontree.reasoning.knowledge import STRONG, Knowledge, Reading
from missiontree.reasoning.protocols import Embedder

#: A request the knowledge's words do not cover is matched to a need by embedding only at this cosine
#: similarity or more (an unknown word to a need's own word, or the request to the need's description:
#: all-MiniLM-L6-v2 puts unrelated words at 0.2-0.45 and synonyms at 0.6-0.9) ...
NEED_MATCH = 0.6
#: A word's match needs the whole request at least this similar to the same need's description.
AGREE = 0.3
#: ... and this far ahead of the next need (a word as near to two needs says neither).
EMBEDDED_MARGIN = 0.1
#: A match at NEED_MATCH reads at the strong threshold and one at this similarity or more at full
#: strength, so a label serving the need fully is a candidate, a partial server (0.7) is not.
NEED_SURE = 0.9
#: Text of the ``why`` of a reading made by embedding (the leaf tells such readings apart by it).
BY_EMBEDDING = "similarity"


@lru_cache(maxsize=4)
def need_heads(kb: Knowledge) -> dict[str, tuple[str, ...]]:
    """Each need's own words (weight 1.0 for that need alone): what an unknown word is compared with.

    A word that also names an object class not serving the need strongly is left out: near it an
    unknown word may be near the object ("pooped" is near "stool", a seat as much as a toilet's word).
    """
    heads: dict[str, list[str]] = {}
    for word, needs in kb.need_words.items():
        if len(needs) == 1 and max(needs.values()) >= 1.0:
            need = next(iter(needs))
            label = kb.label_words.get(word)
            if label is not None and kb.serves.get(label, {}).get(need, 0.0) < STRONG:
                continue
            heads.setdefault(need, []).append(word)
    return {need: tuple(words) for need, words in heads.items()}


def embedded_need(embedder: Embedder, request: str, unknown: Sequence[str], descriptions: Mapping[str, str],
                  heads: Mapping[str, Sequence[str]], margin: float = EMBEDDED_MARGIN
                  ) -> tuple[str, float, str] | None:
    """The need an unlisted request means by embedding, its strength and why; None when unclear.

    Each need's evidence is the best cosine similarity of the request to its description, or of an
    unknown word of it to one of the need's own words ("famished" to "famish") when the request is also
    at least :data:`AGREE` similar to the description. The best need counts
    only at :data:`NEED_MATCH` or more and ``margin`` (at least :data:`EMBEDDED_MARGIN`) ahead of the
    next. Its strength grows from the strong threshold at NEED_MATCH to 1.0 at :data:`NEED_SURE`, so
    only a label that serves the need fully (1.0) or nearly passes the reasoner's threshold.
    """
    needs = sorted(set(descriptions) | set(heads))
    evidence = {n: (-1.0, "") for n in needs}
    sentence = similarity(embedder, request, [descriptions.get(n, n) for n in needs])
    for n, value in zip(needs, sentence, strict=True):
        evidence[n] = (float(value), "the request")
    words = [w for w in dict.fromkeys(unknown) if len(w) > 3]
    vocabulary = [(n, w) for n in needs for w in heads.get(n, ())]
    if words and vocabulary:
        vectors = embedder.embed([*words, *(w for _, w in vocabulary)])
        table = vectors[len(words):] @ vectors[:len(words)].T   # vocabulary x unknown words
        for (n, head), row in zip(vocabulary, table, strict=True):
            j = int(np.argmax(row))
            # a word near a need's word counts only when the whole request leans that way too ("potation"
            # is near "pot" by its letters, the request is not about the toilet)
            if float(row[j]) > evidence[n][0] and float(sentence[needs.index(n)]) >= AGREE:
                evidence[n] = (float(row[j]), f"{words[j]} ~ {head}")
    order = sorted(needs, key=lambda n: -evidence[n][0])
    best, how = evidence[order[0]]
    second = evidence[order[1]][0] if len(order) > 1 else -1.0
    if best < NEED_MATCH or best - second < max(margin, EMBEDDED_MARGIN):
        return None
    strength = STRONG + (1.0 - STRONG) * min(1.0, (best - NEED_MATCH) / (NEED_SURE - NEED_MATCH))
    return order[0], round(strength, 3), f"{BY_EMBEDDING} {best:.2f}: {how}"


def embedded_reading(embedder: Embedder, request: str, known: Reading, kb: Knowledge,
                     margin: float = EMBEDDED_MARGIN) -> Reading:
    """``known`` when it reads a need or names an object; else the need :func:`embedded_need` finds.

    The embedded need is read at its strength, with ``why`` starting with :data:`BY_EMBEDDING`.
    """
    if not known.empty or known.met:
        return known  # a request saying a need was met ("I'm rested") is not read as having it
    found = embedded_need(embedder, request, known.unknown, kb.needs, need_heads(kb), margin)
    if found is None:
        return known
    need, strength, why = found
    return Reading(needs={need: (strength, why)}, unknown=known.unknown)


def by_embedding(reading: Reading) -> bool:
    """Whether ``reading`` was made by embedding similarity, not by the knowledge's own words."""
    return bool(reading.needs) and all(why.startswith(BY_EMBEDDING) for _, why in reading.needs.values())
