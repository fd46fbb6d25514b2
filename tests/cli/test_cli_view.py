"""``missiontree view`` and ``missiontree log export`` from the command line."""

from __future__ import annotations

from pathlib import Path

import pytest

from missiontree.cli.main import main
from missiontree.runlog.btlog import read_btlog
from missiontree.testing_runs import synthesize_run


@pytest.fixture
def run_dir(tmp_path: Path) -> Path:
    synthesize_run(tmp_path / "run", 200)
    return tmp_path / "run"


def test_view_writes_one_html_file(run_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]):
    """`view RUN --out FILE` writes the page and says where."""
    out = tmp_path / "report.html"
    assert main(["view", str(run_dir), "--out", str(out)]) == 0
    assert out.read_text().startswith("<!DOCTYPE html>")
    assert str(out) in capsys.readouterr().out


def test_view_defaults_to_report_html_in_the_run(run_dir: Path):
    """Without --out the page goes beside the log."""
    assert main(["view", str(run_dir)]) == 0
    assert (run_dir / "report.html").is_file()


def test_view_of_a_missing_run_exits_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]):
    """A run that does not exist is bad input, said plainly."""
    assert main(["view", str(tmp_path / "nope")]) == 2
    assert "does not exist" in capsys.readouterr().err


def test_follow_of_a_missing_directory_exits_2(tmp_path: Path):
    """--follow needs the run directory to exist."""
    assert main(["view", "--follow", str(tmp_path / "nope")]) == 2


def test_log_export_btlog_and_mcap(run_dir: Path, tmp_path: Path):
    """Both formats are written and read back."""
    from mcap.reader import make_reader

    assert (
        main(["log", "export", str(run_dir), "--format", "btlog", "--out", str(tmp_path / "run.btlog")]) == 0
    )
    assert read_btlog((tmp_path / "run.btlog").read_bytes()).transitions
    assert main(["log", "export", str(run_dir), "--format", "mcap", "--out", str(tmp_path / "run.mcap")]) == 0
    with (tmp_path / "run.mcap").open("rb") as stream:
        assert make_reader(stream).get_summary().statistics.message_count > 200


def test_log_export_refuses_a_btlog_without_its_extension(run_dir: Path, tmp_path: Path):
    """Groot2 needs .btlog; another name is bad input (exit 2)."""
    assert main(["log", "export", str(run_dir), "--format", "btlog", "--out", str(tmp_path / "run.bin")]) == 2


def test_log_export_needs_a_known_format(run_dir: Path, tmp_path: Path):
    """An unknown --format is refused by the parser."""
    with pytest.raises(SystemExit) as exit_info:
        main(["log", "export", str(run_dir), "--format", "rosbag", "--out", str(tmp_path / "x")])
    assert exit_info.value.code == 2


def test_run_with_view_serves_records_the_path_and_writes_the_replay(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
):
    """`run --view` starts the live viewer, samples the pose each tick and leaves report.html."""
    from missiontree.paths import REPO_ROOT

    monkeypatch.setattr("missiontree.cli.view.RUN_VIEW_PORT", 0)  # any free port
    out = tmp_path / "run"
    code = main(["run", str(REPO_ROOT / "trees" / "patrol.yaml"), "--out", str(out), "--max-duration", "5",
                 "--view", "--quiet"])
    assert code == 1  # stopped by the duration limit
    captured = capsys.readouterr()
    assert "live viewer at http://127.0.0.1:" in captured.err
    assert (out / "report.html").is_file()
    rows = (out / "poses.jsonl").read_text().splitlines()
    assert len(rows) >= 19  # 5 s at one sample each 0.25 s
