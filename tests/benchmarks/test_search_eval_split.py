"""The search benchmark's held-out sample: the real maps come first in every round of the test cycle."""

from __future__ import annotations

import sys
from pathlib import Path

from missiontree.evaluation.splits import current_test_cycle

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
import search_eval  # noqa: E402


def test_a_sample_smaller_than_the_cycle_holds_every_real_map() -> None:
    """The first seeds of the sample are the cycle's real maps (warehouse and depot among them)."""
    cycle = current_test_cycle()
    maps = [p for p in cycle if p[0] != "floorplan"]
    seeds = search_eval.held_out_seeds(len(maps), first_seed=0)
    assert sorted(cycle[s % len(cycle)] for s in seeds) == sorted(maps)
    assert ("map", "warehouse") in maps and ("map", "depot") in maps


def test_a_whole_round_holds_every_place_once_and_no_seed_twice() -> None:
    """Two rounds from any first seed: every place twice, every seed distinct, none below the first."""
    cycle = current_test_cycle()
    seeds = search_eval.held_out_seeds(2 * len(cycle), first_seed=5)
    assert len(set(seeds)) == len(seeds) and min(seeds) >= 5
    places = [cycle[s % len(cycle)] for s in seeds]
    assert all(places.count(p) == 2 for p in cycle)


def test_the_cycle_order_is_the_seeds_in_order() -> None:
    """--test-order cycle keeps the seeds from the first one on."""
    assert search_eval.held_out_seeds(4, first_seed=3, order="cycle") == [3, 4, 5, 6]


def test_large_dev_apartments_come_from_the_dev_generator_at_the_size_asked(tmp_path: Path) -> None:
    """--dev-rooms and --dev-size make a larger apartment of the same generator, still a dev case."""
    import yaml

    assert search_eval._size("36x24") == (36.0, 24.0) and search_eval._size("") is None
    case, path = search_eval.make_case(0, 310, False, tmp_path, rooms=12, size=(30.0, 20.0))
    data = yaml.safe_load(path.read_text())
    assert case.split == "dev" and case.world.startswith("generated:")
    assert len(data["rooms"]) >= 8
