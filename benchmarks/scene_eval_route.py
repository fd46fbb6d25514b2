"""The scene-graph benchmark's scripted parts: the dynamic phase's route and the evaluator's changes.

The route (:func:`viewpoints`, :func:`revisit_points`) reads the robot's own learned map and graph;
the changes (:func:`move_object`, :func:`remove_object`, :func:`add_object`, :func:`free_spot`) are
the evaluator's hand on the simulator's world, never seen by the robot but through its camera.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from missiontree.backends.sim.raycast import BOX, CYLINDER, Primitives
from missiontree.backends.sim.schema import ObjectSpec
from missiontree.backends.sim.world import InstanceInfo, World, _make_object
from missiontree.semantics.rooms import segment_rooms
from missiontree.types import Pose2D

COVER_RADIUS = 3.0
#: Every free cell beside a wall or furniture (where objects stand) gets a viewpoint within this many
#: metres with a clear line of sight on the map, when one exists: the detector finds a cup from about
#: 14 pixels, 1.8 m away (see :func:`surface_viewpoints`).
SURFACE_RADIUS = 2.0
#: A cell is beside a wall or furniture when it lies this close to an obstacle of the map, metres.
SURFACE_BAND = 0.35
#: Greedy cover stops when a new viewpoint would see fewer uncovered surface cells than this.
SURFACE_MIN_GAIN = 4
#: The dynamic phase's pass adds a viewpoint this far (min, best, max) from each known instance no
#: viewpoint of the route is within REVISIT_MAX of.
REVISIT_MIN, REVISIT_BEST, REVISIT_MAX = 0.9, 1.5, 2.2


# -- the robot's route (from its map only) ---------------------------------------------------------


def viewpoints(robot: Any) -> list[tuple[float, float]]:
    """Free points with room to turn, spread over each segmented room, in a nearest-neighbour tour."""
    import cv2

    grid = robot.occupancy()
    start = robot.pose().pose
    seg = segment_rooms(grid, inside=(start.x, start.y))
    free = (grid.data >= 0) & (grid.data < 50)
    clearance = cv2.distanceTransform(free.astype(np.uint8), cv2.DIST_L2, 5) * grid.resolution
    points: list[tuple[float, float]] = []
    for label, room in enumerate(seg.rooms, start=1):
        ok = (seg.labels == label) & (clearance >= 0.45)
        rows, cols = np.nonzero(ok)
        if not len(rows):
            continue
        xy = np.stack(
            [grid.origin.x + (cols + 0.5) * grid.resolution, grid.origin.y + (rows + 0.5) * grid.resolution],
            axis=1,
        )
        wanted = 1 if room.area < 25 else 2
        first = int(np.argmax(clearance[rows, cols]))
        chosen = [xy[first]]
        while len(chosen) < wanted:
            d = np.min(np.linalg.norm(xy[:, None, :] - np.array(chosen)[None], axis=2), axis=1)
            if d.max() < 2.5:
                break
            chosen.append(xy[int(np.argmax(d))])
        points += [(float(p[0]), float(p[1])) for p in chosen]
    # then cover what the rooms missed (a room the segmentation joined to another): no free spot with
    # room to turn farther than COVER_RADIUS from a viewpoint
    rows, cols = np.nonzero(free & (clearance >= 0.45) & (seg.labels > 0))
    if len(rows):
        every = np.stack(
            [grid.origin.x + (cols + 0.5) * grid.resolution, grid.origin.y + (rows + 0.5) * grid.resolution],
            axis=1,
        )[::7]
        while True:
            chosen_xy = np.array(points) if points else np.array([[start.x, start.y]])
            d = np.min(np.linalg.norm(every[:, None, :] - chosen_xy[None], axis=2), axis=1)
            if d.max() <= COVER_RADIUS:
                break
            far = every[int(np.argmax(d))]
            points.append((float(far[0]), float(far[1])))
    points += surface_viewpoints(grid, (seg.labels > 0) & free, clearance, points)
    tour, here = [], (start.x, start.y)
    while points:
        nxt = min(points, key=lambda p: math.hypot(p[0] - here[0], p[1] - here[1]))
        points.remove(nxt)
        tour.append(nxt)
        here = nxt
    return tour


def surface_viewpoints(
    grid: Any, inside: np.ndarray, clearance: np.ndarray, chosen: list[tuple[float, float]]
) -> list[tuple[float, float]]:
    """Viewpoints to add so the camera comes near every surface objects may stand on or against.

    Objects stand against walls, in corners and by furniture; a cup is found only from about 1.8 m.
    The surface cells are the map's free cells within ``SURFACE_BAND`` of an obstacle (on a 0.3 m
    lattice); a cell is seen from a viewpoint within ``SURFACE_RADIUS`` whose line of sight on the
    map is free. Viewpoints (free cells with room to turn, on a 0.5 m lattice) are added greedily,
    each the one that sees the most cells no viewpoint sees yet, until none adds ``SURFACE_MIN_GAIN``.
    The robot's map only: nothing here reads the simulator's truth.
    """
    from scipy.spatial import cKDTree

    res = grid.resolution

    def lattice(mask: np.ndarray, step: float) -> np.ndarray:
        k = max(1, int(round(step / res)))
        sub = np.zeros_like(mask)
        sub[::k, ::k] = mask[::k, ::k]
        rows, cols = np.nonzero(sub)
        return np.stack([grid.origin.x + (cols + 0.5) * res, grid.origin.y + (rows + 0.5) * res], axis=1)

    targets = lattice(inside & (clearance <= SURFACE_BAND), 0.3)
    stands = lattice(inside & (clearance >= 0.45), 0.5)
    if not len(targets) or not len(stands):
        return []
    old = np.array(chosen, dtype=float).reshape(-1, 2)
    every = np.concatenate([old, stands])
    tree = cKDTree(every)
    sees: list[set[int]] = [set() for _ in range(len(every))]
    for t, near in enumerate(tree.query_ball_point(targets, SURFACE_RADIUS)):
        if not near:
            continue
        idx = np.array(near)
        ok = _line_of_sight(grid, every[idx], (float(targets[t, 0]), float(targets[t, 1])), own=0.1)
        for i in idx[ok]:
            sees[int(i)].add(t)
    seen: set[int] = set().union(*sees[: len(old)]) if len(old) else set()
    added: list[tuple[float, float]] = []
    while True:
        gains = [len(s - seen) for s in sees]
        best = int(np.argmax(gains))
        if gains[best] < SURFACE_MIN_GAIN:
            return added
        seen |= sees[best]
        added.append((float(every[best, 0]), float(every[best, 1])))


Stop = tuple[float, float, "tuple[float, float] | None"]


def revisit_points(
    robot: Any,
    places: list[tuple[float, float]],
    route: list[tuple[float, float]],
    clear_view: bool = False,
    every: bool = False,
) -> list[Stop]:
    """The route plus a look at every known instance's place that no viewpoint is close to.

    ``places`` are the instances of the robot's own graph (what it believes is where), so the
    dynamic phase's pass looks at the old places again; a viewpoint is a free cell with room to
    turn, between ``REVISIT_MIN`` and ``REVISIT_MAX`` metres from the place (as close to
    ``REVISIT_BEST`` as the map allows), where the robot faces the place and sweeps ``LOOK_SWEEP``
    to each side instead of turning a full circle. With ``clear_view`` the map must also be free
    along the line of sight to the place (the last 0.35 m excepted). With ``every`` each place gets
    its look unless a viewpoint of ``route`` is near it (not skipped for another place's look).
    Returns (x, y, place to look at or None for a full circle) in a nearest-neighbour tour.
    Nothing here reads the simulator's truth.
    """
    import cv2

    grid = robot.occupancy()
    free = (grid.data >= 0) & (grid.data < 50)
    clearance = cv2.distanceTransform(free.astype(np.uint8), cv2.DIST_L2, 5) * grid.resolution
    rows, cols = np.nonzero(clearance >= 0.45)
    if not len(rows):
        return [(x, y, None) for x, y in route]
    res = grid.resolution
    xy = np.stack([grid.origin.x + (cols + 0.5) * res, grid.origin.y + (rows + 0.5) * res], axis=1)
    points: list[Stop] = [(x, y, None) for x, y in route]
    for px, py in places:
        near = [(a, b) for a, b, _ in points] if not every else list(route)
        if any(math.hypot(px - a, py - b) <= REVISIT_MAX for a, b in near):
            continue
        d = np.hypot(xy[:, 0] - px, xy[:, 1] - py)
        ok = (d >= REVISIT_MIN) & (d <= REVISIT_MAX)
        if clear_view and ok.any():
            ok[ok] = _line_of_sight(grid, xy[ok], (px, py))
        if not ok.any():
            continue
        best = int(np.argmin(np.where(ok, np.abs(d - REVISIT_BEST), np.inf)))
        points.append((float(xy[best, 0]), float(xy[best, 1]), (px, py)))
    start = robot.pose().pose
    tour: list[Stop] = []
    here = (start.x, start.y)
    while points:
        nxt = min(points, key=lambda p: math.hypot(p[0] - here[0], p[1] - here[1]))
        points.remove(nxt)
        tour.append(nxt)
        here = (nxt[0], nxt[1])
    return tour


def _line_of_sight(
    grid: Any, points: np.ndarray, place: tuple[float, float], own: float = 0.35
) -> np.ndarray:
    """Whether the map is free along each point's line to ``place`` (its last ``own`` metres not checked)."""
    res = grid.resolution
    t = np.linspace(0.0, 1.0, 24)[None, :]
    dx, dy = place[0] - points[:, 0], place[1] - points[:, 1]
    length = np.hypot(dx, dy)
    stop = np.clip(1.0 - own / np.maximum(length, 1e-6), 0.0, 1.0)[:, None]
    xs = points[:, :1] + dx[:, None] * t * stop
    ys = points[:, 1:] + dy[:, None] * t * stop
    cols = np.clip(((xs - grid.origin.x) / res).astype(int), 0, grid.data.shape[1] - 1)
    rows = np.clip(((ys - grid.origin.y) / res).astype(int), 0, grid.data.shape[0] - 1)
    cells = grid.data[rows, cols]
    return np.all((cells >= 0) & (cells < 50), axis=1)


# -- changing the world (the evaluator's hand, not the robot's) ---------------------------------------


def _set_static(world: World, prims: Primitives) -> None:
    world.static = prims


def move_object(world: World, object_id: str, x: float, y: float) -> None:
    obj = world.object(object_id)
    prims = world.static
    geom = prims.geom.copy()
    rows = prims.inst == obj.inst
    geom[rows, 0] = x
    geom[rows, 1] = y
    _set_static(world, dataclasses.replace(prims, geom=geom))
    world.objects[world.objects.index(obj)] = dataclasses.replace(obj, pose=Pose2D(x, y, obj.pose.yaw))


def remove_object(world: World, object_id: str) -> None:
    obj = world.object(object_id)
    _set_static(world, world.static.select(world.static.inst != obj.inst))
    world.objects.remove(obj)


def add_object(
    world: World, label: str, colour: str, size: tuple[float, float, float], shape: str, x: float, y: float
) -> str:
    inst = max(world.instances) + 1
    oid = f"added_{label.replace(' ', '_')}"
    spec = ObjectSpec(id=oid, label=label, color=colour, size=size, shape=shape, pose={"x": x, "y": y})
    obj = _make_object(spec, oid, inst)
    row: tuple[Any, ...]
    if obj.shape == "cylinder":
        row = (CYLINDER, (x, y, obj.size[0] / 2), obj.elevation, obj.top, obj.rgb, inst, obj.pattern)
    else:
        row = (
            BOX,
            (x, y, 1.0, 0.0, obj.size[0] / 2, obj.size[1] / 2),
            obj.elevation,
            obj.top,
            obj.rgb,
            inst,
            obj.pattern,
        )
    _set_static(world, world.static.concat(Primitives.build([row])))
    world.objects.append(obj)
    world.instances[inst] = InstanceInfo(inst, "object", oid, label)
    return oid


def reachable_floor(world: World, x: float, y: float) -> np.ndarray:
    """The world's free cells connected to (x, y) (the evaluator's truth: where a changed object may go).

    A real map's free cells include pockets the robot cannot reach (behind glass, outside the
    building's scan); a changed object must stand where the robot could see it.
    """
    from scipy import ndimage

    g = world.grid
    free = g.data == 0
    labels, _ = ndimage.label(free)
    row, col = g.world_to_cell(x, y)
    if not (0 <= row < free.shape[0] and 0 <= col < free.shape[1]) or labels[row, col] == 0:
        return free
    return labels == labels[row, col]


def free_spot(
    world: World, rng: np.random.Generator, avoid: list[tuple[float, float]], floor: np.ndarray | None = None
) -> tuple[float, float]:
    """A free floor point away from walls, objects and the route's viewpoints (the evaluator's choice).

    ``floor`` (cells) limits the choice to where the robot can go; a world without rooms (a real map
    with placed objects) takes any free point with the clearance. A cramped world (a small real map
    whose viewpoints cover it densely) gets the spot at smaller distances (0.6 m from walls, 1 m
    from viewpoints and objects; then 0.45 m and 0.6 m) before none is found.
    """
    g = world.grid
    rows, cols = np.nonzero((g.data == 0) if floor is None else floor)
    for wall, apart in ((0.6, 1.0), (0.45, 0.6)):
        for _ in range(2000):
            i = int(rng.integers(len(rows)))
            x, y = g.cell_to_world(int(rows[i]), int(cols[i]))
            if (world.rooms and world.room_at(x, y) is None) or world.clearance(x, y) < wall:
                continue
            if any(math.hypot(x - a, y - b) < apart for a, b in avoid):
                continue
            if any(math.hypot(x - o.pose.x, y - o.pose.y) < apart for o in world.objects):
                continue
            return x, y
    raise RuntimeError("no free spot for a changed object")
