"""How big the viewer's page of a 1-hour run is, and how fast Chromium opens it.

Synthesizes a 36,000-tick patrol-like run (10 Hz for an hour, a real patrol's event rate: about
0.6 events a tick), builds the page with ``missiontree view``'s code, and opens it in headless
Chromium (Debian's, through Playwright) until the viewer reports ready with the last tick shown.
The reference, opened alternately in the same browser: a page holding the raw ``ticks.jsonl``
inline that only parses it line by line (``JSON.parse`` per line, no drawing) — the least a
viewer reading the raw log must do. Targets: the page <= 10 MB and open <= 3 s.

    .venv/bin/python benchmarks/viewer_size.py [--ticks 36000] [--rounds 5]

Last line: one JSON object with ``html_mb_36k`` and ``open_s_36k`` (median), their spread and
the ratios to the reference.
"""

from __future__ import annotations

import argparse
import json
import statistics
import tempfile
import time
from pathlib import Path
from typing import Any

from missiontree.runlog.html import write_page
from missiontree.testing_runs import synthesize_run

CHROMIUM = "/usr/bin/chromium"
FLAGS = [
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
]


def reference_page(log: Path, out: Path) -> Path:
    """A page that holds the raw log and parses every line (the reference)."""
    raw = json.dumps(log.read_text(encoding="utf-8")).replace("</", "<\\/")
    out.write_text(
        "<!DOCTYPE html><html><body><script>const RAW=" + raw + ";"
        "const rows=RAW.split('\\n').filter(l=>l).map(l=>JSON.parse(l));"
        "document.body.dataset.ready='1';document.body.dataset.rows=String(rows.length);</script></body></html>",
        encoding="utf-8",
    )
    return out


def spread(values: list[float]) -> dict[str, float]:
    return {"min": min(values), "median": statistics.median(values), "max": max(values)}


def open_seconds(browser: Any, path: Path) -> float:
    """Wall seconds from navigation to the page's ready flag, in a fresh browser context."""
    context = browser.new_context(viewport={"width": 1400, "height": 900})
    page = context.new_page()
    start = time.perf_counter()
    page.goto(path.as_uri())
    page.wait_for_selector("body[data-ready='1']", state="attached", timeout=60_000)
    elapsed = time.perf_counter() - start
    context.close()
    return elapsed


def scrub_ms(browser: Any, path: Path, moves: int = 40) -> list[float]:
    """Milliseconds per timeline move to a random tick until the frame is painted (tree, events, map)."""
    context = browser.new_context(viewport={"width": 1400, "height": 900})
    page = context.new_page()
    page.goto(path.as_uri())
    page.wait_for_selector("body[data-ready='1']", state="attached", timeout=60_000)
    # each move waits for the next painted frame: what a user dragging the slider sees
    times = page.evaluate(
        """async (moves) => { const out = []; let seed = 7; const n = MT.count();
        const frame = () => new Promise((r) => requestAnimationFrame(() => setTimeout(r, 0)));
        await frame();
        for (let k = 0; k < moves; k++) { seed = (seed * 16807) % 2147483647;
          const t0 = performance.now(); MT.setTick(seed % n); await frame();
          out.push(performance.now() - t0); }
        return out; }""",
        moves,
    )
    context.close()
    return [float(t) for t in times]


def measure(browser: Any, run: Path, rounds: int) -> dict[str, Any]:
    """Size, build time, open time against the reference (alternating) and scrub time of one run."""
    log = run / "ticks.jsonl"
    start = time.perf_counter()
    page = write_page(run, run / "report.html")
    build_s = time.perf_counter() - start
    reference = reference_page(log, run / "reference.html")
    open_seconds(browser, reference)  # warm the browser's caches once, off the record
    viewer_s: list[float] = []
    reference_s: list[float] = []
    for _ in range(rounds):  # alternate: the same browser state for both
        viewer_s.append(open_seconds(browser, page))
        reference_s.append(open_seconds(browser, reference))
    ratios = [v / r for v, r in zip(viewer_s, reference_s, strict=True)]
    return {
        "html_mb": page.stat().st_size / 1e6,
        "jsonl_mb": log.stat().st_size / 1e6,
        "build_s": build_s,
        "open": spread(viewer_s),
        "reference": spread(reference_s),
        "ratio": spread(ratios),
        "scrub_ms": spread(scrub_ms(browser, page)),
    }


def report(name: str, ticks: int, m: dict[str, Any]) -> None:
    v, r, q, s = m["open"], m["reference"], m["ratio"], m["scrub_ms"]
    print(
        f"== {name}: {ticks} ticks, ticks.jsonl {m['jsonl_mb']:.2f} MB, page {m['html_mb']:.2f} MB "
        f"({m['html_mb'] / m['jsonl_mb']:.2f} of the log), built in {m['build_s']:.2f} s"
    )
    print(
        f"open viewer    s  min {v['min']:.3f}  median {v['median']:.3f}  max {v['max']:.3f}  (target <= 3)"
    )
    print(
        f"open reference s  min {r['min']:.3f}  median {r['median']:.3f}  max {r['max']:.3f}"
        "  (raw log, parse only)"
    )
    print(f"viewer / reference  min {q['min']:.2f}  median {q['median']:.2f}  max {q['max']:.2f}")
    print(f"timeline move  ms  min {s['min']:.1f}  median {s['median']:.1f}  max {s['max']:.1f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--ticks", type=int, default=36_000)
    parser.add_argument("--rounds", type=int, default=5)
    args = parser.parse_args()
    from playwright.sync_api import sync_playwright

    shapes = {
        "patrol-sized tree (8 nodes)": {"leaves": 4, "groups": 1},
        "1,023 nodes, 20 leaves running at once": {"leaves": 50, "groups": 20},
    }
    results: dict[str, dict[str, Any]] = {}
    with tempfile.TemporaryDirectory() as tmp, sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=CHROMIUM, headless=True, args=FLAGS)
        for index, (name, shape) in enumerate(shapes.items()):
            run = Path(tmp) / f"run{index}"
            synthesize_run(run, args.ticks, **shape)
            results[name] = measure(browser, run, args.rounds)
            report(name, args.ticks, results[name])
        browser.close()
    small, big = results.values()
    print(
        json.dumps(
            {
                "benchmark": "viewer_size",
                "ticks": args.ticks,
                "rounds": args.rounds,
                "html_mb_36k": round(small["html_mb"], 3),
                "jsonl_mb_36k": round(small["jsonl_mb"], 3),
                "html_vs_jsonl_size": round(small["html_mb"] / small["jsonl_mb"], 3),
                "build_s": round(small["build_s"], 3),
                "open_s_36k": round(small["open"]["median"], 3),
                "open_s_min": round(small["open"]["min"], 3),
                "open_s_max": round(small["open"]["max"], 3),
                "reference_open_s_median": round(small["reference"]["median"], 3),
                "open_vs_reference_median": round(small["ratio"]["median"], 3),
                "open_vs_reference_min": round(small["ratio"]["min"], 3),
                "open_vs_reference_max": round(small["ratio"]["max"], 3),
                "scrub_ms_median": round(small["scrub_ms"]["median"], 2),
                "html_mb_36k_1000_nodes": round(big["html_mb"], 3),
                "open_s_36k_1000_nodes": round(big["open"]["median"], 3),
                "open_vs_reference_1000_nodes_median": round(big["ratio"]["median"], 3),
                "scrub_ms_1000_nodes_median": round(big["scrub_ms"]["median"], 2),
            },
            sort_keys=True,
        )
    )


if __name__ == "__main__":
    main()
