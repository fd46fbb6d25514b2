"""The top-down picture of a simulated run, drawn with OpenCV from a plain :class:`Scene`.

Map (free, walls, occupied cells), rooms with their names, objects in their colours, people's
tracks up to now, the robot's true trajectory and pose, the navigation goals sent, the learned
map in unknown-map runs (cells not yet mapped greyed), and the run's markers (goals, detections,
alarms, anything else) with their labels placed so that they do not overlap. A legend under the
map shows only what the picture contains, each entry drawn with its own symbol and colour; a
metre scale sits in the lower left. +y points up. With ``metre_grid`` (``missiontree world show``)
a light line is drawn every metre and numbered in metres along the top (x) and left (y) edges.

The scene is a value (what to draw), built by the simulator; this module knows nothing of the
robot or the world objects.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from missiontree.mapping.occupancy import BLOCKED_FROM
from missiontree.types import Marker, OccupancyGrid, Pose2D

PIXELS_PER_METRE = 60
MAX_SIDE = 1800
_MARGIN = 30
_TITLE_H = 28
_LEGEND_H = 48
_ROOM_TINTS = [(235, 225, 250), (225, 245, 230), (250, 240, 220), (225, 235, 250), (245, 230, 235)]
# BGR; people are teal so that they never read as the robot (blue)
ROBOT_BGR = (200, 90, 20)
PEOPLE_BGR = (130, 130, 0)
OTHER_ROBOT_BGR = (150, 60, 160)   # the other robots of a fleet
GOAL_BGR = (40, 160, 40)
_MARKER_BGR = {"goal": GOAL_BGR, "detection": (0, 140, 255), "alarm": (30, 30, 220)}
_OTHER_BGR = (200, 0, 200)
_UNMAPPED_BGR = (190, 190, 190)
#: What ``bumps`` means, for the picture and run summaries.
BUMPS_MEANING = ("contacts: times the robot's body touched a wall or object (the simulator refused the "
                 "move instead of letting it pass through); refused_moves: the physics steps refused")


@dataclass(frozen=True)
class SceneObject:
    """An object as drawn: id, RGB colour, footprint polygon (N, 2) and the point under which its id goes."""

    id: str
    rgb: tuple[int, int, int]
    footprint: np.ndarray
    label_at: tuple[float, float]


@dataclass(frozen=True)
class SceneRobot:
    """Another robot of a fleet as drawn: name, true pose now, body radius and path (t, x, y) so far."""

    name: str
    pose: Pose2D
    radius: float
    trajectory: list[tuple[float, float, float]] = field(default_factory=list)


@dataclass(frozen=True)
class ScenePerson:
    """A person as drawn: id, track up to now (N, 2) and where they are now (None when away)."""

    id: str
    track: np.ndarray
    position: tuple[float, float] | None


@dataclass(frozen=True)
class SceneRoom:
    """A room as drawn: name, type and polygon (N, 2)."""

    name: str
    type: str
    polygon: np.ndarray


@dataclass(frozen=True)
class Scene:
    """Everything the top-down picture shows, as plain values."""

    name: str
    bounds: tuple[float, float, float, float]   # xmin, ymin, xmax, ymax (m)
    grid: OccupancyGrid
    now: float
    seed: int
    bumps: int                                  # contacts: times the body touched something
    robot_pose: Pose2D
    robot_radius: float
    rooms: list[SceneRoom] = field(default_factory=list)
    walls: list[tuple[float, float, float, float]] = field(default_factory=list)
    objects: list[SceneObject] = field(default_factory=list)
    people: list[ScenePerson] = field(default_factory=list)
    trajectory: list[tuple[float, float, float]] = field(default_factory=list)  # (t, x, y)
    goals: list[Pose2D] = field(default_factory=list)
    learned: OccupancyGrid | None = None
    others: list[SceneRobot] = field(default_factory=list)   # the other robots of a fleet


class _Canvas:
    def __init__(self, bounds: tuple[float, float, float, float]) -> None:
        xmin, ymin, xmax, ymax = bounds
        span = max(xmax - xmin, ymax - ymin, 1e-3)
        self.scale = min(PIXELS_PER_METRE, (MAX_SIDE - 2 * _MARGIN) / span)
        self.xmin, self.ymin, self.ymax = xmin, ymin, ymax
        w = max(int((xmax - xmin) * self.scale) + 2 * _MARGIN, 560)
        self.map_bottom = int((ymax - ymin) * self.scale) + 2 * _MARGIN + _TITLE_H
        self.image = np.full((self.map_bottom + _LEGEND_H, w, 3), 255, np.uint8)
        self.labels: list[tuple[int, int, int, int]] = []   # boxes of labels and symbols placed so far
        self.texts: list[tuple[int, int, int, int]] = []    # boxes of the labels alone

    def px(self, x: float, y: float) -> tuple[int, int]:
        return (int(round(_MARGIN + (x - self.xmin) * self.scale)),
                int(round(_MARGIN + _TITLE_H + (self.ymax - y) * self.scale)))

    def poly(self, points: np.ndarray) -> np.ndarray:
        return np.array([self.px(float(x), float(y)) for x, y in points], np.int32)

    def block(self, centre: tuple[int, int], radius: int) -> None:
        """Keep labels off a symbol drawn at ``centre``."""
        self.labels.append((centre[0] - radius, centre[1] - radius, centre[0] + radius, centre[1] + radius))

    def label(self, text: str, anchor: tuple[int, int], bgr: tuple[int, ...], scale: float = 0.38) -> bool:
        """Put ``text`` near ``anchor`` where it overlaps no label placed before; False when nowhere fits."""
        (w, h), base = cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, scale, 1)
        ax, ay = anchor
        candidates = [(ax + 8, ay - 6), (ax + 8, ay + h // 2), (ax + 8, ay + h + 6), (ax - w - 8, ay - 6),
                      (ax - w - 8, ay + h + 6),
                      (ax - w // 2, ay - 12), (ax - w // 2, ay + h + 12)]
        candidates += [(ax + 8, ay - 6 - k * (h + 4)) for k in (2, 3)] + [(ax + 8, ay + h + 6 + k * (h + 4))
                                                                         for k in (2, 3)]
        H, W = self.image.shape[:2]
        for x, y in candidates:
            box = (x - 1, y - h - 1, x + w + 1, y + base + 1)
            if box[0] < 0 or box[1] < _TITLE_H or box[2] > W or box[3] > self.map_bottom:
                continue
            if any(not (box[2] <= b[0] or b[2] <= box[0] or box[3] <= b[1] or b[3] <= box[1])
                   for b in self.labels):
                continue
            self.labels.append(box)
            self.texts.append(box)
            cv2.putText(self.image, text, (x, y), cv2.FONT_HERSHEY_SIMPLEX, scale, bgr, 1, cv2.LINE_AA)
            return True
        return False


def draw_topdown(scene: Scene, markers: list[Marker], path: Path,
                 metre_grid: bool = False) -> list[tuple[int, int, int, int]]:
    """Draw ``scene`` and the run's ``markers`` into the PNG at ``path`` (with a metre grid when asked).

    Returns the pixel boxes (x0, y0, x1, y1) of the labels placed; no two overlap, nor any symbol.
    """
    canvas = _Canvas(scene.bounds)
    img = canvas.image
    _shade_cells(canvas, scene.grid, scene.grid.data < 0, lambda region: (215, 215, 215))
    for i, room in enumerate(scene.rooms):
        overlay = img.copy()
        cv2.fillPoly(overlay, [canvas.poly(room.polygon)], _ROOM_TINTS[i % len(_ROOM_TINTS)])
        cv2.addWeighted(overlay, 0.5, img, 0.5, 0, dst=img)
    if metre_grid:
        _draw_metre_grid(canvas, scene.bounds)
    _shade_cells(canvas, scene.grid, scene.grid.data >= BLOCKED_FROM,
                 lambda region: (region * 0.55 + 60).astype(np.uint8))
    for x1, y1, x2, y2 in scene.walls:
        cv2.line(img, canvas.px(x1, y1), canvas.px(x2, y2), (60, 60, 60), 2, cv2.LINE_AA)
    if scene.learned is not None:
        _draw_learned(canvas, scene.learned)
    for room in scene.rooms:
        cx, cy = room.polygon.mean(axis=0)
        text = f"{room.name} ({room.type})"
        (w, h), _ = cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, 0.45, 1)
        p = canvas.px(cx, cy)
        canvas.label(text, (p[0] - w // 2 - 8, p[1] + h // 2 + 6), (120, 90, 90), 0.45)
    for obj in scene.objects:
        bgr = tuple(int(c) for c in obj.rgb[::-1])
        pts = canvas.poly(obj.footprint)
        cv2.fillPoly(img, [pts], bgr, cv2.LINE_AA)
        cv2.polylines(img, [pts], True, (40, 40, 40), 1, cv2.LINE_AA)
    _draw_people(canvas, scene)
    _draw_robot(canvas, scene)
    for goal in scene.goals:
        cv2.drawMarker(img, canvas.px(goal.x, goal.y), GOAL_BGR, cv2.MARKER_TILTED_CROSS, 12, 2)
    kinds: set[str] = set()
    labelled: set[tuple[str, int, int]] = set()
    for marker in markers:
        kind = marker.kind if marker.kind in _MARKER_BGR else "other"
        kinds.add(kind)
        colour = _MARKER_BGR.get(marker.kind, _OTHER_BGR)
        p = canvas.px(marker.x, marker.y)
        _marker_symbol(img, kind, p, colour)
        canvas.block(p, 8)
        key = (marker.label, p[0] // 12, p[1] // 12)  # one label for repeats at the same spot
        if marker.label and key not in labelled:
            labelled.add(key)
            canvas.label(marker.label, p, colour)
    for obj in scene.objects:
        canvas.label(obj.id, canvas.px(*obj.label_at), (70, 70, 70), 0.3)
    title = (f"{scene.name}   t = {scene.now:.1f} s   seed {scene.seed}   contacts {scene.bumps} "
             "(the body touched something; where: summary.json 'bumps')")
    cv2.putText(img, title, (8, 19), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (30, 30, 30), 1, cv2.LINE_AA)
    _draw_scale(canvas, scene.bounds)
    _draw_legend(canvas, scene, kinds)
    path.parent.mkdir(parents=True, exist_ok=True)
    if not cv2.imwrite(str(path), img):
        raise OSError(f"could not write {path}")
    return list(canvas.texts)


def _marker_symbol(img: np.ndarray, kind: str, p: tuple[int, int], colour: tuple[int, ...]) -> None:
    if kind == "alarm":
        cv2.drawMarker(img, p, colour, cv2.MARKER_TRIANGLE_UP, 14, 2)
    elif kind == "goal":
        cv2.drawMarker(img, p, colour, cv2.MARKER_CROSS, 14, 2)
    else:
        cv2.circle(img, p, 6, colour, 2, cv2.LINE_AA)


def _cells_region(canvas: _Canvas, grid: OccupancyGrid,
                  values: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """The canvas region under the grid and the grid ``values`` resized onto it (row 0 at the top)."""
    h, w = values.shape
    x0, y1 = canvas.px(grid.origin.x, grid.origin.y + h * grid.resolution)
    x1, y0 = canvas.px(grid.origin.x + w * grid.resolution, grid.origin.y)
    cx0, cy1 = max(x0, 0), max(y1, 0)
    cx1, cy0 = min(x1, canvas.image.shape[1]), min(y0, canvas.map_bottom)
    if cx1 <= cx0 or cy0 <= cy1 or x1 <= x0 or y0 <= y1:
        return None
    big = cv2.resize(np.flipud(values).astype(np.uint8), (x1 - x0, y0 - y1), interpolation=cv2.INTER_NEAREST)
    big = big[cy1 - y1: cy0 - y1, cx0 - x0: cx1 - x0]
    region = canvas.image[cy1:cy0, cx0:cx1]
    hh, ww = min(region.shape[0], big.shape[0]), min(region.shape[1], big.shape[1])
    return region[:hh, :ww], big[:hh, :ww]


def _shade_cells(canvas: _Canvas, grid: OccupancyGrid, mask: np.ndarray, colour) -> None:  # noqa: ANN001
    found = _cells_region(canvas, grid, mask)
    if found is not None:
        region, big = found
        sel = big > 0
        region[sel] = colour(region[sel])


def _draw_learned(canvas: _Canvas, learned: OccupancyGrid) -> None:
    """Grey what the robot has not mapped yet; outline what it mapped as occupied."""
    found = _cells_region(canvas, learned, learned.data < 0)
    if found is not None:
        region, big = found
        sel = big > 0
        region[sel] = (region[sel] * 0.45 + np.array(_UNMAPPED_BGR) * 0.55).astype(np.uint8)
    found = _cells_region(canvas, learned, learned.data >= BLOCKED_FROM)
    if found is not None:
        region, big = found
        region[big > 0] = (40, 40, 40)


def _draw_metre_grid(canvas: _Canvas, bounds: tuple[float, float, float, float]) -> None:
    """A light line every metre, with its coordinate (m) above the map (x) and left of it (y)."""
    xmin, ymin, xmax, ymax = bounds
    for x in range(math.ceil(xmin), math.floor(xmax) + 1):
        cv2.line(canvas.image, canvas.px(x, ymin), canvas.px(x, ymax), (225, 225, 225), 1)
    for y in range(math.ceil(ymin), math.floor(ymax) + 1):
        cv2.line(canvas.image, canvas.px(xmin, y), canvas.px(xmax, y), (225, 225, 225), 1)
    _draw_axis_labels(canvas, bounds)


#: Size of the axis labels' text (OpenCV font scale) and their colour (BGR).
_AXIS_TEXT = 0.35
_AXIS_BGR = (90, 90, 90)


def axis_step(span_px_per_metre: float, min_gap_px: float) -> int:
    """The label step (m): the smallest of 1, 2, 5, 10, 20, 50… whose labels are ``min_gap_px`` apart."""
    for magnitude in (1, 10, 100, 1000):
        for step in (1, 2, 5):
            if step * magnitude * span_px_per_metre >= min_gap_px:
                return step * magnitude
    return 10000


def axis_ticks(low: float, high: float, step: int) -> list[int]:
    """Whole-metre coordinates from ``low`` to ``high`` that are multiples of ``step``."""
    first = math.ceil(low / step) * step
    return list(range(first, math.floor(high) + 1, step))


def _draw_axis_labels(canvas: _Canvas, bounds: tuple[float, float, float, float]) -> None:
    """Number the grid lines: x along the top margin, y along the left one, "m" in the corner between."""
    xmin, ymin, xmax, ymax = bounds
    img, font = canvas.image, cv2.FONT_HERSHEY_SIMPLEX
    widest = max(cv2.getTextSize(f"{v:g}", font, _AXIS_TEXT, 1)[0][0]
                 for v in (math.floor(xmin), math.ceil(xmax), math.floor(ymin), math.ceil(ymax)))
    top = _TITLE_H + _MARGIN - 7              # baseline of the x labels
    for x in axis_ticks(xmin, xmax, axis_step(canvas.scale, widest + 8)):
        (w, h), base = cv2.getTextSize(f"{x:g}", font, _AXIS_TEXT, 1)
        px = canvas.px(x, ymax)[0] - w // 2
        cv2.putText(img, f"{x:g}", (px, top), font, _AXIS_TEXT, _AXIS_BGR, 1, cv2.LINE_AA)
        canvas.labels.append((px - 1, top - h - 1, px + w + 1, top + base + 1))
    for y in axis_ticks(ymin, ymax, axis_step(canvas.scale, 16)):
        (w, h), base = cv2.getTextSize(f"{y:g}", font, _AXIS_TEXT, 1)
        px, py = _MARGIN - 4 - w, canvas.px(xmin, y)[1] + h // 2
        cv2.putText(img, f"{y:g}", (max(px, 1), py), font, _AXIS_TEXT, _AXIS_BGR, 1, cv2.LINE_AA)
        canvas.labels.append((max(px, 1) - 1, py - h - 1, _MARGIN - 3, py + base + 1))
    cv2.putText(img, "m", (6, top), font, _AXIS_TEXT, _AXIS_BGR, 1, cv2.LINE_AA)


def _draw_scale(canvas: _Canvas, bounds: tuple[float, float, float, float]) -> None:
    """A scale bar of a round number of metres (about a fifth of the map's width) in the lower left."""
    xmin, _, xmax, _ = bounds
    target = max((xmax - xmin) / 5.0, 0.1)
    metres = min((m for m in (0.5, 1, 2, 5, 10, 20, 50, 100, 200) if m >= target * 0.5), default=1)
    x0, y = _MARGIN, canvas.map_bottom - 10
    x1 = x0 + int(round(metres * canvas.scale))
    img = canvas.image
    cv2.rectangle(img, (x0 - 4, y - 18), (x1 + 50, y + 5), (255, 255, 255), -1)
    cv2.line(img, (x0, y), (x1, y), (20, 20, 20), 2)
    for x in (x0, x1):
        cv2.line(img, (x, y - 5), (x, y + 3), (20, 20, 20), 2)
    text = f"{metres:g} m"
    cv2.putText(img, text, (x1 + 6, y + 4), cv2.FONT_HERSHEY_SIMPLEX, 0.42, (20, 20, 20), 1, cv2.LINE_AA)


def _draw_legend(canvas: _Canvas, scene: Scene, kinds: set[str]) -> None:
    """One entry per thing the picture shows, each with its own symbol."""
    entries: list[tuple[str, str, tuple[int, ...]]] = [("robot", "robot and its path", ROBOT_BGR)]
    if scene.goals:
        entries.append(("goal_sent", "navigation goals sent", GOAL_BGR))
    if scene.people:
        entries.append(("person", "people and their tracks", PEOPLE_BGR))
    names = {"goal": "goal markers", "detection": "detections", "alarm": "alarms", "other": "other markers"}
    for kind in ("goal", "detection", "alarm", "other"):
        if kind in kinds:
            entries.append((kind, names[kind], _MARKER_BGR.get(kind, _OTHER_BGR)))
    if scene.learned is not None:
        entries.append(("unmapped", "not mapped yet", _UNMAPPED_BGR))
    img = canvas.image
    x, y = 12, canvas.map_bottom + 18
    for kind, text, colour in entries:
        (w, _), _ = cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, 0.42, 1)
        if x + 22 + w > img.shape[1] - 8:
            x, y = 12, y + 20
        p = (x + 7, y - 4)
        if kind == "robot":
            cv2.circle(img, p, 6, colour, 2, cv2.LINE_AA)
        elif kind == "goal_sent":
            cv2.drawMarker(img, p, colour, cv2.MARKER_TILTED_CROSS, 10, 2)
        elif kind == "person":
            cv2.circle(img, p, 5, colour, -1, cv2.LINE_AA)
        elif kind == "unmapped":
            cv2.rectangle(img, (p[0] - 6, p[1] - 6), (p[0] + 6, p[1] + 6), colour, -1)
        else:
            _marker_symbol(img, kind, p, colour)
        cv2.putText(img, text, (x + 18, y), cv2.FONT_HERSHEY_SIMPLEX, 0.42, (40, 40, 40), 1, cv2.LINE_AA)
        x += 22 + w + 16


def _draw_people(canvas: _Canvas, scene: Scene) -> None:
    for person in scene.people:
        if len(person.track) > 1:
            cv2.polylines(canvas.image, [canvas.poly(person.track)], False, PEOPLE_BGR, 1, cv2.LINE_AA)
        if person.position is not None:
            p = canvas.px(*person.position)
            r = max(3, int(0.22 * canvas.scale))
            cv2.circle(canvas.image, p, r, PEOPLE_BGR, -1, cv2.LINE_AA)
            canvas.block(p, r + 1)
    for person in scene.people:
        if person.position is not None:
            p = canvas.px(*person.position)
            canvas.label(person.id, (p[0] + max(3, int(0.22 * canvas.scale)) - 4, p[1]), PEOPLE_BGR)


def _draw_other_robots(canvas: _Canvas, scene: Scene) -> None:
    """The other robots of a fleet: thin paths, their bodies and headings, their names."""
    img = canvas.image
    for other in scene.others:
        if len(other.trajectory) > 1:
            pts = np.array([canvas.px(x, y) for _, x, y in other.trajectory], np.int32)
            cv2.polylines(img, [pts], False, OTHER_ROBOT_BGR, 1, cv2.LINE_AA)
        p = canvas.px(other.pose.x, other.pose.y)
        r = max(3, int(other.radius * canvas.scale))
        cv2.circle(img, p, r, OTHER_ROBOT_BGR, 2, cv2.LINE_AA)
        yaw = other.pose.yaw
        tip = canvas.px(other.pose.x + 0.3 * math.cos(yaw), other.pose.y + 0.3 * math.sin(yaw))
        cv2.line(img, p, tip, OTHER_ROBOT_BGR, 2, cv2.LINE_AA)
        canvas.block(p, r + 2)
        canvas.label(other.name, p, OTHER_ROBOT_BGR)


def _draw_robot(canvas: _Canvas, scene: Scene) -> None:
    _draw_other_robots(canvas, scene)   # under the robot's own path and body
    img = canvas.image
    if len(scene.trajectory) > 1:
        pts = np.array([canvas.px(x, y) for _, x, y in scene.trajectory], np.int32)
        cv2.polylines(img, [pts], False, ROBOT_BGR, 2, cv2.LINE_AA)
    pose = scene.robot_pose
    p = canvas.px(pose.x, pose.y)
    r = max(3, int(scene.robot_radius * canvas.scale))
    cv2.circle(img, p, r, ROBOT_BGR, 2, cv2.LINE_AA)
    tip = canvas.px(pose.x + 0.35 * math.cos(pose.yaw), pose.y + 0.35 * math.sin(pose.yaw))
    cv2.line(img, p, tip, ROBOT_BGR, 2, cv2.LINE_AA)
    canvas.block(p, r + 2)
