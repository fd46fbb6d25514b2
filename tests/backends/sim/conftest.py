"""Helpers for the simulator tests: small world files written on the fly."""

from __future__ import annotations

import textwrap
from collections.abc import Callable
from pathlib import Path

import pytest

ROOM = """\
name: box_room
robot:
  profile: turtlebot4
  start: {x: 2.0, y: 1.5, yaw: 0.0}
walls:
  height: 2.5
  polygons:
    - [[0, 0], [6, 0], [6, 4], [0, 4]]
"""


@pytest.fixture
def write_world(tmp_path: Path) -> Callable[[str], Path]:
    """Write a world file (dedented text) into a temporary folder and return its path."""

    def write(text: str, name: str = "world.yaml") -> Path:
        path = tmp_path / name
        path.write_text(textwrap.dedent(text))
        return path

    return write
