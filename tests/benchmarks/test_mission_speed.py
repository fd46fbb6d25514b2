"""benchmarks/mission_speed.py: a run's figures, the overhead over the simulator alone, the JSON keys."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
import mission_speed  # noqa: E402


def _run(cpu: float, robot: float = 100.0, wall: float = 10.0, rss: float = 300.0) -> mission_speed.Run:
    return mission_speed.Run("patrol", "combined", 1, "SUCCESS", "status", robot, wall, cpu, cpu + 2.0,
                             rss, 1.0, [("model:detector", cpu / 2, 0.5)])


def test_a_runs_real_time_factors_and_cpu_per_robot_second() -> None:
    """100 robot s in 10 s wall and 4 s CPU: 10x wall, 25x CPU, 0.04 CPU s per robot s."""
    run = _run(cpu=4.0)
    assert (run.rtf, run.cpu_rtf, run.cpu_per_robot_s) == (10.0, 25.0, 0.04)


def test_overhead_is_the_median_of_mission_over_sim_alone_per_seed() -> None:
    """Each seed's mission CPU per robot-second over its simulator-alone's; the median is reported."""
    case = mission_speed.Case("patrol", "combined", "default",
                              runs=[_run(4.0), _run(6.0), _run(8.0)], sims=[_run(1.0), _run(1.0), _run(2.0)])
    assert mission_speed.overhead(case) == pytest.approx(4.0)


def test_the_json_keys_are_per_mission_and_world(capsys: pytest.CaptureFixture[str]) -> None:
    """rtf_median, rss_peak_mb and overhead_vs_sim_median are keyed <mission>.<world>."""
    case = mission_speed.Case("patrol", "combined", "default", runs=[_run(4.0, rss=280.0)], sims=[_run(1.0)])
    args = argparse.Namespace(seeds=1, max_duration=60.0)
    result = mission_speed.report([case], (1.0, 1.0, 1.0), args)
    assert result["rtf_median"]["patrol"]["default"] == 10.0
    assert result["rss_peak_mb"]["patrol"]["default"] == 280.0
    assert result["overhead_vs_sim_median"]["patrol"]["default"] == 4.0
    assert "model:detector 50%" in capsys.readouterr().out


def test_a_case_without_runs_says_why() -> None:
    """A mission that could not run on a world is printed with the reason, not dropped."""
    case = mission_speed.Case("go_to_intent", "x.yaml", "floor30x50", skipped=["no scene graph"])
    result = mission_speed.report([case], (1.0, 1.0, 1.0), argparse.Namespace(seeds=1, max_duration=60.0))
    assert "go_to_intent" not in result["rtf_median"]
