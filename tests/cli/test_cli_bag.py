"""`missiontree bag info|record`: a bag's contents without ROS; bad input exits 2 with one line."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

from missiontree.cli.main import main
from missiontree.paths import REPO_ROOT

BAG = REPO_ROOT / "tests" / "data" / "ros2bag" / "sim_office.mcap"
NO_DECODER = importlib.util.find_spec("mcap_ros2") is None


@pytest.mark.realdata
@pytest.mark.skipif(NO_DECODER, reason="mcap-ros2-support missing: pip install 'missiontree[realdata]'")
def test_info_lists_topics_and_what_the_backend_reads(capsys: pytest.CaptureFixture[str]) -> None:
    """Each topic with its count, then the scans, poses, frames and maps the recorded backend plays."""
    assert main(["bag", "info", str(BAG)]) == 0
    out = capsys.readouterr().out
    assert "/scan: 119" in out and "/tf_static: 1" in out
    assert "scans: 119 over 11.8 s; poses: 239 from tf (map); RGB-D frames: 13; maps: 13" in out


@pytest.mark.skipif(NO_DECODER, reason="mcap-ros2-support missing: pip install 'missiontree[realdata]'")
def test_info_on_a_file_that_is_not_a_bag_exits_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A text file named .mcap: exit 2 and one line naming it."""
    junk = tmp_path / "junk.mcap"
    junk.write_text("hello")
    assert main(["bag", "info", str(junk)]) == 2
    assert "junk.mcap: not a readable ROS 2 MCAP bag" in capsys.readouterr().err


def test_record_refuses_a_bad_rate_or_file_name(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """--max-rate without =HZ, or an --out that is not .mcap, exits 2 before anything is recorded."""
    out = str(tmp_path / "run.mcap")
    assert main(["bag", "record", "--out", out, "--duration", "1", "--max-rate", "/scan"]) == 2
    assert "expected TOPIC=HZ" in capsys.readouterr().err
    assert main(["bag", "record", "--out", str(tmp_path / "run.bag"), "--duration", "1"]) == 2
    assert "expected an .mcap file name" in capsys.readouterr().err
    assert not Path(out).exists()


@pytest.mark.skipif(importlib.util.find_spec("rclpy") is not None, reason="ROS 2 is installed here")
def test_record_without_ros2_says_how_to_install_it(tmp_path: Path,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    """Without rclpy, `bag record` exits 2 naming the ros2 extra."""
    assert main(["bag", "record", "--out", str(tmp_path / "r.mcap"), "--duration", "1"]) == 2
    assert "ros2" in capsys.readouterr().err
