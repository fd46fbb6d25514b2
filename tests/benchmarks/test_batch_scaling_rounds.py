"""The batch-scaling benchmark's rounds: every run once, each round a whole multiple of the workers."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
import batch_scaling  # noqa: E402

CASES = [(200, 8, 2), (201, 8, 2), (200, 8, 3), (10, 8, 2), (1, 8, 2), (200, 1, 2), (7, 3, 4)]


@pytest.mark.parametrize(("runs", "rounds", "workers"), CASES)
def test_round_sizes_keep_every_run_and_fill_the_workers(runs: int, rounds: int, workers: int) -> None:
    sizes = batch_scaling.round_sizes(runs, rounds, workers)
    assert sum(sizes) == runs and all(size > 0 for size in sizes) and len(sizes) <= rounds
    assert all(size % workers == 0 for size in sizes[:-1])  # only the last holds the spare runs
    assert sizes[-1] % workers == runs % workers


def test_the_default_rounds_give_no_worker_an_extra_run() -> None:
    assert batch_scaling.round_sizes(200, 8, 2) == [26, 26, 26, 26, 24, 24, 24, 24]
