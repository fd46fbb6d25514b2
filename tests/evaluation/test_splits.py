"""The evaluation splits: dev is the generator's apartments, test is floorplans and real maps."""

from __future__ import annotations

from pathlib import Path

import pytest

from missiontree.backends.sim import load_world
from missiontree.backends.sim.floorplans import KINDS
from missiontree.evaluation.splits import TEST_CYCLE, small_objects, split_worlds, write_split_world


def test_dev_split_is_the_generated_apartments() -> None:
    """Dev worlds are generated:<seed> from the first seed on, without people unless asked."""
    worlds = split_worlds("dev", 2, first_seed=5)
    assert [w.name for w in worlds] == ["generated:5", "generated:6"]
    assert {w.family for w in worlds} == {"generated"}
    assert all(not w.data["people"] for w in worlds)


def test_test_split_is_deterministic_and_differs_in_kind() -> None:
    """The same seed gives the same test world, and the cycle holds floorplans and real maps only."""
    (a,) = split_worlds("test", 1, first_seed=3)
    (b,) = split_worlds("test", 1, first_seed=3)
    assert a == b
    assert a.family == "floorplan" and a.name.startswith("floorplan:")
    assert {family for family, _ in TEST_CYCLE} == {"floorplan", "map"}
    assert {what for family, what in TEST_CYCLE if family == "floorplan"} == set(KINDS)


def test_real_map_test_world_writes_and_loads(tmp_path: Path) -> None:
    """A real-map test world written to any folder loads there, with rooms and placed objects."""
    seed = next(i for i, (family, what) in enumerate(TEST_CYCLE) if what == "tb3_sandbox")
    (world,) = split_worlds("test", 1, first_seed=seed, min_objects=4)
    loaded = load_world(write_split_world(world, tmp_path))
    assert load_world(write_split_world(world, tmp_path)).name == loaded.name  # written again over itself
    assert not list(tmp_path.rglob("*.tmp"))
    assert world.name == f"map:tb3_sandbox:{seed}"
    assert loaded.rooms
    assert sum(o.movable for o in loaded.objects) >= 4


def test_min_objects_tops_up_a_dev_world() -> None:
    """A dev world gets at least min_objects small objects, its own first."""
    (plain,) = split_worlds("dev", 1, first_seed=2)
    (topped,) = split_worlds("dev", 1, first_seed=2, min_objects=15)
    assert len(small_objects(topped.data)) >= 15 > len(small_objects(plain.data))
    assert topped.data["objects"][: len(plain.data["objects"])] == plain.data["objects"]


def test_unknown_split_is_refused() -> None:
    """A split other than dev and test is an error naming the known ones."""
    with pytest.raises(ValueError, match="dev, test"):
        split_worlds("train", 1)
