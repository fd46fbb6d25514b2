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
from missiontree.runlog.synthetic import synthesize_run

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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--ticks", type=int, default=36_000)
    parser.add_argument("--rounds", type=int, default=5)
    args = parser.parse_args()
    from playwright.sync_api import sync_playwright

    with tempfile.TemporaryDirectory() as tmp:
        run = Path(tmp) / "run"
        start = time.perf_counter()
        log = synthesize_run(run, args.ticks)
        synth_s = time.perf_counter() - start
        start = time.perf_counter()
        page = write_page(run, run / "report.html")
        build_s = time.perf_counter() - start
        reference = reference_page(log, run / "reference.html")
        html_mb = page.stat().st_size / 1e6
        jsonl_mb = log.stat().st_size / 1e6
        print(
            f"{args.ticks} ticks: ticks.jsonl {jsonl_mb:.2f} MB, page {html_mb:.2f} MB "
            f"({html_mb / jsonl_mb:.2f} of the log), built in {build_s:.2f} s"
            f" (synthesized in {synth_s:.2f} s)"
        )
        viewer_s: list[float] = []
        reference_s: list[float] = []
        with sync_playwright() as playwright:
            browser = playwright.chromium.launch(executable_path=CHROMIUM, headless=True, args=FLAGS)
            open_seconds(browser, reference)  # warm the browser's caches once, off the record
            for _ in range(args.rounds):  # alternate: the same browser state for both
                viewer_s.append(open_seconds(browser, page))
                reference_s.append(open_seconds(browser, reference))
            browser.close()
    ratios = [v / r for v, r in zip(viewer_s, reference_s, strict=True)]
    v, r, q = spread(viewer_s), spread(reference_s), spread(ratios)
    print(
        f"open viewer    s  min {v['min']:.3f}  median {v['median']:.3f}  max {v['max']:.3f}  (target <= 3)"
    )
    print(
        f"open reference s  min {r['min']:.3f}  median {r['median']:.3f}  max {r['max']:.3f}"
        "  (raw log, parse only)"
    )
    print(f"viewer / reference  min {q['min']:.2f}  median {q['median']:.2f}  max {q['max']:.2f}")
    print(
        json.dumps(
            {
                "benchmark": "viewer_size",
                "ticks": args.ticks,
                "rounds": args.rounds,
                "html_mb_36k": round(html_mb, 3),
                "jsonl_mb_36k": round(jsonl_mb, 3),
                "html_vs_jsonl_size": round(html_mb / jsonl_mb, 3),
                "build_s": round(build_s, 3),
                "open_s_36k": round(v["median"], 3),
                "open_s_min": round(v["min"], 3),
                "open_s_max": round(v["max"], 3),
                "reference_open_s_median": round(r["median"], 3),
                "open_vs_reference_median": round(q["median"], 3),
                "open_vs_reference_min": round(q["min"], 3),
                "open_vs_reference_max": round(q["max"], 3),
            },
            sort_keys=True,
        )
    )


if __name__ == "__main__":
    main()
