"""The scene-graph benchmark's splits: per-split figures with Wilson intervals, the gap, the table."""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import numpy as np

from missiontree.backends.sim.world import load_world

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
import scene_eval_route  # noqa: E402
import scene_graph_eval  # noqa: E402


def row(tp: int, pred: int, truth: int, reflected: int) -> dict:
    counts = {
        "tp": tp,
        "pred": pred,
        "pred_all": pred,
        "truth": truth,
        "in_room": tp,
        "colour_ok": tp,
        "rooms": 2,
        "types_ok": 1,
        "reflected": reflected,
    }
    return {
        "ours": counts,
        "nais": dict(counts),
        "changes": 6,
        "relations_good": 3,
        "relations": 4,
        "ms_per_frame": {"ours": 1.0, "nais": 1.0},
    }


def test_split_figures_pool_counts_and_give_wilson_intervals() -> None:
    """Rates are pooled over worlds, each with its 95 % Wilson interval and its counts."""
    fig = scene_graph_eval.split_figures([row(9, 10, 10, 6), row(8, 10, 12, 5)])
    assert fig["worlds"] == 2
    assert fig["object_precision"] == 0.85 and fig["counts"]["object_precision"] == [17, 20]
    low, high = fig["ci95"]["object_recall"]
    assert low < 17 / 22 < high
    assert fig["changes_reflected"] == round(11 / 12, 4)
    assert fig["nais"]["relation_precision"] is None


def test_without_a_dynamic_phase_changes_reflected_is_not_measured() -> None:
    """Worlds run without changes (--single-pass) give no changes figure, not a zero."""
    single = row(9, 10, 10, 0)
    single["changes"] = 0
    fig = scene_graph_eval.split_figures([single])
    assert fig["changes_reflected"] is None
    assert any("| changes_reflected | - |" in line for line in scene_graph_eval.markdown_table({"dev": fig}))


def test_markdown_table_shows_both_splits_and_the_gap() -> None:
    """The table has a row per headline figure with dev, test (interval and counts) and the gap."""
    dev = scene_graph_eval.split_figures([row(10, 10, 10, 6)])
    test = scene_graph_eval.split_figures([row(8, 10, 10, 5)])
    result = {"dev": dev, "test": test, "gap": {"object_precision": 0.2}}
    lines = scene_graph_eval.markdown_table(result)
    assert lines[0].startswith("| figure | dev (1 worlds) | test (1 worlds) | gap dev-test |")
    precision = next(line for line in lines if line.startswith("| object_precision "))
    assert "(8/10)" in precision and "+0.200" in precision


def test_free_spot_on_a_world_without_rooms_stays_on_reachable_floor() -> None:
    """A changed object on a real map (no rooms) goes to free floor connected to the robot."""
    world = load_world("office")
    world = dataclasses.replace(world, rooms=[])
    start = world.start
    floor = scene_eval_route.reachable_floor(world, start.x, start.y)
    x, y = scene_eval_route.free_spot(world, np.random.default_rng(3), [], floor)
    row_, col = world.grid.world_to_cell(x, y)
    assert floor[row_, col]


def test_free_spot_in_a_cramped_world_comes_closer_before_giving_up() -> None:
    """Viewpoints covering the floor densely leave a spot 0.6-1 m from them, not an error."""
    world = load_world("office")
    g = world.grid
    rows, cols = np.nonzero(g.data == 0)
    every = [g.cell_to_world(int(r), int(c)) for r, c in zip(rows[::40], cols[::40], strict=True)]
    dense = [p for k, p in enumerate(every) if k % 2 == 0]  # no spot 1 m from all of them
    x, y = scene_eval_route.free_spot(world, np.random.default_rng(1), dense)
    assert min(np.hypot(x - a, y - b) for a, b in dense) >= 0.6
