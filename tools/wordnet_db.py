"""A small reader of the WordNet 3.0 database files (Debian's ``wordnet-base``, /usr/share/wordnet).

Only what the offline tools need: synsets of a word in sense order (most frequent first), their
lemmas, gloss and pointers (hypernyms, hyponyms, similar-to, derivations, ...), and WordNet's own
morphology (exception lists, then its detachment rules). No third-party package: the database format
is plain text (wndb(5WN)). Used at build time only; the runtime reads what the tools wrote.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

DEFAULT_ROOT = Path("/usr/share/wordnet")
POS_FILES = {"n": "noun", "v": "verb", "a": "adj", "s": "adj", "r": "adv"}
#: WordNet's detachment rules (morphy), per part of speech.
RULES = {
    "n": [("s", ""), ("ses", "s"), ("xes", "x"), ("zes", "z"), ("ches", "ch"), ("shes", "sh"),
          ("men", "man"), ("ies", "y")],
    "v": [("s", ""), ("ies", "y"), ("es", "e"), ("es", ""), ("ed", "e"), ("ed", ""), ("ing", "e"),
          ("ing", "")],
    "a": [("er", ""), ("est", ""), ("er", "e"), ("est", "e")],
    "r": [],
}


@dataclass(frozen=True)
class Synset:
    """One synset: ``key`` is "<pos>:<offset>", ``lemmas`` its words (spaces, lower case)."""

    key: str
    pos: str
    lemmas: tuple[str, ...]
    pointers: tuple[tuple[str, str], ...]   # (pointer symbol, target key)
    gloss: str

    @property
    def name(self) -> str:
        """A readable name: first lemma, part of speech and offset."""
        return f"{self.lemmas[0]}.{self.pos}.{self.key.split(':')[1]}"


class WordNet:
    """The WordNet database under ``root`` (raises FileNotFoundError naming the package when absent)."""

    def __init__(self, root: Path = DEFAULT_ROOT) -> None:
        if not (root / "data.noun").is_file():
            raise FileNotFoundError(f"no WordNet database at {root}: apt-get install wordnet-base")
        self.root = root
        self._data: dict[str, bytes] = {}
        self._index: dict[str, dict[str, list[str]]] = {}
        self._exc: dict[str, dict[str, list[str]]] = {}
        for pos, name in (("n", "noun"), ("v", "verb"), ("a", "adj"), ("r", "adv")):
            self._data[pos] = (root / f"data.{name}").read_bytes()
            index: dict[str, list[str]] = {}
            for line in (root / f"index.{name}").read_text(encoding="latin-1").splitlines():
                if line.startswith(" "):
                    continue
                parts = line.split()
                lemma, p_cnt = parts[0], int(parts[3])
                offsets = parts[4 + p_cnt + 2:]
                index[lemma] = [f"{pos}:{o}" for o in offsets]
            self._index[pos] = index
            exc: dict[str, list[str]] = {}
            path = root / f"{name}.exc"
            if path.is_file():
                for line in path.read_text(encoding="latin-1").splitlines():
                    parts = line.split()
                    if len(parts) >= 2:
                        exc[parts[0]] = parts[1:]
            self._exc[pos] = exc

    def base_forms(self, word: str, pos: str) -> list[str]:
        """WordNet's morphy: the dictionary forms of ``word`` as part of speech ``pos`` (n, v, a, r)."""
        word = word.lower().replace(" ", "_")
        pos = "a" if pos == "s" else pos
        index = self._index[pos]
        found = [word] if word in index else []
        found += [b for b in self._exc[pos].get(word, []) if b in index and b not in found]
        for suffix, ending in RULES[pos]:
            if word.endswith(suffix) and len(word) > len(suffix):
                base = word[: len(word) - len(suffix)] + ending
                if base in index and base not in found:
                    found.append(base)
        return found

    def synsets(self, word: str, pos: str | None = None) -> list[Synset]:
        """Synsets of ``word`` (any inflected form), most frequent sense first, per part of speech."""
        out: list[Synset] = []
        for p in ([pos] if pos else ["n", "v", "a", "r"]):
            p = "a" if p == "s" else p
            for base in self.base_forms(word, p):
                for key in self._index[p].get(base, []):
                    synset = self.synset(key)
                    if synset not in out:
                        out.append(synset)
        return out

    @lru_cache(maxsize=200_000)  # noqa: B019 - one database object lives as long as the tool
    def synset(self, key: str) -> Synset:
        """The synset at ``key`` ("n:02876657")."""
        pos, offset = key.split(":")
        data = self._data[pos]
        start = int(offset)
        end = data.index(b"\n", start)
        line = data[start:end].decode("latin-1")
        head, _, gloss = line.partition(" | ")
        parts = head.split()
        ss_type = parts[2]
        count = int(parts[3], 16)
        lemmas = []
        for i in range(count):
            word = parts[4 + 2 * i]
            if "(" in word:
                word = word[: word.index("(")]
            lemmas.append(word.lower().replace("_", " "))
        at = 4 + 2 * count
        p_cnt = int(parts[at])
        pointers = []
        for i in range(p_cnt):
            symbol, target, target_pos = parts[at + 1 + 4 * i], parts[at + 2 + 4 * i], parts[at + 3 + 4 * i]
            pointers.append((symbol, f"{'a' if target_pos == 's' else target_pos}:{target}"))
        return Synset(key, ss_type, tuple(lemmas), tuple(pointers), gloss.strip())

    def related(self, synset: Synset, *symbols: str) -> list[Synset]:
        """Synsets ``synset`` points to with any of ``symbols`` (``@`` hypernym, ``~`` hyponym, ...)."""
        return [self.synset(k) for s, k in synset.pointers if s in symbols]

    def hyponyms(self, synset: Synset, depth: int) -> list[tuple[Synset, int]]:
        """Hyponyms (and instance hyponyms) down to ``depth`` levels, with their level."""
        out: list[tuple[Synset, int]] = []
        frontier = [synset]
        seen = {synset.key}
        for level in range(1, depth + 1):
            nxt = []
            for s in frontier:
                for h in self.related(s, "~", "~i"):
                    if h.key not in seen:
                        seen.add(h.key)
                        out.append((h, level))
                        nxt.append(h)
            frontier = nxt
        return out

    def hypernym_closure(self, synset: Synset) -> list[Synset]:
        """Every hypernym of ``synset`` up to the root, nearest first."""
        out: list[Synset] = []
        frontier = [synset]
        seen = {synset.key}
        while frontier:
            nxt = []
            for s in frontier:
                for h in self.related(s, "@", "@i"):
                    if h.key not in seen:
                        seen.add(h.key)
                        out.append(h)
                        nxt.append(h)
            frontier = nxt
        return out
