"""Engine helpers that need no workers: Dask's chunking of runs."""

from __future__ import annotations

from pathlib import Path

import pytest

from missiontree.errors import ConfigError
from missiontree.evaluation.dask_engine import DaskEngine, guided_chunks
from missiontree.evaluation.plan import RunSpec
from missiontree.evaluation.worker import RunTask


def _tasks(count: int) -> list[RunTask]:
    runs = str(Path("runs"))
    return [RunTask(RunSpec(world=None, seed=s, run_seed=s), "m.yaml", runs) for s in range(count)]


def test_guided_chunks_shrink_to_single_runs_and_keep_the_order() -> None:
    tasks = _tasks(23)
    chunks = guided_chunks(tasks, workers=2, most=32)
    assert [len(c) for c in chunks] == [8, 5, 4, 2, 2, 1, 1]
    assert [t for c in chunks for t in c] == tasks


def test_guided_chunks_respect_the_most_runs_a_chunk() -> None:
    assert max(len(c) for c in guided_chunks(_tasks(100), workers=2, most=3)) == 3
    assert [len(c) for c in guided_chunks(_tasks(3), workers=2, most=8)] == [1, 1, 1]


def test_guided_chunks_send_at_most_one_more_than_the_workers_alone_at_the_end() -> None:
    for count in range(1, 120):
        for workers in (1, 2, 3, 8):
            sizes = [len(c) for c in guided_chunks(_tasks(count), workers=workers, most=32)]
            assert sum(sizes) == count and sizes == sorted(sizes, reverse=True)
            assert sizes.count(1) <= workers + 1


@pytest.mark.parametrize("chunk", [0, -1, "big", True, 1.5])
def test_dask_engine_refuses_a_bad_chunk(chunk: object) -> None:
    pytest.importorskip("distributed")
    with pytest.raises(ConfigError, match="chunk"):
        DaskEngine("local", 1, chunk=chunk)  # type: ignore[arg-type]


TWO_CLUSTERS = """\
from missiontree.evaluation import DaskEngine

if __name__ == "__main__":
    first, second = DaskEngine("local", 1), DaskEngine("local", 1)
    first.close()
    second.close()
    print("closed")
"""


@pytest.mark.slow
def test_two_local_clusters_start_and_close_without_a_word(tmp_path: Path) -> None:
    """No 'Port 8787 is already in use' warning, no INFO lines of the second's shutdown, no traceback.

    In a process of its own: what a user of two engines sees on the terminal.
    """
    pytest.importorskip("distributed")
    import subprocess
    import sys

    script = tmp_path / "two_clusters.py"
    script.write_text(TWO_CLUSTERS, encoding="utf-8")
    done = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=120,
                          cwd=tmp_path, check=False)
    assert done.returncode == 0 and done.stdout.strip() == "closed", done.stderr
    assert done.stderr == "", done.stderr


def _sizer(workers: int) -> DaskEngine:
    engine = object.__new__(DaskEngine)  # no cluster: only the sizing rule
    engine.workers = workers
    return engine


def test_auto_chunks_are_single_runs_until_run_times_say_they_are_short() -> None:
    from collections import deque

    from missiontree.evaluation import dask_engine

    sizer = _sizer(2)
    assert sizer._chunk_size(100, deque()) == 1  # nothing known yet
    assert sizer._chunk_size(100, deque([dask_engine.SHORT_RUN_S * 2] * 4)) == 1  # long runs: alone
    short = dask_engine.CHUNK_S / 8  # eight runs make a chunk's worth
    assert sizer._chunk_size(100, deque([short] * 4)) == 8
    assert sizer._chunk_size(10, deque([short] * 4)) == 4  # 10 left over 3: guided, rounded up
    assert sizer._chunk_size(2, deque([short] * 4)) == 1
    # two workers' first runs, slow with their imports, beside two ordinary ones: the quartile decides
    assert sizer._chunk_size(100, deque([0.45, 0.4, short, short])) >= 4
