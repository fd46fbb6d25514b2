"""The viewer in a real browser: Debian's Chromium driven by Playwright (no browser download).

Each test opens the page, moves the timeline and compares what the page shows — node statuses,
the map's marks, the event list — with the tick log replayed line by line.
"""

from __future__ import annotations

import json
import os
import shutil
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from runlog_helpers import read_lines, statuses_by_replaying

from missiontree.runlog.follow import make_server
from missiontree.runlog.html import write_page
from missiontree.runlog.record import write_runview
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
RUNNER_LINES = {"tick", "halted", "mission_started", "mission_finished"}


def _missing(reason: str) -> None:
    if os.environ.get("MISSIONTREE_REQUIRE_BROWSER") == "1":
        pytest.fail(
            f"MISSIONTREE_REQUIRE_BROWSER=1 but {reason}; run `make setup-browser` (apt chromium) and "
            f"install the dev extra (playwright)"
        )
    pytest.skip(reason)


@pytest.fixture(scope="module")
def browser() -> Iterator[Any]:
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        _missing("playwright is not installed")
    if not Path(CHROMIUM).exists() and shutil.which("chromium") is None:
        _missing("Debian's chromium is not installed")
    with sync_playwright() as playwright:
        launched = playwright.chromium.launch(
            executable_path=CHROMIUM if Path(CHROMIUM).exists() else shutil.which("chromium"),
            headless=True,
            args=FLAGS,
        )
        yield launched
        launched.close()


@pytest.fixture
def page(browser: Any) -> Iterator[Any]:
    context = browser.new_context(viewport={"width": 1400, "height": 900})
    opened = context.new_page()
    errors: list[str] = []
    opened.on("pageerror", lambda error: errors.append(str(error)))
    opened.errors = errors
    yield opened
    context.close()
    assert not errors, f"the page raised: {errors}"


def open_page(page: Any, path: Path) -> float:
    start = time.perf_counter()
    page.goto(path.as_uri())
    page.wait_for_selector("body[data-ready='1']")
    return time.perf_counter() - start


def scrub_to(page: Any, index: int) -> None:
    """Move the timeline's slider as a user would (its input event)."""
    page.locator("#scrub").fill(str(index))
    page.wait_for_function(f"document.body.dataset.index === '{index}'")


def shown_statuses(page: Any) -> dict[str, str]:
    return dict(
        page.evaluate(
            "Array.from(document.querySelectorAll('.node'), e => [e.dataset.path, e.dataset.status])"
        )
    )


def test_statuses_map_and_events_match_the_log_at_chosen_ticks(page: Any, patrol_run: Path, tmp_path: Path):
    """At several ticks (first, first alarm, middle, last) the page agrees with the tick log."""
    report = write_page(patrol_run, tmp_path / "report.html")
    assert open_page(page, report) < 3.0
    lines = read_lines(patrol_run)
    ticks = [line for line in lines if line["event"] == "tick"]
    events = [line for line in lines if line["event"] not in RUNNER_LINES]
    poses = json.loads((patrol_run / "runview.json").read_text())["poses"]
    first_alarm = next(e["tick"] for e in events if e["event"] == "alarm")
    chosen = sorted({ticks[0]["tick"], first_alarm, ticks[len(ticks) // 2]["tick"], ticks[-1]["tick"]})
    for number in chosen:
        index = number - ticks[0]["tick"]
        scrub_to(page, index)
        assert page.evaluate("document.body.dataset.tick") == str(number)
        expected = statuses_by_replaying(lines, number)
        shown = shown_statuses(page)
        assert {p: s for p, s in shown.items() if s != "INVALID"} == {
            p: s for p, s in expected.items() if s != "INVALID"
        }, f"tick {number}"
        upto = [e for e in events if e["tick"] <= number]
        assert page.locator("#events").get_attribute("data-count") == str(len(upto))
        if upto:
            assert page.locator("#events li").first.get_attribute("data-kind") == upto[-1]["event"]
        marks = page.locator("#map")
        goals = [e for e in upto if e["event"] == "goal_sent"]
        alarms = [e for e in upto if e["event"] == "alarm"]
        assert marks.get_attribute("data-goals") == str(len(goals))
        assert marks.get_attribute("data-alarms") == str(len(alarms))
        t = next(line["t"] for line in ticks if line["tick"] == number)
        assert marks.get_attribute("data-path-points") == str(sum(1 for p in poses if p[0] <= t + 1e-9))
        if number >= first_alarm:
            assert page.locator("#frame").is_visible(), "the latest alarm's frame is shown"
    page.screenshot(path=str(tmp_path / "viewer.png"))
    assert (tmp_path / "viewer.png").stat().st_size > 10_000


def test_node_details_and_blackboard_at_the_selected_tick(page: Any, patrol_run: Path, tmp_path: Path):
    """Clicking a node shows its feedback at that tick; the blackboard lists the keys written so far."""
    open_page(page, write_page(patrol_run, tmp_path / "report.html"))
    lines = read_lines(patrol_run)
    ticks = [line for line in lines if line["event"] == "tick"]
    number = ticks[len(ticks) // 3]["tick"]
    scrub_to(page, number - ticks[0]["tick"])
    page.locator(".node[data-path='respond_or_patrol/patrol_and_watch/patrol'] > .row").click()
    feedback = ""
    board: dict[str, Any] = {}
    for line in ticks:
        if line["tick"] > number:
            break
        for change in line.get("changed", []):
            if change["node"] == "respond_or_patrol/patrol_and_watch/patrol":
                feedback = change.get("feedback", "")
        board.update(line.get("bb", {}))
        for key in line.get("bb_unset", []):
            board.pop(key, None)
    assert page.locator("#details dd[data-field='feedback']").inner_text() == (feedback or "—")
    assert page.locator("#details dd[data-field='type']").inner_text().startswith("Patrol")
    keys = page.evaluate("Array.from(document.querySelectorAll('#bb tr'), r => r.dataset.key)")
    assert keys == sorted(board)


def failing_run(run_dir: Path) -> Path:
    """A two-leaf run whose second leaf fails with a reason at tick 5."""
    from test_replay import TREE, failing_log

    run_dir.mkdir(parents=True, exist_ok=True)
    (run_dir / "ticks.jsonl").write_text("".join(json.dumps(r) + "\n" for r in failing_log()))
    write_runview(run_dir, {"version": 1, "tree": TREE})
    return run_dir


def test_why_did_it_end_jumps_to_the_deciding_failure_chain(page: Any, tmp_path: Path):
    """The button selects the tick where the leaf failed and marks root -> leaf, with the reason."""
    report = write_page(failing_run(tmp_path / "run"), tmp_path / "report.html")
    open_page(page, report)
    scrub_to(page, 0)
    page.locator("#why").click()
    assert page.evaluate("document.body.dataset.tick") == "5"
    chain = page.evaluate("Array.from(document.querySelectorAll('.node.chain'), e => e.dataset.path)")
    assert chain == ["main", "main/look"]
    assert page.locator("#details dd[data-field='failure reason']").inner_text() == "no object"
    assert "no object" in page.locator("#ending").inner_text()


def test_a_thousand_node_tree_opens_searches_and_collapses(page: Any, tmp_path: Path):
    """1,000+ nodes: opens fast, search finds by name and reveals, collapse hides subtrees."""
    run = tmp_path / "big"
    synthesize_run(run, 600, leaves=50, groups=20)
    elapsed = open_page(page, write_page(run, tmp_path / "big.html"))
    assert page.locator(".node").count() == 1 + 2 + 20 * 51
    assert elapsed < 3.0
    page.locator("#collapse").click()
    assert not page.locator(".node[data-path='root/group7/step3']").is_visible()
    page.locator("#search").fill("step33")
    assert page.locator("#matches").inner_text() == "20 matches"
    assert page.locator(".node[data-path='root/group7/step33']").is_visible()
    page.locator("#search").press("Enter")
    assert page.locator(".node.sel").get_attribute("data-path") == "root/group0/step33"


def test_play_advances_and_pause_stops(page: Any, synthetic_run: Path, tmp_path: Path):
    """Play moves the selected tick forward at the chosen speed; pause holds it."""
    open_page(page, write_page(synthetic_run, tmp_path / "report.html"))
    scrub_to(page, 0)
    page.locator("#speed").select_option("100")
    page.locator("#play").click()
    page.wait_for_function("Number(document.body.dataset.index) > 50")
    page.locator("#play").click()
    held = page.evaluate("document.body.dataset.index")
    page.wait_for_timeout(300)
    assert page.evaluate("document.body.dataset.index") == held


def test_follow_updates_the_page_as_the_log_grows(page: Any, tmp_path: Path):
    """Served live, the page picks up ticks written after it opened."""
    source = tmp_path / "source"
    synthesize_run(source, 400)
    lines = (source / "ticks.jsonl").read_text().splitlines(keepends=True)
    live = tmp_path / "live"
    live.mkdir()
    shutil.copy(source / "runview.json", live / "runview.json")
    half = len(lines) // 2
    (live / "ticks.jsonl").write_text("".join(lines[:half]))
    server = make_server(live, 0)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        host, port = server.server_address[:2]
        page.goto(f"http://{host}:{port}/")
        page.wait_for_selector("body[data-ready='1']")
        first = page.evaluate("MT.count()")
        assert 0 < first < 400
        with (live / "ticks.jsonl").open("a") as stream:
            stream.write("".join(lines[half:]))
        page.wait_for_function("MT.count() === 400", timeout=10_000)
        assert page.evaluate("document.body.dataset.tick") == "400", "a page left at the end follows the end"
    finally:
        server.shutdown()
        server.server_close()


def test_the_scene_graph_is_drawn_on_the_map_and_can_be_hidden(page: Any, tmp_path: Path):
    """The run's scene graph shows as labelled objects and the served target; the checkbox hides it."""
    run = tmp_path / "run"
    synthesize_run(run, 200)
    nodes = [
        {"id": "room_1", "type": "room", "label": "kitchen"},
        {"id": "cup_1", "type": "object", "label": "cup", "coordinates": [1.0, 2.0, 0.8]},
        {"id": "chair_1", "type": "object", "label": "chair", "coordinates": [3.0, 1.0, 0.4]},
    ]
    edges = [{"source_id": "room_1", "target_id": "cup_1", "relation": "contains"}]
    (run / "scene_graph.json").write_text(json.dumps({"nodes": nodes, "edges": edges}))
    summary = json.loads((run / "summary.json").read_text())
    summary["outcome"] = {"intent": {"commands": [{"status": "served", "object": "chair_1"}]}}
    (run / "summary.json").write_text(json.dumps(summary))
    open_page(page, write_page(run, tmp_path / "report.html"))
    marks = page.locator("#map")
    assert marks.get_attribute("data-scene-objects") == "2"
    assert marks.get_attribute("data-scene-rooms") == "1"
    assert marks.get_attribute("data-target") == "served: chair"
    page.locator("#scenetoggle").uncheck()
    assert marks.get_attribute("data-scene-objects") == "0"


def test_the_alarm_frame_sits_beside_the_map_not_over_it(page: Any, patrol_run: Path, tmp_path: Path):
    """With an alarm frame shown, the frame's box and the map's box do not overlap."""
    open_page(page, write_page(patrol_run, tmp_path / "report.html"))
    assert page.locator("#frame").is_visible()
    frame = page.locator("#frame").bounding_box()
    drawn = page.locator("#map").bounding_box()
    assert frame is not None and drawn is not None
    assert frame["x"] >= drawn["x"] + drawn["width"] - 0.5, (frame, drawn)
    width = page.evaluate("document.getElementById('map').width")
    assert abs(width - round(drawn["width"])) <= 2, "the canvas is drawn at its laid-out size"


def test_the_profile_lists_the_nodes_that_took_the_most_cpu(page: Any, tmp_path: Path):
    """The side pane's profile lists nodes by CPU, most first; a node's details give its own figures."""
    run = tmp_path / "run"
    synthesize_run(run, 100)
    summary = json.loads((run / "summary.json").read_text())
    leaf = json.loads((run / "runview.json").read_text())["tree"]["children"][0]["path"]
    figures = {"cpu_s": 2.0, "cpu_realtime_factor": 5.0, "rss_peak_mb": 280.0}
    summary["profile"] = {"nodes": {"root": {"ticks": 100, "rate_hz": 10.0, "cpu_s": 0.01},
                                    leaf: {"ticks": 40, "rate_hz": 4.0, "cpu_s": 0.5}},
                          "run": figures, "models": {}}
    (run / "summary.json").write_text(json.dumps(summary))
    open_page(page, write_page(run, tmp_path / "report.html"))
    assert page.locator("#profpane").is_visible()
    assert page.locator("#prof tr[data-path]").first.get_attribute("data-path") == leaf
    assert "2.00 s CPU" in page.locator("#profnote").inner_text()
    page.locator(f".node[data-path='{leaf}'] > .row").click()
    assert "40 ticks · 4.0 Hz · 0.500 s CPU" in page.locator("#details").inner_text()
