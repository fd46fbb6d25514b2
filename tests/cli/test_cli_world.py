"""Tests of `missiontree world show`."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from missiontree.cli.main import main


def test_world_show_draws_a_png_with_a_metre_grid(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The picture is written, names the world's size, and has grid lines every metre on the floor."""
    out = tmp_path / "pics" / "world.png"
    assert main(["world", "show", "conformance", "--out", str(out)]) == 0
    assert "conformance:" in capsys.readouterr().out
    image = cv2.imread(str(out))
    assert image is not None and image.shape[0] > 100 and image.shape[1] > 100
    assert main(["world", "show", "generated:4", "--out", str(tmp_path / "g.png")]) == 0
    assert (tmp_path / "g.png").stat().st_size > 1000


def test_world_show_grid_lines_differ_from_a_plain_drawing(tmp_path: Path) -> None:
    """The metre grid is really drawn: the picture differs from the same world drawn without it."""
    from missiontree.backends.sim import create_robot
    from missiontree.backends.sim.render import draw_topdown

    out = tmp_path / "w.png"
    assert main(["world", "show", "conformance", "--out", str(out)]) == 0
    robot = create_robot({"world": "conformance"})
    plain = tmp_path / "plain.png"
    draw_topdown(robot.scene(), [], plain)
    a, b = cv2.imread(str(out)), cv2.imread(str(plain))
    assert a.shape == b.shape and np.count_nonzero(np.any(a != b, axis=2)) > 500


def test_world_show_reports_a_broken_world_with_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A broken world file prints its located problems and exits 2, drawing nothing."""
    world = tmp_path / "w.yaml"
    world.write_text("name: w\nrobot: {start: {x: 1, y: .nan}}\nwalls: {segments: [[[0, 0], [4, 0]]]}\n")
    assert main(["world", "show", str(world), "--out", str(tmp_path / "w.png")]) == 2
    assert f"{world}:2:" in capsys.readouterr().err
    assert not (tmp_path / "w.png").exists()
