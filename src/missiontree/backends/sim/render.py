"""The top-down picture of a simulated run, drawn with OpenCV.

Map (free, walls, occupied cells), rooms with their names, objects in their colours, people's
tracks up to now, the robot's true trajectory and pose, the navigation goals sent, and the run's
markers (goals, detections, alarms, anything else) with their labels. +y points up.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING

import cv2
import numpy as np

from missiontree.types import Marker

if TYPE_CHECKING:
    from missiontree.backends.sim.robot import SimRobot

PIXELS_PER_METRE = 60
MAX_SIDE = 1800
_MARGIN = 30
_LEGEND_H = 28
_ROOM_TINTS = [(235, 225, 250), (225, 245, 230), (250, 240, 220), (225, 235, 250), (245, 230, 235)]
_MARKER_BGR = {"goal": (40, 160, 40), "detection": (0, 140, 255), "alarm": (30, 30, 220)}


class _Canvas:
    def __init__(self, bounds: tuple[float, float, float, float]) -> None:
        xmin, ymin, xmax, ymax = bounds
        span = max(xmax - xmin, ymax - ymin, 1e-3)
        self.scale = min(PIXELS_PER_METRE, (MAX_SIDE - 2 * _MARGIN) / span)
        self.xmin, self.ymax = xmin, ymax
        w = int((xmax - xmin) * self.scale) + 2 * _MARGIN
        h = int((ymax - ymin) * self.scale) + 2 * _MARGIN + _LEGEND_H
        self.image = np.full((h, w, 3), 255, np.uint8)

    def px(self, x: float, y: float) -> tuple[int, int]:
        return (int(round(_MARGIN + (x - self.xmin) * self.scale)),
                int(round(_MARGIN + _LEGEND_H + (self.ymax - y) * self.scale)))

    def poly(self, points: np.ndarray) -> np.ndarray:
        return np.array([self.px(float(x), float(y)) for x, y in points], np.int32)


def draw_topdown(robot: SimRobot, markers: list[Marker], path: Path) -> None:
    """Draw ``robot``'s world and run so far into the PNG at ``path``."""
    world = robot.world
    canvas = _Canvas(world.bounds())
    img = canvas.image
    _draw_grid(canvas, robot)
    for i, room in enumerate(world.rooms):
        overlay = img.copy()
        cv2.fillPoly(overlay, [canvas.poly(room.polygon)], _ROOM_TINTS[i % len(_ROOM_TINTS)])
        cv2.addWeighted(overlay, 0.5, img, 0.5, 0, dst=img)
    _draw_grid_walls(canvas, robot)
    for x1, y1, x2, y2 in world.wall_segments:
        cv2.line(img, canvas.px(x1, y1), canvas.px(x2, y2), (60, 60, 60), 2, cv2.LINE_AA)
    for room in world.rooms:
        cx, cy = room.polygon.mean(axis=0)
        _text(img, f"{room.name} ({room.type})", canvas.px(cx, cy), (120, 90, 90), 0.45, center=True)
    for obj in world.objects:
        bgr = tuple(int(c) for c in obj.rgb[::-1])
        pts = canvas.poly(obj.footprint())
        cv2.fillPoly(img, [pts], bgr, cv2.LINE_AA)
        cv2.polylines(img, [pts], True, (40, 40, 40), 1, cv2.LINE_AA)
        _text(img, obj.id, canvas.px(obj.pose.x, obj.pose.y - obj.size[1] / 2 - 0.12), (70, 70, 70), 0.3,
              center=True)
    _draw_people(canvas, robot)
    _draw_robot(canvas, robot)
    for goal in robot.goals:
        p = canvas.px(goal.x, goal.y)
        cv2.drawMarker(img, p, (40, 160, 40), cv2.MARKER_TILTED_CROSS, 12, 2)
    for marker in markers:
        colour = _MARKER_BGR.get(marker.kind, (200, 0, 200))
        p = canvas.px(marker.x, marker.y)
        if marker.kind == "alarm":
            cv2.drawMarker(img, p, colour, cv2.MARKER_TRIANGLE_UP, 14, 2)
        elif marker.kind == "goal":
            cv2.drawMarker(img, p, colour, cv2.MARKER_CROSS, 14, 2)
        else:
            cv2.circle(img, p, 6, colour, 2, cv2.LINE_AA)
        if marker.label:
            _text(img, marker.label, (p[0] + 8, p[1] - 6), colour, 0.38)
    title = (f"{world.name}  t={robot.now():.1f} s  seed={robot.seed}  bumps={robot.bumps}   "
             "blue: robot  green x: goals  orange: detections  red: alarms  thin: people")
    _text(img, title, (8, 18), (30, 30, 30), 0.45)
    path.parent.mkdir(parents=True, exist_ok=True)
    if not cv2.imwrite(str(path), img):
        raise OSError(f"could not write {path}")


def _cells_region(canvas: _Canvas, robot: SimRobot,
                  values: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """The canvas region under the grid and the grid ``values`` resized onto it (row 0 at the top)."""
    grid = robot.world.grid
    h, w = values.shape
    x0, y1 = canvas.px(grid.origin.x, grid.origin.y + h * grid.resolution)
    x1, y0 = canvas.px(grid.origin.x + w * grid.resolution, grid.origin.y)
    x0, y1 = max(x0, 0), max(y1, 0)
    if x1 <= x0 or y0 <= y1:
        return None
    big = cv2.resize(np.flipud(values).astype(np.uint8), (x1 - x0, y0 - y1), interpolation=cv2.INTER_NEAREST)
    region = canvas.image[y1:y0, x0:x1]
    hh, ww = min(region.shape[0], big.shape[0]), min(region.shape[1], big.shape[1])
    return region[:hh, :ww], big[:hh, :ww]


def _draw_grid(canvas: _Canvas, robot: SimRobot) -> None:
    """Grey out unknown cells (maps from map_server have them)."""
    found = _cells_region(canvas, robot, robot.world.grid.data < 0)
    if found is not None:
        region, mask = found
        region[mask > 0] = (215, 215, 215)


def _draw_grid_walls(canvas: _Canvas, robot: SimRobot) -> None:
    """Shade occupied cells (walls as drawn thick, obstacles) under the exact geometry."""
    found = _cells_region(canvas, robot, robot.world.grid.data >= 50)
    if found is not None:
        region, mask = found
        region[mask > 0] = (region[mask > 0] * 0.55 + 60).astype(np.uint8)


def _draw_people(canvas: _Canvas, robot: SimRobot) -> None:
    now = robot.now()
    for person in robot.world.crowd.people:
        bgr = tuple(int(c) for c in person.spec.shirt_rgb[::-1])
        times = np.arange(0.0, now + 1e-9, 0.2) if now > 0 else np.array([0.0])
        pts = [canvas.px(s.x, s.y) for s in (person.state_at(float(t)) for t in times) if s.present]
        if len(pts) > 1:
            cv2.polylines(canvas.image, [np.array(pts, np.int32)], False, bgr, 1, cv2.LINE_AA)
        state = person.state_at(now)
        if state.present:
            p = canvas.px(state.x, state.y)
            cv2.circle(canvas.image, p, max(3, int(0.22 * canvas.scale)), bgr, -1, cv2.LINE_AA)
            _text(canvas.image, person.id, (p[0] + 8, p[1] + 4), bgr, 0.38)


def _draw_robot(canvas: _Canvas, robot: SimRobot) -> None:
    img = canvas.image
    if len(robot.trajectory) > 1:
        pts = np.array([canvas.px(x, y) for _, x, y in robot.trajectory], np.int32)
        cv2.polylines(img, [pts], False, (200, 90, 20), 2, cv2.LINE_AA)
    pose = robot.true_pose
    p = canvas.px(pose.x, pose.y)
    r = max(3, int(robot.profile.body.radius * canvas.scale))
    cv2.circle(img, p, r, (200, 90, 20), 2, cv2.LINE_AA)
    tip = canvas.px(pose.x + 0.35 * math.cos(pose.yaw), pose.y + 0.35 * math.sin(pose.yaw))
    cv2.line(img, p, tip, (200, 90, 20), 2, cv2.LINE_AA)


def _text(img: np.ndarray, text: str, org: tuple[int, int], bgr: tuple[int, ...], scale: float,
          center: bool = False) -> None:
    if center:
        (w, h), _ = cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, scale, 1)
        org = (org[0] - w // 2, org[1] + h // 2)
    cv2.putText(img, text, org, cv2.FONT_HERSHEY_SIMPLEX, scale, bgr, 1, cv2.LINE_AA)
