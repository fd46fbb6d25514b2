"""The test split's MRPT places: appended after the first 11, only when mrpt-common is installed."""

from __future__ import annotations

from pathlib import Path

import pytest

from missiontree.backends.sim import mrpt_worlds
from missiontree.backends.sim.world import load_world
from missiontree.evaluation import splits
from missiontree.evaluation.splits import (
    MRPT_CYCLE,
    TEST_CYCLE,
    current_test_cycle,
    split_worlds,
    write_split_world,
)

#: The test cycle's first 11 places as benchmarks running before the MRPT maps were added saw them.
FIRST_ELEVEN = (
    ("floorplan", "corridor"), ("map", "tb3_sandbox"), ("floorplan", "l_corridor"),
    ("floorplan", "open_plan"), ("map", "depot"), ("floorplan", "t_corridor"), ("floorplan", "suites"),
    ("map", "maze"),
    ("floorplan", "clutter"), ("floorplan", "warehouse"), ("map", "warehouse"),
)


@pytest.mark.parametrize("installed", [True, False])
def test_first_eleven_places_do_not_move(monkeypatch: pytest.MonkeyPatch, installed: bool) -> None:
    """Whether or not MRPT's maps are installed, test indices 0-10 give the same places."""
    monkeypatch.setattr(splits, "mrpt_available", lambda: installed)
    assert current_test_cycle()[:11] == FIRST_ELEVEN == TEST_CYCLE


def test_mrpt_maps_are_places_11_and_12_when_installed(monkeypatch: pytest.MonkeyPatch) -> None:
    """With the package, the cycle has 13 places, the MRPT maps at 11 and 12."""
    monkeypatch.setattr(splits, "mrpt_available", lambda: True)
    assert current_test_cycle()[11:] == MRPT_CYCLE == (("mrpt", "uwb"), ("mrpt", "malaga"))


def test_without_the_package_one_note_on_stderr(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """Without the package the cycle is the 11 places and one line on stderr names the apt package."""
    monkeypatch.setattr(splits, "mrpt_available", lambda: False)
    monkeypatch.setattr(splits, "_noted", [])
    assert current_test_cycle() == TEST_CYCLE and current_test_cycle() == TEST_CYCLE
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "mrpt-common" in err


@pytest.mark.skipif(
    not mrpt_worlds.mrpt_available(),
    reason="MRPT's datasets are not installed: apt-get install -y mrpt-common (or make setup-mrpt)",
)
def test_index_11_is_the_uwb_world_and_it_writes_and_loads(tmp_path: Path) -> None:
    """Test world 11 is mrpt:uwb:11, a real map with objects, and its written file loads."""
    (world,) = split_worlds("test", 1, first_seed=11, min_objects=3)
    assert (world.name, world.family) == ("mrpt:uwb:11", "real map")
    loaded = load_world(write_split_world(world, tmp_path))
    assert len(loaded.objects) >= 3
