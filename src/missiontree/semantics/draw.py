"""The scene on a top-down picture: the map, rooms tinted with their names, instances with labels.

:func:`draw_scene` writes ``scene_graph.png`` beside a run's ``scene_graph.json``: the occupancy map
(free white, unknown grey, occupied black), each room tinted and named (type and id), each instance
as a dot in its measured colour with its id, a ring for doubtful ones, and the ``next_to``/``on``
relations as thin lines. +y points up. Pure OpenCV; it draws what the robot believes, not the truth.
"""

from __future__ import annotations

import zlib
from collections.abc import Callable, Sequence
from pathlib import Path

import cv2
import numpy as np

from missiontree.mapping.occupancy import BLOCKED_FROM
from missiontree.semantics.live import LiveScene
from missiontree.types import OccupancyGrid

#: Display colours (BGR) of colour names.
_BGR = {
    "black": (30, 30, 30),
    "grey": (150, 150, 150),
    "white": (235, 235, 235),
    "red": (40, 40, 220),
    "orange": (0, 140, 255),
    "brown": (40, 80, 140),
    "yellow": (0, 220, 230),
    "green": (50, 170, 50),
    "cyan": (210, 200, 0),
    "blue": (220, 90, 30),
    "purple": (160, 50, 140),
    "pink": (180, 120, 250),
    "beige": (170, 210, 230),
}
_SCALE_MAX = 1600


def _tint(name: str) -> tuple[int, int, int]:
    h = zlib.crc32(name.encode())
    return 170 + h % 70, 170 + (h >> 8) % 70, 170 + (h >> 16) % 70


class _Canvas:
    """The map drawn at an integer scale (free white, unknown grey, occupied black), +y up."""

    def __init__(self, grid: OccupancyGrid) -> None:
        data = np.asarray(grid.data)
        self.grid = grid
        self.h, w = data.shape
        self.scale = max(1, min(8, _SCALE_MAX // max(self.h, w, 1)))
        img: np.ndarray = np.full((self.h, w, 3), 255, np.uint8)
        img[data < 0] = (200, 200, 200)
        img[data >= BLOCKED_FROM] = (0, 0, 0)
        size = (w * self.scale, self.h * self.scale)
        self.img = cv2.resize(img[::-1], size, interpolation=cv2.INTER_NEAREST)
        blocked = (data >= BLOCKED_FROM)[::-1].astype(np.uint8)
        walls = cv2.resize(blocked, size, interpolation=cv2.INTER_NEAREST)
        #: Occupied cells at the picture's scale: drawn black again over the rooms' tint.
        self.walls = walls > 0

    def px(self, x: float, y: float) -> tuple[int, int]:
        """The pixel of a map point."""
        col = (x - self.grid.origin.x) / self.grid.resolution
        row = self.h - (y - self.grid.origin.y) / self.grid.resolution
        return int(round(col * self.scale)), int(round(row * self.scale))


def draw_scene(
    grid: OccupancyGrid, scene: LiveScene, path: str | Path, trajectory: Sequence[tuple[float, float]] = ()
) -> Path:
    """Draw the scene over ``grid`` into the PNG at ``path``; return the path."""
    canvas = _Canvas(grid)
    px = canvas.px
    overlay = canvas.img.copy()
    for room in scene.rooms:
        if len(room.polygon) >= 3:
            pts = np.array([px(float(x), float(y)) for x, y in room.polygon], np.int32)
            cv2.fillPoly(overlay, [pts], _tint(room.id))
    img = cv2.addWeighted(overlay, 0.45, canvas.img, 0.55, 0)
    img[canvas.walls] = (0, 0, 0)
    for a, b in zip(trajectory[:-1], trajectory[1:], strict=False):
        cv2.line(img, px(*a), px(*b), (200, 160, 120), 1, cv2.LINE_AA)
    _draw_relations(img, scene, px)
    _draw_instances(img, scene, px, max(3, canvas.scale * 2))
    for room in scene.rooms:
        cx, cy = px(*room.centroid)
        text = f"{room.label} ({room.id})"
        cv2.putText(
            img, text, (cx - 4 * len(text), cy), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (90, 20, 20), 1, cv2.LINE_AA
        )
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(target), img)
    return target


def _draw_relations(img: np.ndarray, scene: LiveScene, px: Callable[[float, float], tuple[int, int]]) -> None:
    """The ``on`` and ``next_to`` relations as thin grey lines between the instances."""
    positions = {inst.id: inst.xy for inst in scene.map}
    for edge in scene.graph.edges:
        source, target = str(edge["source_id"]), str(edge["target_id"])
        if edge["relation"] in ("on", "next_to") and source in positions and target in positions:
            cv2.line(img, px(*positions[source]), px(*positions[target]), (120, 120, 120), 1, cv2.LINE_AA)


def _draw_instances(
    img: np.ndarray, scene: LiveScene, px: Callable[[float, float], tuple[int, int]], radius: int
) -> None:
    """Each instance as a dot in its colour with its id; a red ring around a doubtful one."""
    for inst in scene.map:
        centre = px(*inst.xy)
        cv2.circle(img, centre, radius, _BGR.get(inst.colour, (0, 0, 255)), -1, cv2.LINE_AA)
        cv2.circle(img, centre, radius, (0, 0, 0), 1, cv2.LINE_AA)
        if inst.doubtful:
            cv2.circle(img, centre, radius + 3, (0, 0, 255), 1, cv2.LINE_AA)
        cv2.putText(
            img,
            inst.id,
            (centre[0] + radius + 2, centre[1] + 4),
            cv2.FONT_HERSHEY_SIMPLEX,
            0.35,
            (20, 20, 20),
            1,
            cv2.LINE_AA,
        )
