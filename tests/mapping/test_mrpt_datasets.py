"""Where MRPT's datasets are found: apt's folder, the package ``make setup-mrpt`` extracts, the override."""

from __future__ import annotations

from pathlib import Path

import pytest

from missiontree.backends.sim import mrpt_worlds
from missiontree.mapping import mrpt_datasets
from missiontree.mapping.mrpt_datasets import EXTRACT_DIR, PACKAGE_DATASETS, find_dataset, missing_reason


@pytest.fixture
def no_system_install(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> Path:
    """No apt install, no override; the source checkout is an empty folder (returned)."""
    monkeypatch.delenv(mrpt_datasets.DATASETS_ENV, raising=False)
    monkeypatch.setattr(mrpt_datasets, "SYSTEM_DIRS", ())
    root = tmp_path / "checkout"
    root.mkdir()
    monkeypatch.setattr(mrpt_datasets, "SOURCE_ROOT", root)
    monkeypatch.chdir(root)
    return root


def test_package_extracted_without_root_is_found(no_system_install: Path) -> None:
    """A mrpt-common .deb unpacked by `dpkg-deb -x` into .cache/mrpt-common is where the data is read."""
    folder = no_system_install / EXTRACT_DIR / PACKAGE_DATASETS
    folder.mkdir(parents=True)
    for name in mrpt_worlds.MAPS.values():
        (folder / name).write_bytes(b"")
    assert find_dataset("2006-MalagaCampus.gridmap.gz") == (folder / "2006-MalagaCampus.gridmap.gz").resolve()
    assert mrpt_worlds.datasets_dir() == folder.resolve()
    assert mrpt_worlds.mrpt_available()


def test_nothing_installed_gives_a_reason_naming_both_ways(no_system_install: Path) -> None:
    """With neither install the lookup is None and the skip reason names apt-get and make setup-mrpt."""
    assert find_dataset("tests_rgbd.rawlog") is None
    reason = missing_reason("tests_rgbd.rawlog")
    assert "apt-get install -y mrpt-common" in reason and "make setup-mrpt" in reason
    assert str(no_system_install / EXTRACT_DIR / PACKAGE_DATASETS) in reason
    with pytest.raises(FileNotFoundError, match="tests_rgbd.rawlog"):
        mrpt_datasets.dataset_path("tests_rgbd.rawlog")


def test_override_is_the_only_folder_tried(no_system_install: Path, monkeypatch: pytest.MonkeyPatch,
                                           tmp_path: Path) -> None:
    """$MISSIONTREE_MRPT_DATASETS replaces every other folder."""
    monkeypatch.setenv(mrpt_datasets.DATASETS_ENV, str(tmp_path / "mine"))
    assert mrpt_datasets.candidate_dirs() == [tmp_path / "mine"]
