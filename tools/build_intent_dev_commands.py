"""Build the intent benchmark's generated dev words: thesaurus paraphrases the test split does not use.

    apt-get install mythes-en-us
    python -m tools.build_intent_dev_commands      # writes benchmarks/data/intent_dev_words.json

The dev split is tuned on, so it should be as hard and as varied as the test split without sharing
its words. This file is built mechanically, once, from another source than the test split's: the
English thesaurus of LibreOffice (Debian's ``mythes-en-us``, ``th_en_US_v2``), in templates neither
the team's dev commands nor the test split use. Any word that occurs in a test-split command is left
out, so tuning on these words says nothing about the test words. Sources:

- **Need paraphrases**: the thesaurus meanings of the dev commands' need words (thirsty, tired,
  bored, hungry, sleep, read, movie, rain, print), each meaning of the part of speech the dev
  command uses, its synonyms and similar terms (never its antonyms or generic terms), judged by the
  objects the dev split judges to satisfy the need word.
- **Object names**: the synonyms of each benchmark label's thesaurus meanings that name an object
  (judged: that label).

The benchmark adds, per generated dev world, referential commands by colour, room and relation in
templates of its own.
"""

from __future__ import annotations

import json
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "benchmarks" / "data" / "intent_dev_words.json"
TEST_WORDS = ROOT / "benchmarks" / "data" / "intent_test_words.json"
THESAURUS = Path("/usr/share/mythes/th_en_US_v2.dat")

DRINK = ["bottle", "cup", "refrigerator", "sink"]
REST = ["sofa", "chair", "bed", "stool", "bench"]
FUN = ["tv", "laptop", "book", "bookshelf"]
FOOD = ["refrigerator", "microwave", "oven", "dining table"]

#: Dev need words, the part of speech and thesaurus meanings (1-based, in the file's order) meant,
#: and what satisfies them.
NEEDS: list[tuple[str, str, tuple[int, ...], list[str]]] = [
    ("thirsty", "adj", (1,), DRINK),
    ("drink", "verb", (1,), DRINK),
    ("tired", "adj", (1,), REST),
    ("sit", "verb", (1,), REST),
    ("bored", "adj", (1, 2), FUN),
    ("boredom", "noun", (1,), FUN),
    ("hungry", "adj", (1,), FOOD),
    ("hunger", "noun", (1,), FOOD),
    ("sleep", "verb", (1,), ["bed", "sofa"]),
    ("sleepy", "adj", (1,), ["bed", "sofa"]),
    ("movie", "noun", (1,), ["tv", "laptop"]),
    ("rain", "noun", (1,), ["umbrella"]),
]
#: Templates by part of speech; none is the shape of a team-written or a test-split command.
TEMPLATES = {
    "adj": ["I'm getting {w}.", "Feeling pretty {w} at the moment."],
    "verb": ["I'd love to {w} for a while.", "Somewhere to {w}, please."],
    "noun": ["So much {w} today.", "I could do with some {w}."],
}
#: Labels whose thesaurus synonyms name them (a noun meaning each).
OBJECTS: dict[str, tuple[str, tuple[int, ...]]] = {
    "sofa": ("sofa", (1,)), "chair": ("chair", (1,)), "bottle": ("bottle", (1,)), "cup": ("cup", (1,)),
    "refrigerator": ("refrigerator", (1,)), "tv": ("television", (2,)), "laptop": ("laptop", (1,)),
    "backpack": ("backpack", (1,)), "umbrella": ("umbrella", (2,)), "bed": ("bed", (1,)),
    "bookshelf": ("bookshelf", (1,)), "trash can": ("ashcan", (1,)), "toilet": ("toilet", (1,)),
    "sink": ("sink", (1,)), "wardrobe": ("wardrobe", (1,)), "desk": ("desk", (1,)),
}
OBJECT_TEMPLATE = "Lead me over to the {w}."
#: Words never taken: another dev need's own word (bored is no way of being tired) and room names.
NOT_TAKEN = frozenset({w for w, _, _, _ in NEEDS} | {"kitchen", "bathroom", "bedroom", "office", "hall"})


def meanings(word: str) -> list[tuple[str, list[str]]]:
    """(part of speech, [synonyms and similar terms]) of each meaning of ``word`` in the thesaurus."""
    lines = THESAURUS.read_text(encoding="utf-8", errors="replace").splitlines()
    for i, line in enumerate(lines):
        head, _, count = line.partition("|")
        if head == word and count.isdigit():
            out = []
            for entry in lines[i + 1:i + 1 + int(count)]:
                pos, *terms = entry.split("|")
                kept = [t.replace(" (similar term)", "") for t in terms
                        if "(antonym)" not in t and "(generic term)" not in t and "(related term)" not in t]
                out.append((pos.strip("()"), [t.lower() for t in kept]))
            return out
    return []


def test_words() -> set[str]:
    """Every word of a test-split command (left out of the dev words)."""
    document = json.loads(TEST_WORDS.read_text(encoding="utf-8"))
    return {w for group in ("needs", "objects", "absent") for entry in document[group]
            for w in re.findall(r"[a-z]+", str(entry["command"]).lower())}


def fits(word: str, banned: set[str]) -> bool:
    """A single- or multi-word term none of whose words a test command uses."""
    parts = re.findall(r"[a-z]+", word)
    plain = re.fullmatch(r"[a-z' -]+", word) is not None
    return plain and bool(parts) and word not in NOT_TAKEN and not (set(parts) & banned)


def need_paraphrases(banned: set[str]) -> list[dict[str, object]]:
    """Commands from the thesaurus meanings of the dev need words."""
    out: list[dict[str, object]] = []
    seen: set[str] = set()
    for word, pos, which, satisfied in NEEDS:
        found = [m for m in meanings(word) if m[0] == pos]
        for k in which:
            if k > len(found):
                continue
            for i, term in enumerate(t for t in found[k - 1][1] if t != word and fits(t, banned)):
                if term in seen:
                    continue
                seen.add(term)
                templates = TEMPLATES[pos]
                out.append({"command": templates[i % len(templates)].format(w=term),
                            "satisfied_by": satisfied, "source": f"{word} ({pos} {k}) {term}"})
    return out


def object_names(banned: set[str]) -> list[dict[str, object]]:
    """Commands naming a label by a thesaurus synonym."""
    out: list[dict[str, object]] = []
    seen: set[str] = set(OBJECTS)
    for label, (word, which) in OBJECTS.items():
        found = [m for m in meanings(word) if m[0] == "noun"]
        for k in which:
            if k > len(found):
                continue
            for term in found[k - 1][1]:
                if term not in seen and fits(term, banned):
                    seen.add(term)
                    out.append({"command": OBJECT_TEMPLATE.format(w=term), "satisfied_by": [label],
                                "source": f"{word} (noun {k}) {term}"})
    return out


def main() -> int:
    """Write the dev words file."""
    banned = test_words()
    document = {
        "about": "Built by tools/build_intent_dev_commands.py from the LibreOffice English thesaurus "
                 "(mythes-en-us); no word of a test-split command; do not edit by hand.",
        "needs": need_paraphrases(banned),
        "objects": object_names(banned),
    }
    OUT.write_text(json.dumps(document, indent=1) + "\n", encoding="utf-8")
    print(f"wrote {OUT}: " + ", ".join(f"{k} {len(v)}" for k, v in document.items() if isinstance(v, list)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
