"""Build the intent benchmark's generated dev words from a thesaurus that is not WordNet (Aiksaurus).

    apt-get install aiksaurus
    python -m tools.build_intent_dev_commands      # writes benchmarks/data/intent_dev_words.json

The dev split is tuned on, so it should be varied without sharing a source with the test split,
whose commands come from WordNet (and whose reasoner reads WordNet too). This file is built
mechanically, once, from a source of another kind: Aiksaurus (Debian's ``aiksaurus``, GPL-2+, Jared
Davis' English thesaurus): loose groups of associated words under a heading, written independently of
WordNet, where WordNet is a sense-by-sense lexical database (the LibreOffice thesaurus used before is
derived from WordNet, so it was not independent). Any word that occurs in a test-split command is
left out. Sources:

- **Need paraphrases**: for each dev need word, the Aiksaurus groups (by heading) that carry that
  need; every word of the group except the ones listed as not carrying it (a group mixes senses and
  parts of speech: "monsoon" sits in the group of "sup"), in templates neither the team's dev
  commands nor the test split use; judged by the objects the dev split judges to satisfy the need.
- **Object names**: the words of a label's Aiksaurus group that name that object (judged: that label).

The benchmark adds, per generated dev world, referential commands by colour, room and relation in
templates of its own.
"""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "benchmarks" / "data" / "intent_dev_words.json"
TEST_WORDS = ROOT / "benchmarks" / "data" / "intent_test_words.json"

DRINK = ["bottle", "cup", "refrigerator", "sink"]
REST = ["sofa", "chair", "bed", "stool", "bench"]
FUN = ["tv", "laptop", "book", "bookshelf"]
FOOD = ["refrigerator", "microwave", "oven", "dining table"]
SLEEP = ["bed", "sofa"]

#: (look-up word, group heading, template kind, judged satisfied by, words of the group not carrying
#: the need). The heading names the group Aiksaurus prints for the look-up word.
NEEDS: list[tuple[str, str, str, list[str], frozenset[str]]] = [
    ("tired", "worn out", "state", REST,
     frozenset({"done", "used up", "spent", "beaten", "beat up", "tired"})),
    ("hungry", "empty", "state", FOOD, frozenset({"empty", "hollow", "unfilled", "fasting", "hungry"})),
    ("drink", "sup", "act", DRINK, frozenset({
        "dollop", "dram", "drench", "drink", "drink to", "infiltrate", "jigger", "jolt", "libation",
        "monsoon",
        "pledge", "potation", "potion", "rainy day", "snifter", "stormy weather", "suck", "suck in", "suckle",
        "tablet", "toast", "tot", "wet", "gargle"})),
    ("beverage", "spirits", "thing", DRINK, frozenset({"punch bowl", "inebriant", "spirits"})),
    ("food", "sustenance", "thing", FOOD, frozenset({
        "keep", "livelihood", "pap", "support", "nurture", "food", "alimentation", "bread"})),
    ("nap", "slumber", "thing", SLEEP, frozenset({
        "bedtime", "dorm", "dreamland", "hibernation", "oversleep", "sleep", "sleepwalking", "slumberland",
        "snore", "somnambulism", "doss"})),
    ("relax", "beguile", "act_me", FUN, frozenset({
        "betray", "convulse", "kill", "loosen up", "refresh", "relax", "slay", "solace", "titillate", "wow",
        "exhilarate"})),
    ("boredom", "stupor", "thing", FUN, frozenset({
        "drowsiness", "lethargy", "phlegm", "sleepiness", "sloth", "slowness", "somnolence", "stupor",
        "boredom", "hebetude"})),
    ("movie", "trailer", "show", ["tv", "laptop"], frozenset({
        "nudie", "skin flick", "preview", "sneak preview", "short", "trailer", "technicolor", "picture",
        "flicker", "movie"})),
    ("rain", "spate", "weather", ["umbrella"], frozenset({
        "brash", "cascade", "cataract", "flood", "inundation", "plash", "pour", "scud", "soaker", "spate",
        "waterspout", "rain", "downfall"})),
]
#: Templates by kind; none is the shape of a team-written or a test-split command.
TEMPLATES = {
    "state": ["Honestly I'm {w} right now.", "I feel {w} after today."],
    "act": ["Somewhere I can {w} something?", "I'd like to {w} a little."],
    "act_me": ["Anything around to {w} me?", "Something that could {w} me."],
    "thing": ["Some {w} would be nice.", "I'm in need of {w}."],
    "show": ["I'd enjoy a {w} tonight.", "Time for a {w}, I think."],
    "weather": ["There's {w} on the way.", "Expecting {w} when I head out."],
}
#: (look-up word, heading, label, the group's words that name the label).
OBJECTS: list[tuple[str, str, str, frozenset[str]]] = [
    ("toilet", "can", "toilet", frozenset({
        "can", "comfort station", "john", "johnny", "latrine", "lavatory", "loo", "outhouse", "potty",
        "privy", "rest room", "urinal", "washroom", "water closet", "wc"})),
    ("sink", "washer", "sink", frozenset({"basin", "washbasin", "washstand"})),
]
OBJECT_TEMPLATE = "Could we stop by the {w}?"


def groups(word: str) -> dict[str, list[str]]:
    """Heading → the words of each Aiksaurus group printed for ``word`` (lower case)."""
    out = subprocess.run(["aiksaurus", word], capture_output=True, text=True, check=True).stdout
    found: dict[str, list[str]] = {}
    heading = ""
    for line in out.splitlines():
        if line.startswith("==="):
            heading = line.strip("= ").strip()
        elif heading and line.strip():
            found[heading] = [w.strip().lower() for w in line.split(",") if w.strip()]
            heading = ""
    return found


def test_words() -> set[str]:
    """Every word of a test-split command (left out of the dev words)."""
    document = json.loads(TEST_WORDS.read_text(encoding="utf-8"))
    return {w for group in ("needs", "objects", "absent") for entry in document[group]
            for w in re.findall(r"[a-z]+", str(entry["command"]).lower())}


def fits(word: str, banned: set[str]) -> bool:
    """A plain single- or multi-word term none of whose words a test command uses."""
    parts = re.findall(r"[a-z]+", word)
    return re.fullmatch(r"[a-z' -]+", word) is not None and bool(parts) and not set(parts) & banned


def need_paraphrases(banned: set[str]) -> list[dict[str, object]]:
    """Commands from the Aiksaurus groups of the dev need words."""
    out: list[dict[str, object]] = []
    seen: set[str] = set()
    for word, heading, kind, satisfied, not_taken in NEEDS:
        terms = groups(word).get(heading)
        if terms is None:
            raise SystemExit(f"aiksaurus prints no group {heading!r} for {word!r}")
        kept = [t for t in terms if t not in not_taken and t not in seen and fits(t, banned)]
        for i, term in enumerate(kept):
            seen.add(term)
            templates = TEMPLATES[kind]
            out.append({"command": templates[i % len(templates)].format(w=term),
                        "satisfied_by": satisfied, "source": f"aiksaurus {word} [{heading}]", "term": term})
    return out


def object_names(banned: set[str]) -> list[dict[str, object]]:
    """Commands naming a label by a word of its Aiksaurus group."""
    out: list[dict[str, object]] = []
    for word, heading, label, names in OBJECTS:
        for term in groups(word).get(heading, []):
            if term in names and fits(term, banned):
                out.append({"command": OBJECT_TEMPLATE.format(w=term), "satisfied_by": [label],
                            "source": f"aiksaurus {word} [{heading}]", "term": term})
    return out


def main() -> int:
    """Write the dev words file."""
    banned = test_words()
    document = {
        "about": "Built by tools/build_intent_dev_commands.py from Aiksaurus (Debian's aiksaurus), a "
                 "thesaurus not derived from WordNet; no word of a test-split command; do not edit by hand.",
        "needs": need_paraphrases(banned),
        "objects": object_names(banned),
    }
    OUT.write_text(json.dumps(document, indent=1) + "\n", encoding="utf-8")
    print(f"wrote {OUT}: " + ", ".join(f"{k} {len(v)}" for k, v in document.items() if isinstance(v, list)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
