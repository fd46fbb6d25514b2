"""benchmarks/real_scans.py: raw and corrected figures side by side, the last line one JSON object."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
import real_scans  # noqa: E402


def test_a_missing_rawlog_exits_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A rawlog that is not there exits 2 saying how to install MRPT's datasets."""
    assert real_scans.main(["--rawlog", str(tmp_path / "none.rawlog")]) == 2
    assert "mrpt-common" in capsys.readouterr().err


@pytest.mark.realdata
@pytest.mark.skipif(not real_scans.LOOP.is_file(), reason="MRPT datasets missing (make setup-mrpt)")
def test_prints_raw_and_corrected_with_json_last(capsys: pytest.CaptureFixture[str]) -> None:
    """The benchmark prints both columns and ends with JSON whose corrected loop gap is below the raw one."""
    pytest.importorskip("kiss_icp", reason="KISS-ICP (the realdata extra) is not installed")
    assert real_scans.main([]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    result = json.loads(lines[-1])
    assert result["corrected"]["loop_gap_m_median"] < result["raw"]["loop_gap_m_median"]
    assert any(line.startswith("loop_gap_m_median") for line in lines)
