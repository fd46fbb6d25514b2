"""Surface patterns: what the camera paints on objects' side faces, and what it leaves alone."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import ROOM

from missiontree.backends.sim import create_robot
from missiontree.backends.sim.patterns import LABEL_PATTERNS, PATTERNS, paint, pattern_for
from missiontree.errors import WorldFileError

#: One object of every pattern, all the same white, before a camera at (1, 3) looking along +x.
ROW = """\
name: pattern_row
robot:
  profile: turtlebot4
  start: {x: 1.0, y: 3.0, yaw: 0.0}
walls:
  height: 2.5
  polygons:
    - [[0, 0], [8, 0], [8, 6], [0, 6]]
objects:
  - {id: shelf, label: bookshelf, color: white, size: [0.3, 0.9, 1.8], pose: {x: 5.0, y: 5.0}}
  - {id: fridge, label: refrigerator, color: white, size: [0.7, 0.7, 1.8], pose: {x: 5.0, y: 4.0}}
  - {id: tv, label: tv, color: white, size: [1.0, 0.1, 0.6], pose: {x: 5.0, y: 3.0, yaw_deg: 90},
     elevation: 0.3}
  - {id: sofa, label: sofa, color: white, size: [0.8, 1.8, 0.8], pose: {x: 6.5, y: 1.0}}
  - {id: table, label: table, color: white, size: [0.6, 0.9, 0.7], pose: {x: 5.0, y: 1.6}}
  - {id: bottle, label: bottle, color: white, shape: cylinder, size: [0.1, 0.1, 0.3], pose: {x: 3.0, y: 2.4}}
  - {id: umbrella, label: umbrella, color: white, shape: cylinder, size: [0.1, 0.1, 0.9],
     pose: {x: 3.0, y: 3.6}}
  - {id: plant, label: potted plant, color: white, shape: cylinder, size: [0.4, 0.4, 0.9],
     pose: {x: 3.6, y: 4.6}}
  - {id: chair, label: chair, color: white, size: [0.5, 0.5, 1.0], pose: {x: 2.8, y: 1.9}}
"""


def _frame(write_world, text: str, accelerate: bool = True):
    robot = create_robot({"world": write_world(text), "config": {"accelerate": accelerate}})
    frame = robot.rgbd()
    return robot, frame, robot.truth.instance_mask(frame.stamp)


def _pixels(robot, frame, mask, name: str) -> np.ndarray:
    inst = next(i for i, info in robot.truth.instances.items() if info.name == name)
    return frame.color[mask == inst].astype(int)


def test_labels_choose_patterns_and_the_world_file_can_override():
    assert pattern_for("Bookshelf", None) == PATTERNS["shelves"]
    assert pattern_for("refrigerator", None) == PATTERNS["fridge"]
    assert pattern_for("spaceship", None) == PATTERNS["plain"]
    assert pattern_for("bookshelf", "plain") == PATTERNS["plain"]
    assert set(LABEL_PATTERNS.values()) <= set(PATTERNS)


def test_white_bookshelf_and_white_refrigerator_no_longer_look_alike(write_world):
    """Same colour, same size: the shelf shows dark compartments and books, the fridge stays white."""
    robot, frame, mask = _frame(write_world, ROW)
    shelf = _pixels(robot, frame, mask, "shelf")
    fridge = _pixels(robot, frame, mask, "fridge")
    assert len(shelf) > 500 and len(fridge) > 500
    assert (shelf.max(axis=1) < 120).mean() > 0.3           # compartments and books
    assert (fridge.min(axis=1) > 120).mean() > 0.9          # white but for a door gap and handles
    assert (np.abs(fridge - [150, 150, 156]).max(axis=1) < 40).any() or (fridge.max(axis=1) < 120).any()


def test_patterns_change_colour_only(write_world):
    """Depth and the instance mask are the same with every object drawn plain."""
    robot, frame, mask = _frame(write_world, ROW)
    plain = ROW.replace("label:", "pattern: plain, label:")
    assert plain.count("pattern: plain") == 9
    _, frame2, mask2 = _frame(write_world, plain)
    assert np.array_equal(mask, mask2)
    assert np.allclose(frame.depth, frame2.depth, equal_nan=True)
    differs = (frame.color != frame2.color).any(axis=2)
    assert differs.sum() > 2000
    assert not differs[mask <= 1].any()                     # floor, ceiling and walls untouched
    for name in ("shelf", "fridge", "tv", "table", "sofa", "bottle", "umbrella", "plant", "chair"):
        inst = next(i for i, info in robot.truth.instances.items() if info.name == name)
        assert differs[mask == inst].any(), name


def test_numba_and_numpy_paint_alike(write_world):
    pytest.importorskip("numba")
    _, fast, _ = _frame(write_world, ROW, accelerate=True)
    _, slow, _ = _frame(write_world, ROW, accelerate=False)
    gap = np.abs(fast.color.astype(int) - slow.color.astype(int))
    assert gap.max() <= 1
    assert (gap > 0).mean() < 0.001


def test_paint_leaves_a_frame_without_patterned_objects_alone(write_world):
    robot, frame, mask = _frame(write_world, ROOM)
    before = frame.color.copy()
    prims = robot.world.static
    assert prims.pattern is None
    width, height = before.shape[1], before.shape[0]
    out = paint(before, frame.depth, mask, (0.0, 0.0, 0.4), np.ones(width), np.zeros(width), np.zeros(height),
                prims)
    assert np.array_equal(out, frame.color)


def test_unknown_pattern_is_a_clear_world_file_error(write_world):
    text = ROOM + """
objects:
  - {id: shelf, label: bookshelf, pattern: stripes, size: [0.9, 0.3, 1.8], pose: {x: 4.6, y: 3.3}}
"""
    with pytest.raises(WorldFileError, match="pattern"):
        create_robot({"world": write_world(text)})
