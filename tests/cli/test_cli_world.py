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


def _text_in_band(image: np.ndarray, rows: slice, cols: slice) -> bool:
    """Whether the band holds dark (text) pixels."""
    return bool((image[rows, cols].max(axis=2) < 160).any())


def test_world_show_numbers_the_grid_in_metres_along_the_top_and_left(tmp_path: Path) -> None:
    """Each whole metre of x is written above the map and each of y left of it; a run picture has neither."""
    from missiontree.backends.sim import create_robot, load_world
    from missiontree.backends.sim.render import _MARGIN, _TITLE_H, _Canvas, draw_topdown

    out = tmp_path / "w.png"
    assert main(["world", "show", "conformance", "--out", str(out)]) == 0
    bounds = load_world("conformance").bounds()
    canvas = _Canvas(bounds)
    plain = tmp_path / "plain.png"
    draw_topdown(create_robot({"world": "conformance"}).scene(), [], plain)
    for image, labelled in ((cv2.imread(str(out)), True), (cv2.imread(str(plain)), False)):
        for x in range(int(np.ceil(bounds[0])), int(np.floor(bounds[2])) + 1):
            px = canvas.px(x, bounds[3])[0]
            top = slice(_TITLE_H + 4, _TITLE_H + _MARGIN - 4)
            assert _text_in_band(image, top, slice(px - 4, px + 5)) == labelled, (x, labelled)
        for y in range(int(np.ceil(bounds[1])), int(np.floor(bounds[3])) + 1):
            py = canvas.px(bounds[0], y)[1]
            left = slice(2, _MARGIN - 4)
            assert _text_in_band(image, slice(py - 4, py + 5), left) == labelled, (y, labelled)


def test_axis_labels_thin_out_on_a_large_map() -> None:
    """Labels are every metre at full scale, every 5 or 10 m when a metre is a few pixels."""
    from missiontree.backends.sim.render import axis_step, axis_ticks

    assert axis_step(60.0, 20.0) == 1
    assert axis_step(6.0, 20.0) == 5
    assert axis_step(1.5, 20.0) == 20
    assert axis_ticks(-0.5, 12.5, 1) == list(range(0, 13))
    assert axis_ticks(-12.0, 31.0, 10) == [-10, 0, 10, 20, 30]
