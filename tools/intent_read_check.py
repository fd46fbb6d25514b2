"""Read the dev split's commands with the offline reasoner alone (no simulator): a quick tuning check.

    python tools/intent_read_check.py                 # every dev word on generated:100..105
    python tools/intent_read_check.py --worlds 3 -v   # fewer flats, print each miss

The team's written dev commands, and every dev need paraphrase and object name
(``benchmarks/data/intent_dev_words.json``) and every dev referential command on each generated dev
flat, are put to the offline language model over the world's ground-truth graph (the benchmark's own
graph builder and judges). A reading is *right* when it names candidates and every one satisfies the
command (or names none when nothing does), *wrong* when one of them does not (a possible wrong object
served), *abstained* when it names none though something satisfies it. Dev only: this tool never
reads the test split's words.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from collections import Counter
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "benchmarks"))


def main(argv: list[str] | None = None) -> int:
    """Print right / wrong / abstained per group; the last line is JSON."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--worlds", type=int, default=6)
    parser.add_argument("--first-seed", type=int, default=100)
    parser.add_argument("-v", "--verbose", action="store_true")
    args = parser.parse_args(argv)

    import intent_eval as ie  # type: ignore[import-not-found]  # noqa: PLC0415 - the benchmark's judges

    from missiontree.reasoning.checks import chat_checked
    from missiontree.reasoning.intent import graph_objects, prompt_objects
    from missiontree.reasoning.prompts import intent_messages
    from missiontree.reasoning.schemas import IntentResolution

    folder = Path(tempfile.mkdtemp(prefix="intent_read_"))
    bench = ie.Bench(folder)
    names = ie.dev_world_names(args.worlds, args.first_seed, folder / "worlds")
    words = json.loads(ie.DEV_WORDS.read_text(encoding="utf-8"))
    tally: Counter[tuple[str, str]] = Counter()
    batches = [[c for c in [*ie.TABLE2, *ie.WRITTEN] if c.world == w] for w in ("office", "generated:3")]
    for name in names:
        world = bench.world(name)
        cases = ie._dealt_words(words, world, name, 0, 1, "dev")  # every word on every flat
        cases += ie.referential_cases(world, name, templates=ie.DEV_TEMPLATES, group="dev_referential")
        batches.append(cases)
    for cases in batches:
        for case in cases:
            scene = graph_objects(bench.graph(case).read_text(encoding="utf-8"))
            objects = prompt_objects(scene)
            answer = chat_checked(bench.models["llm"], intent_messages(case.command, objects),
                                  IntentResolution).value
            truth = {o.id for o in bench.truth(case)}
            picked = [str(c) for c in answer.candidates]
            if not picked:
                verdict = "abstained" if truth else "right"
            else:
                verdict = "right" if all(p in truth for p in picked) else "wrong"
            tally[(case.group, verdict)] += 1
            if args.verbose and verdict != "right":
                labels = sorted({scene.objects[p].label for p in picked if p in scene.objects})
                print(f"{verdict:9s} {case.group:15s} {case.command!r} -> {labels} :: {answer.reason[:150]}")
    groups = sorted({g for g, _ in tally})
    out = {g: {v: tally[(g, v)] for v in ("right", "wrong", "abstained")} for g in groups}
    for g, row in out.items():
        print(f"{g:16s} {row}")
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
