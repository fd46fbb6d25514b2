"""Held-out-like test worlds for exploration: a corridor with rooms behind narrow doors, rooms off rooms.

Not the generator's apartments: the kind of building the issue's held-out flat was -- a corridor
1.2 m wide with a door of 0.8-0.9 m into every room, each door near a corner of its room (the room
is not seen from the corridor), and an inner room behind a second door at the far corner, with a
box beside that door. Every room is in the world's ``rooms`` (the truth scores what was seen).
"""

from __future__ import annotations

from typing import Any

WALL = 0.1


def corridor_world(doors: tuple[float, ...] = (0.8, 0.8, 0.9, 0.9, 0.85, 0.8), room_w: float = 3.0,
                   depth: float = 3.5, inner: float = 3.0, corridor: float = 1.2,
                   inner_doors: tuple[float, ...] | None = None) -> dict[str, Any]:
    """A world file dict: rooms on both sides of a corridor, each with an inner room behind it.

    Args:
        doors: Clear width (m) of each room's door from the corridor (one room per door, half on
            each side); the walls are ``WALL`` thick.
        room_w: Width of a room along the corridor (m).
        depth: Depth of a room (m).
        inner: Depth of the inner room behind it (m).
        corridor: Corridor width (m).
        inner_doors: Clear width of each inner room's door (default: the room's door).
    """
    n = len(doors)
    per = (n + 1) // 2
    length = per * room_w
    inner_doors = inner_doors or doors
    segments: list[list[list[float]]] = []
    rooms: list[dict[str, Any]] = [{"name": "corridor", "type": "corridor",
                                    "polygon": [[0, 0], [length, 0], [length, corridor], [0, corridor]]}]
    objects: list[dict[str, Any]] = []
    far = depth + inner
    outline = [[0.0, -far], [length, -far], [length, corridor + far], [0.0, corridor + far]]

    def wall_with_door(y: float, x0: float, x1: float, centre: float, width: float) -> None:
        half = width / 2 + WALL / 2   # the wall's drawn thickness eats into the gap
        segments.append([[x0, y], [centre - half, y]])
        segments.append([[centre + half, y], [x1, y]])

    for side in (0, 1):
        sign = -1.0 if side == 0 else 1.0
        y = 0.0 if side == 0 else corridor
        for k in range(per):
            i = side * per + k
            if i >= n:
                break
            x0, x1 = k * room_w, (k + 1) * room_w
            wall_with_door(y, x0, x1, x0 + 0.6 + doors[i] / 2, doors[i])        # near the room's corner
            y_inner = y + sign * depth
            centre = x1 - 0.6 - inner_doors[i] / 2
            wall_with_door(y_inner, x0, x1, centre, inner_doors[i])            # at the far corner
            if k > 0:
                segments.append([[x0, y], [x0, y + sign * far]])
            a, b = sorted((y, y_inner))
            c, d = sorted((y_inner, y_inner + sign * inner))
            rooms.append({"name": f"room{i}", "type": "office",
                          "polygon": [[x0, a], [x1, a], [x1, b], [x0, b]]})
            rooms.append({"name": f"inner{i}", "type": "bedroom",
                          "polygon": [[x0, c], [x1, c], [x1, d], [x0, d]]})
            objects.append({"label": "box", "size": [0.4, 0.4, 0.5],   # clutter beside the inner door
                            "pose": {"x": centre - inner_doors[i] / 2 - 0.45, "y": y_inner - sign * 0.35,
                                     "yaw": 0.0}})
    return {"name": "corridor_rooms", "robot": {"profile": "turtlebot4",
                                                "start": {"x": 0.6, "y": corridor / 2, "yaw": 0.0}},
            "walls": {"polygons": [outline], "segments": segments}, "rooms": rooms, "objects": objects}
