"""Every broken mission in bad_inputs/ is refused by `missiontree validate` with the expected message.

Each ``NAME.yaml`` is paired with ``NAME.expected``: lines that must each appear in the report
(they carry ``file:line:col``). Every case must exit 2, print one ``file:line:col:`` line per
problem, never a traceback, and finish within a few seconds.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import time
import tracemalloc
from pathlib import Path

import pytest

from missiontree.cli.main import main

HERE = Path(__file__).parent / "bad_inputs"
CASES = sorted(p.stem for p in HERE.glob("*.expected"))
PROBLEM_LINE = re.compile(r"^[^\s:][^:]*\.(yaml|py):\d+:\d+: ")
SUMMARY_LINE = re.compile(r"^\d+ problems? in \d+ files?$")


def run_validate(
    name: str, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> tuple[int, str]:
    monkeypatch.chdir(HERE)
    code = main(["validate", "--no-plugins", f"{name}.yaml"])
    captured = capsys.readouterr()
    return code, captured.err


def test_there_are_at_least_thirty_cases() -> None:
    """The suite holds at least thirty broken files, each with its expected message."""
    assert len(CASES) >= 30
    for name in CASES:
        assert (HERE / f"{name}.yaml").is_file(), name


@pytest.mark.parametrize("name", CASES)
def test_bad_input_is_refused_with_expected_message(
    name: str, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """The case exits 2, names file and line on every problem line, and says what was expected."""
    start = time.process_time()  # CPU time: a loaded machine stretches wall time, not the work done
    code, err = run_validate(name, capsys, monkeypatch)
    elapsed = time.process_time() - start
    assert code == 2, err
    assert "Traceback" not in err
    assert elapsed < 5.0
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert SUMMARY_LINE.match(lines[-1]), lines[-1]
    for line in lines[:-1]:
        assert PROBLEM_LINE.match(line), f"not a file:line:col problem line: {line}"
    for expected in (HERE / f"{name}.expected").read_text().splitlines():
        if expected.strip():
            assert any(expected in line for line in lines), f"missing {expected!r} in:\n{err}"


@pytest.mark.parametrize("name", ["alias_bomb", "deep_nesting", "deep_tree"])
def test_costly_inputs_stay_in_bounded_memory(
    name: str, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """Alias bombs and absurd nesting are refused using less than 50 MB of Python memory."""
    tracemalloc.start()
    try:
        code, _ = run_validate(name, capsys, monkeypatch)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert code == 2
    assert peak < 50 * 1024 * 1024


def test_absurd_size_is_refused_before_parsing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """A mission file of several megabytes is refused at once, naming its size."""
    huge = tmp_path / "huge.yaml"
    huge.write_text("root: Succeed\nblackboard:\n" + "".join(f"  k{i}: {i}\n" for i in range(400_000)))
    monkeypatch.chdir(tmp_path)
    start = time.process_time()  # CPU time: the size is refused before the file is read
    code = main(["validate", "--no-plugins", "huge.yaml"])
    err = capsys.readouterr().err
    assert code == 2
    assert time.process_time() - start < 2.0
    assert re.search(r"^huge\.yaml:1:1: expected a file of at most \d+ bytes, found \d+ bytes", err, re.M)


def test_real_entry_point_reports_without_traceback() -> None:
    """The installed `missiontree` command (a fresh process) exits 2 with file:line lines and no traceback."""
    env = {**os.environ, "MISSIONTREE_DISABLE_PLUGIN_AUTOLOAD": "1"}
    done = subprocess.run(
        [sys.executable, "-m", "missiontree.cli.main", "validate", "many_problems.yaml", "tabs.yaml",
         "alias_bomb.yaml"],
        cwd=HERE, capture_output=True, text=True, timeout=60, env=env, check=False,
    )
    assert done.returncode == 2
    assert "Traceback" not in done.stderr
    assert "many_problems.yaml:4:9:" in done.stderr
    assert "tabs.yaml:2:1:" in done.stderr
    assert "alias_bomb.yaml:" in done.stderr
    assert "problems in 3 files" in done.stderr
