"""Tests of batch plans: seeds, worlds, --set and --sweep expand as the batch command documents."""

from __future__ import annotations

import tracemalloc
from collections.abc import Callable
from pathlib import Path

import pytest

from missiontree.errors import ConfigError
from missiontree.evaluation.plan import (
    RunSpec,
    derive_seed,
    expand_plan,
    parse_assignments,
    parse_seeds,
    parse_sweeps,
    parse_worlds,
)


def test_seed_ranges_and_lists_expand_in_order() -> None:
    """'0-999' is the thousand seeds 0..999; lists and ranges mix in the order written."""
    assert parse_seeds("0-999") == list(range(1000))
    assert parse_seeds("5, 0-2,10") == [5, 0, 1, 2, 10]
    assert parse_seeds("7") == [7]


@pytest.mark.parametrize("text", ["", "a", "-3", "3-1", "1,,2", "0-2,1", "1.5"])
def test_bad_seeds_are_refused(text: str) -> None:
    """Backwards ranges, repeats, negatives and non-numbers are a ConfigError naming --seeds."""
    with pytest.raises(ConfigError, match="--seeds"):
        parse_seeds(text)


def test_worlds_expand_names_and_source_ranges() -> None:
    """'office,generated:0-49' is the office world then generated:0 .. generated:49."""
    worlds = parse_worlds("office,generated:0-49")
    assert worlds[0] == "office"
    assert worlds[1:] == [f"generated:{n}" for n in range(50)]
    assert parse_worlds("generated:7,maps/a.yaml") == ["generated:7", "maps/a.yaml"]


@pytest.mark.parametrize("text", ["office,office", "generated:5-1", "office,"])
def test_bad_worlds_are_refused(text: str) -> None:
    """A world twice, a backwards range or an empty item is a ConfigError naming --worlds."""
    with pytest.raises(ConfigError, match="--worlds"):
        parse_worlds(text)


def test_sweeps_split_on_top_level_commas_only() -> None:
    """Values with brackets keep their commas; each key is one axis of the grid."""
    assert parse_sweeps(["laps=1,2,3", "goal=[1,2],[3,4]"]) == {"laps": ["1", "2", "3"],
                                                                "goal": ["[1,2]", "[3,4]"]}
    with pytest.raises(ConfigError, match="--sweep"):
        parse_sweeps(["laps"])
    with pytest.raises(ConfigError, match="twice"):
        parse_assignments(["a=1", "a=2"])


def test_plan_is_worlds_by_grid_by_seeds() -> None:
    """Every combination once, ordered world, then sweep values, then seed; --set in every run."""
    plan = expand_plan(Path("m.yaml"), seeds=[0, 1], worlds=["office", "generated:3"],
                       fixed={"route": "a"}, sweeps={"laps": ["1", "2"], "fast": ["true", "false"]})
    assert len(plan.runs) == 2 * 4 * 2
    first = plan.runs[0]
    assert (first.world, first.seed, first.params_dict) == ("office", 0, {"fast": "true", "laps": "1",
                                                                          "route": "a"})
    assert [r.seed for r in plan.runs[:4]] == [0, 1, 0, 1]
    assert plan.runs[-1].world == "generated:3"
    assert len({r.run_id for r in plan.runs}) == len(plan.runs)
    assert plan.sweep_keys == ["laps", "fast"]


def test_run_seed_is_the_batch_seed_or_derived_and_recorded() -> None:
    """Without a base seed the run seed is the batch seed; with one it is derived, stable and distinct."""
    plain = expand_plan(Path("m.yaml"), seeds=[3, 4])
    assert [(r.seed, r.run_seed) for r in plain.runs] == [(3, 3), (4, 4)]
    derived = expand_plan(Path("m.yaml"), seeds=[3, 4], base_seed=11)
    assert [r.run_seed for r in derived.runs] == [derive_seed(11, 3), derive_seed(11, 4)]
    assert derive_seed(11, 3) != derive_seed(12, 3) != derive_seed(11, 4)
    assert derive_seed(11, 3) == derive_seed(11, 3)
    assert derived.describe()["base_seed"] == 11


def test_a_key_both_set_and_swept_is_refused() -> None:
    """--set laps=1 with --sweep laps=1,2 is ambiguous."""
    with pytest.raises(ConfigError, match="both --set and --sweep"):
        expand_plan(Path("m.yaml"), seeds=[0], fixed={"laps": "1"}, sweeps={"laps": ["1", "2"]})


def test_run_ids_are_safe_directory_names_and_unique() -> None:
    """World paths and odd values become safe names; two specs differing only in unsafe characters differ."""
    a = RunSpec(world="maps/a b.yaml", seed=1, run_seed=1, params=(("t", "red/blue"),))
    b = RunSpec(world="maps/a_b.yaml", seed=1, run_seed=1, params=(("t", "red/blue"),))
    assert "/" not in a.run_id and " " not in a.run_id
    assert a.run_id != b.run_id
    assert RunSpec(world="office", seed=2, run_seed=2).run_id == "office_s2"


def _peak_bytes(call: Callable[[], object]) -> int:
    """Peak Python allocation (bytes) while ``call`` runs (the ConfigError it raises is swallowed)."""
    tracemalloc.start()
    try:
        call()
    except ConfigError:
        pass
    finally:
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
    return peak


def test_seed_ranges_are_counted_together_before_they_are_built() -> None:
    """A range within the cap that takes the seeds over it is refused before it is expanded."""
    text = "0-9,10-1000009"
    with pytest.raises(ConfigError, match="more than 1000000 seeds in all"):
        parse_seeds(text)
    assert _peak_bytes(lambda: parse_seeds(text)) < 5 * 2**20


def test_world_ranges_are_counted_together_before_they_are_built() -> None:
    """World ranges over the cap together are refused, naming the range that crossed it."""
    with pytest.raises(ConfigError, match="more than 1000000 worlds in all"):
        parse_worlds("generated:0-999999,floorplan:0-999")


def test_a_sweep_grid_is_counted_before_it_is_built() -> None:
    """A sweep grid of 40^4 combinations is refused before its combinations are listed (small memory)."""
    sweeps = {f"k{i}": [str(v) for v in range(40)] for i in range(4)}
    with pytest.raises(ConfigError, match="would make 2560000 runs"):
        expand_plan(Path("m.yaml"), seeds=[0], sweeps=sweeps)
    assert _peak_bytes(lambda: expand_plan(Path("m.yaml"), seeds=[0], sweeps=sweeps)) < 5 * 2**20
