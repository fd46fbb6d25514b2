"""Runs to replay: a real patrol on the simulator (short) and synthetic runs of any length."""

from __future__ import annotations

from pathlib import Path

import pytest

from missiontree.paths import REPO_ROOT
from missiontree.testing_runs import synthesize_run


@pytest.fixture(scope="session")
def patrol_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The shipped patrol on the simulator for 40 s of robot time (alarms, goals, model calls)."""
    from missiontree.session import MissionRequest, run_mission

    out = tmp_path_factory.mktemp("patrol") / "run"
    run_mission(
        MissionRequest(
            mission=REPO_ROOT / "trees" / "patrol.yaml",
            out=out,
            max_duration=40.0,
            quiet=True,
            handle_signals=False,
        )
    )
    return out


@pytest.fixture(scope="session")
def synthetic_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A synthetic patrol-like run of 3,000 ticks."""
    out = tmp_path_factory.mktemp("synthetic") / "run"
    synthesize_run(out, 3000)
    return out
