"""Scene graph quality: missiontree's live graph against the NAIS pipeline as published, same frames.

Two splits (``--split dev|test|both``, default both), reported side by side:

- ``dev`` (what the fusion is tuned on): ``--worlds`` generated apartments from ``--first-seed``
  (``generated:<seed>``) plus the shipped office world;
- ``test`` (held out; run once at the end of a change, to report): ``--test-worlds`` worlds of the
  test split of :mod:`missiontree.evaluation.splits` from ``--test-first-seed`` -- a second
  generator family (long corridors with many 0.8-0.9 m doors, L and T corridors, open plan, rooms
  off rooms, clutter by doors, warehouse floors) and real SLAM maps, their objects placed by the
  placement generator (on floors, on tables, against walls, in corners, with same-class and
  same-colour decoys).

Each split prints ours' figures; the test figures with 95 % Wilson intervals (counts beside them),
the dev - test gap, and a markdown table of both; the last line is one JSON object with ``dev``,
``test`` and ``gap`` (each split: ours' figures flat, ``ci95`` and ``counts`` of every rate,
``nais`` nested). ``--world-file PATH`` (repeatable) runs given world files instead, as split
``files`` (diagnostics on worlds built by hand).

For each world the simulated robot visits viewpoints chosen from its map alone (rooms segmented from the
occupancy map, free cells with room to turn, spread over each room, then more until every free cell
beside a wall or furniture is within 2 m of one in sight on the map: :func:`surface_viewpoints`)
and turns a slow full circle at each; every camera frame is detected once and handed to both methods:

- ``ours`` — :class:`~missiontree.semantics.builder.SceneBuilder` as the ``BuildSceneGraph`` leaf runs
  it: the NAIS filters, fusion that refines, removes what is seen gone and moves what moved, rooms
  segmented from the map and typed from the objects seen in them, colours measured in the pixels;
- ``nais`` — the NAIS paper's pipeline: :class:`~missiontree.perception.tracking.NaisTracker` (its
  filters at the paper's values: confidence 0.7, no dynamic classes, depth at the box centre,
  4.5 m, 10 frames, 0.5 m over the last 100, room-change replacement), the room context from the
  vision-language model on the current frame about once a second (LLaVA's rate in the paper),
  colours from the VLM's description of a crop 20 % larger than the box, and no update once an
  object is confirmed (the paper's stated limit). The models are those of ``--models`` (default
  ``offline``: the shipped detector and the offline VLM stand-in).

After the first pass: **object precision / recall** (same class — the simulator draws desks and
dining tables as tables, so those count as ``table`` — and planar position within 0.5 m, greedy
nearest matching; truth = every object of the detector's classes), **room_accuracy** (matched
objects whose room node is the one paired with their true room; graph rooms and true rooms paired
one to one to agree on the most objects), **room_type_accuracy** (true rooms whose paired node
names their type), **colour_accuracy** (matched objects with the true colour name), and
**relation_precision** (ours: relations between matched objects that also hold between the true
objects, by the same geometry). Then the **dynamic phase**: three objects are moved, two removed
and one added (``--changes-seed``) while the robot patrols the same viewpoints once more, plus a
look (face the place, sweep 0.5 rad to each side) from a free cell near every object *its own
graph* holds that no viewpoint is within 2.2 m of, and at the end a look with a clear line of
sight in its map at every place of its graph that no frame of the pass could check (every view of
it occluded: the fusion's own bookkeeping; the route reads the robot's map and graph only);
**changes_reflected** is the share of those six changes the final graph shows (a moved object
found at its new place and nothing of its label at the old, a removed one gone, an added one
found). **rebuild_ms_300** times rebuilding relations and graph for 300 objects (min / median /
max over repetitions), beside the NAIS reference's rebuild, which is a GPT-4 round trip not
timed here.

``--verify`` makes ours ask the VLM whether a crop 20 % larger than the box shows the label before
a candidate becomes an instance (off by default: the offline stand-in re-runs the detector on the
small crop and turns down most true small objects).

``--diagnose`` prints each false and missed object of ours with its cause and each change of the
dynamic phase with what the fusion judged at its places (``scene_graph_diagnosis.py``).

Each world is one run of the batch runner (:func:`missiontree.evaluation.run_batch`, the wiring every
evaluation benchmark shares): a mission that ends at its first tick, before the robot's clock moves,
opens the session (the world's robot with its seed, the ``--models``), and a probe
(:class:`SceneEvalProbe`) runs the world's whole evaluation in the worker on them — visit, score,
change the world, patrol, score — and hands back the world's figures and what it printed
(``--debug``, ``--diagnose``), which are printed here per world, in order, and aggregated.
``--workers N`` runs worlds on a process pool of N (one world a task), ``--workers 1`` in this process.
A world whose evaluation raised is reported on stderr and left out (exit 1).

Scoring reads the simulator's truth; both pipelines see only frames, detections, poses and the
map. ``--quick`` runs 3 generated worlds and the office world (dev) and 4 test worlds.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import json
import math
import statistics
import sys
import time
from collections import Counter
from typing import Any

import numpy as np
from scene_rebuild import rebuild_figures  # benchmarks/scene_rebuild.py, beside this script
from scipy.optimize import linear_sum_assignment

from missiontree.backends.sim.raycast import BOX, CYLINDER, Primitives
from missiontree.backends.sim.schema import ObjectSpec
from missiontree.backends.sim.world import InstanceInfo, World, _make_object
from missiontree.perception.colour import canonical_colour
from missiontree.perception.projection import project
from missiontree.perception.tracking import NaisTracker
from missiontree.reasoning.offline_scene import measured_description, room_type_from_objects
from missiontree.reasoning.prompts import object_description_prompt
from missiontree.reasoning.scene_prompts import crop_verifier, expanded_crop
from missiontree.reasoning.schemas import ObjectDescription, RoomClassification
from missiontree.semantics.builder import BuilderParams, SceneBuilder
from missiontree.semantics.relations import Body, compute_relations
from missiontree.semantics.rooms import segment_rooms
from missiontree.types import Pose2D, Tolerance

#: Truth labels the simulator draws as another class's prism (the detector's README).
TRUTH_ALIAS = {"desk": "table", "dining table": "table", "coffee table": "table"}
MATCH_RADIUS = 0.5
TURN_SPEED = 0.5
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
#: Radians swept to each side of a revisited place.
LOOK_SWEEP = 0.5
NAIS_ROOM_PERIOD = 1.0
DEBUG = False
DIAGNOSE = False
SINGLE_PASS = False
VERIFY = False
#: After each pass, look again from a good distance at the candidates it left unconfirmed (off by
#: default: on dev it confirmed more false objects than true ones, and doubled some worlds' time).
SECOND_LOOK = False
#: ours' depth method (the BuildSceneGraph leaf's default unless --depth-method says otherwise).
DEPTH_METHOD = "centre"


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


# -- the NAIS reference ------------------------------------------------------------------------------


class NaisPipeline:
    """The NAIS paper's detection node, room context and descriptions (see module docstring)."""

    def __init__(self, vlm: Any) -> None:
        self.tracker = NaisTracker()
        self.vlm = vlm
        self.room = "unknown"
        self.next_room_query = -math.inf
        self.objects: dict[str, dict[str, Any]] = {}

    def add_frame(self, frame: Any, detections: list[Any]) -> None:
        """One frame: room context about once a second, the paper's filters, a description per new object."""
        if frame.stamp >= self.next_room_query:
            self.next_room_query = frame.stamp + NAIS_ROOM_PERIOD
            answer = RoomClassification.model_validate_json(
                self.vlm.ask([frame.color], "room", RoomClassification)
            )
            if answer.room_type != "unknown":
                self.room = answer.room_type
        projections = [
            p
            for p in (project(frame, d, method="centre", surface_offset=0.0) for d in detections)
            if p is not None
        ]
        by_label = {id(p): p for p in projections}
        for event in self.tracker.process(projections, room=self.room):
            if event.kind == "duplicate":
                continue
            if event.replaced:
                self.objects.pop(event.replaced, None)
            near = [p for p in by_label.values() if p.label == event.label]
            colour = "unknown"
            if near:
                p = min(near, key=lambda q: math.dist(q.position[:2], event.position[:2]))
                crop = expanded_crop(frame.color, p.box)
                text = self.vlm.ask([crop], object_description_prompt(event.label), ObjectDescription)
                colour = ObjectDescription.model_validate_json(text).colour
            self.objects[event.key] = {
                "id": event.key,
                "label": event.label,
                "position": event.position,
                "room": self.room,
                "colour": colour,
            }

    def predictions(self) -> list[dict[str, Any]]:
        """The confirmed objects."""
        return list(self.objects.values())


def ours_predictions(builder: SceneBuilder) -> list[dict[str, Any]]:
    rooms = {r.id: r for r in builder.scene.rooms}
    return [
        {
            "id": i.id,
            "label": i.label,
            "position": i.position,
            "room": i.room,
            "room_type": rooms[i.room].type if i.room in rooms else "unknown",
            "colour": i.colour,
            "size": i.size,
        }
        for i in builder.scene.map
    ]


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


# -- scoring ------------------------------------------------------------------------------------------


def truth_label(label: str) -> str:
    return TRUTH_ALIAS.get(label, label)


def match(preds: list[dict[str, Any]], truths: list[Any]) -> list[tuple[int, int]]:
    """Greedy nearest matching of predictions to true objects of the same class within 0.5 m."""
    pairs = []
    for i, p in enumerate(preds):
        for j, t in enumerate(truths):
            if p["label"] == truth_label(t.label):
                d = math.hypot(p["position"][0] - t.pose.x, p["position"][1] - t.pose.y)
                if d <= MATCH_RADIUS:
                    pairs.append((d, i, j))
    used_p, used_t, out = set(), set(), []
    for _, i, j in sorted(pairs):
        if i not in used_p and j not in used_t:
            used_p.add(i)
            used_t.add(j)
            out.append((i, j))
    return out


def on_unknown_object(p: dict[str, Any], world: World, classes: set[str]) -> bool:
    """Whether a prediction stands on an object of a class the detector does not know.

    A sink the detector called a chair: such predictions are left out of precision (and counted in
    ``object_precision_strict``).
    """
    x, y = p["position"][0], p["position"][1]
    for o in world.objects:
        if truth_label(o.label) in classes:
            continue
        local = np.array([x - o.pose.x, y - o.pose.y])
        c, s_ = math.cos(o.pose.yaw), math.sin(o.pose.yaw)
        u, v = c * local[0] + s_ * local[1], -s_ * local[0] + c * local[1]
        if abs(u) <= o.size[0] / 2 + MATCH_RADIUS and abs(v) <= o.size[1] / 2 + MATCH_RADIUS:
            return True
    return False


def score_phase(preds: list[dict[str, Any]], world: World, classes: set[str]) -> dict[str, Any]:
    preds = [p for p in preds if p["label"] in classes]
    truths = [o for o in world.objects if truth_label(o.label) in classes]
    pairs = match(preds, truths)
    matched = {i for i, _ in pairs}
    ignored = sum(1 for i, p in enumerate(preds) if i not in matched and on_unknown_object(p, world, classes))
    # rooms: pair graph room nodes with true rooms one to one, agreeing on the most matched objects
    nodes = sorted({str(preds[i]["room"]) for i, _ in pairs})
    true_rooms = [r.name for r in world.rooms]
    counts = np.zeros((max(len(nodes), 1), max(len(true_rooms), 1)))
    truth_room = {}
    for i, j in pairs:
        room = world.room_at(truths[j].pose.x, truths[j].pose.y)
        truth_room[(i, j)] = room.name if room else None
        if room is not None and nodes:
            counts[nodes.index(str(preds[i]["room"])), true_rooms.index(room.name)] += 1
    r_idx, c_idx = linear_sum_assignment(-counts)
    paired = {
        nodes[r]: true_rooms[c]
        for r, c in zip(r_idx, c_idx, strict=True)
        if r < len(nodes) and c < len(true_rooms) and counts[r, c] > 0
    }
    in_room = sum(
        1
        for i, j in pairs
        if paired.get(str(preds[i]["room"])) == truth_room[(i, j)] and preds[i]["room"] is not None
    )
    colour_ok = sum(1 for i, j in pairs if preds[i]["colour"] == canonical_colour(truths[j].color))
    node_type = {}
    for i, _ in pairs:
        node_type[str(preds[i]["room"])] = preds[i].get("room_type", preds[i]["room"])
    types_ok = sum(
        1
        for node, name in paired.items()
        if _norm(node_type.get(node, "")) == _norm(next(r.type for r in world.rooms if r.name == name))
    )
    return {
        "tp": len(pairs),
        "pred": len(preds) - ignored,
        "pred_all": len(preds),
        "truth": len(truths),
        "in_room": in_room,
        "colour_ok": colour_ok,
        "rooms": len(world.rooms),
        "types_ok": types_ok,
        "pairs": pairs,
        "preds": preds,
        "truths": truths,
    }


def _norm(room_type: str) -> str:
    return room_type.strip().lower().replace(" ", "_")


def relation_precision(builder: SceneBuilder, scored: dict[str, Any], world: World) -> tuple[int, int]:
    """Our relations between matched objects that also hold between the true objects."""
    preds, truths = scored["preds"], scored["truths"]
    id_to_truth = {preds[i]["id"]: truths[j] for i, j in scored["pairs"]}
    bodies = []
    for oid, t in id_to_truth.items():
        room = world.room_at(t.pose.x, t.pose.y)
        bodies.append(
            Body(
                oid,
                t.pose.x,
                t.pose.y,
                t.elevation + t.size[2] / 2,
                t.size[0],
                t.size[1],
                t.size[2],
                room.name if room else None,
            )
        )
    centres = {r.name: (float(r.polygon[:, 0].mean()), float(r.polygon[:, 1].mean())) for r in world.rooms}
    truth_edges = {(e.source_id, e.target_id, e.relation) for e in compute_relations(bodies, centres)}
    truth_pairs = {(s, t) for s, t, _ in truth_edges} | {(t, s) for s, t, _ in truth_edges}
    ours = [
        e
        for e in builder.scene.graph.edges
        if e["relation"] != "contains"
        and str(e["source_id"]) in id_to_truth
        and str(e["target_id"]) in id_to_truth
    ]
    good = 0
    for e in ours:
        s, t, r = str(e["source_id"]), str(e["target_id"]), e["relation"]
        if (s, t) in truth_pairs or (t, s) in truth_pairs:
            good += 1 if (s, t, r) in truth_edges or r in ("near", "next_to") else 0
    return good, len(ours)


def change_reflected(preds: list[dict[str, Any]], change: dict[str, Any]) -> bool:
    def near(label: str, x: float, y: float) -> bool:
        return any(
            p["label"] == label and math.hypot(p["position"][0] - x, p["position"][1] - y) <= MATCH_RADIUS
            for p in preds
        )

    label = change["label"]
    if change["kind"] == "moved":
        return near(label, *change["to"]) and not near(label, *change["from"])
    if change["kind"] == "removed":
        return not near(label, *change["from"])
    return near(label, *change["to"])


# -- one world -----------------------------------------------------------------------------------------


def run_world(name: str, seed: int, robot: Any, models: dict[str, Any], changes_seed: int) -> dict[str, Any]:
    """One world's whole evaluation on ``robot`` (the session's): visit, score, change, patrol, score.

    The robot is the batch run's (its session closes it); the row returned is plain JSON data.
    """
    detector, vlm = models["detector"], models["vlm"]
    classes = set(detector.labels) - {"person"}

    def typer(room: Any, labels: list[str]) -> tuple[str, float, list[str]]:
        answer = room_type_from_objects(labels)
        return answer.room_type, answer.confidence, answer.evidence

    def describer(inst: Any) -> tuple[str, str, str]:
        d = measured_description(inst.label, inst.colour, inst.size)
        return d.description, d.shape, d.size

    verifier = crop_verifier(vlm) if VERIFY else None
    ours = SceneBuilder(
        BuilderParams(depth_method=DEPTH_METHOD),  # type: ignore[arg-type]
        room_typer=typer,
        describer=describer,
        verifier=verifier,
    )
    nais = NaisPipeline(vlm)
    route = viewpoints(robot)
    diag = None
    if DIAGNOSE:
        from scene_graph_diagnosis import Diagnosis

        diag = Diagnosis(robot, classes, ours.params.depth_method)
        diag.watch(ours.scene.map, ours.fusion)
    state = {"last": -math.inf, "frames": 0, "wall_ours": 0.0, "wall_nais": 0.0}

    def tick() -> None:
        robot.spin_until(robot.now() + 0.1)
        frame = robot.rgbd()
        if frame is not None and frame.stamp > state["last"]:
            state["last"] = frame.stamp
            state["frames"] += 1
            detections = detector.detect(frame.color)
            if diag is not None:
                diag.frame(frame, detections)
            # alternate which method goes first, so machine load falls on both alike
            order: list[tuple[Any, str]] = [(ours, "wall_ours"), (nais, "wall_nais")]
            for method, key in order if state["frames"] % 2 else order[::-1]:
                t0 = time.perf_counter()
                method.add_frame(frame, detections)
                state[key] += time.perf_counter() - t0
        pose = robot.pose()
        t0 = time.perf_counter()
        ours.update_rooms(robot.occupancy(), (pose.pose.x, pose.pose.y), robot.now())
        ours.step(robot.now())
        state["wall_ours"] += time.perf_counter() - t0

    def turn(speed: float, seconds: float) -> None:
        robot.drive(0.0, speed)
        end = robot.now() + seconds
        while robot.now() < end:
            tick()
        robot.stop()

    def second_look() -> None:
        """A look from a good distance at every doubtful place of ours (a candidate left unconfirmed)."""
        places = [(x, y) for _, x, y in ours.scene.doubtful]
        ours.scene.doubtful.clear()
        if places:
            patrol(revisit_points(robot, places, [], clear_view=True, every=True))

    def patrol(points: list[Stop]) -> None:
        for x, y, look in points:
            handle = robot.navigate_to(Pose2D(x, y, 0.0), Tolerance(0.35, 2 * math.pi))
            limit = robot.now() + 90.0
            while not handle.status().done and robot.now() < limit:
                tick()
            if not handle.status().done:
                handle.cancel()
            if look is None:
                turn(TURN_SPEED, 2 * math.pi / TURN_SPEED)
                continue
            here = robot.pose().pose
            error = math.remainder(math.atan2(look[1] - here.y, look[0] - here.x) - here.yaw, 2 * math.pi)
            turn(math.copysign(TURN_SPEED, error), abs(error) / TURN_SPEED)  # face the place
            turn(TURN_SPEED, LOOK_SWEEP / TURN_SPEED)
            turn(-TURN_SPEED, 2 * LOOK_SWEEP / TURN_SPEED)
            turn(TURN_SPEED, LOOK_SWEEP / TURN_SPEED)

    patrol([(x, y, None) for x, y in route])
    if SECOND_LOOK:
        second_look()
    ours.rebuild(robot.now())
    world = robot.world
    first = {
        "ours": score_phase(ours_predictions(ours), world, classes),
        "nais": score_phase(nais.predictions(), world, classes),
    }
    rel_good, rel_total = relation_precision(ours, first["ours"], world)
    if diag is not None:
        for line in diag.report(
            name, first["ours"], world, lambda p, w: on_unknown_object(p, w, classes), truth_label
        ):
            print(line, flush=True)
    if DEBUG:
        for m in ("ours", "nais"):
            sc = first[m]
            matched = {i for i, _ in sc["pairs"]}
            for i, p in enumerate(sc["preds"]):
                if i in matched:
                    continue
                near = min(
                    world.objects,
                    key=lambda o: math.hypot(o.pose.x - p["position"][0], o.pose.y - p["position"][1]),
                )
                d = math.hypot(near.pose.x - p["position"][0], near.pose.y - p["position"][1])
                print(
                    f"  FP {m} {p['id']} {p['label']} {[round(v, 2) for v in p['position']]} -> "
                    f"{near.id} {near.label} {d:.2f}"
                )
            found = {j for _, j in sc["pairs"]}
            for j, t in enumerate(sc["truths"]):
                if j not in found:
                    print(f"  FN {m} {t.id} {t.label} ({t.pose.x:.2f}, {t.pose.y:.2f}) elev {t.elevation}")

    if SINGLE_PASS:
        return {
            "world": name,
            "frames": state["frames"],
            "sim_s": robot.now(),
            "changes": 0,
            "relations_good": rel_good,
            "relations": rel_total,
            "ms_per_frame": {
                "ours": 1000 * state["wall_ours"] / max(state["frames"], 1),
                "nais": 1000 * state["wall_nais"] / max(state["frames"], 1),
            },
            **{
                m: {
                    **{
                        k: first[m][k]
                        for k in (
                            "tp",
                            "pred",
                            "pred_all",
                            "truth",
                            "in_room",
                            "colour_ok",
                            "rooms",
                            "types_ok",
                        )
                    },
                    "reflected": 0,
                }
                for m in ("ours", "nais")
            },
        }
    # dynamic phase: move 3, remove 2, add 1, then one more pass
    rng = np.random.default_rng(changes_seed + seed)
    candidates = [
        o
        for o in world.objects
        if o.movable and truth_label(o.label) in classes and o.size[0] * o.size[1] < 0.5 and o.elevation < 0.3
    ]
    rng.shuffle(candidates)
    # objects the robot has seen first (found by either method): a change to an object nobody saw says little
    seen = {id(first[m]["truths"][j]) for m in first for _, j in first[m]["pairs"]}
    candidates.sort(key=lambda o: id(o) not in seen)
    changes: list[dict[str, Any]] = []
    avoid = list(route)
    here = robot.pose().pose
    floor = reachable_floor(world, here.x, here.y)
    for obj in candidates[:3]:
        to = free_spot(world, rng, avoid, floor)
        avoid.append(to)
        changes.append(
            {
                "kind": "moved",
                "label": truth_label(obj.label),
                "id": obj.id,
                "from": (obj.pose.x, obj.pose.y),
                "to": to,
            }
        )
        move_object(world, obj.id, *to)
    for obj in candidates[3:5]:
        changes.append(
            {
                "kind": "removed",
                "label": truth_label(obj.label),
                "id": obj.id,
                "from": (obj.pose.x, obj.pose.y),
            }
        )
        remove_object(world, obj.id)
    to = free_spot(world, rng, avoid, floor)
    oid = add_object(world, "backpack", "green", (0.32, 0.22, 0.45), "box", *to)
    changes.append({"kind": "added", "label": "backpack", "id": oid, "to": to})
    # the pass of the dynamic phase looks again at every place the robot's graph holds an object
    if diag is not None:
        diag.new_phase()
    pass_start = robot.now()
    patrol(revisit_points(robot, [inst.xy for inst in ours.scene.map], route))
    # then a look, with a clear line of sight, at every place of its graph no frame of the pass could
    # check (each view of it was occluded): the robot's own bookkeeping, no truth
    unchecked = [inst.xy for inst in ours.fusion.unchecked_since(pass_start)]
    if unchecked:
        patrol(revisit_points(robot, unchecked, [], clear_view=True))
    if SECOND_LOOK:
        second_look()
    ours.rebuild(robot.now())
    after = {"ours": ours_predictions(ours), "nais": nais.predictions()}
    reflected = {m: sum(change_reflected(after[m], c) for c in changes) for m in after}
    if diag is not None:
        for line in diag.report_changes(name, changes, after["ours"], change_reflected):
            print(line, flush=True)
    if DEBUG:
        for c in changes:
            print(
                f"  change {c['kind']} {c['id']} {c['label']} from {c.get('from')} to {c.get('to')}: "
                f"ours {change_reflected(after['ours'], c)} nais {change_reflected(after['nais'], c)}"
            )
    out = {
        "world": name,
        "frames": state["frames"],
        "sim_s": robot.now(),
        "changes": len(changes),
        "relations_good": rel_good,
        "relations": rel_total,
        "ms_per_frame": {
            "ours": 1000 * state["wall_ours"] / max(state["frames"], 1),
            "nais": 1000 * state["wall_nais"] / max(state["frames"], 1),
        },
    }
    for m in ("ours", "nais"):
        s = first[m]
        out[m] = {
            k: s[k] for k in ("tp", "pred", "pred_all", "truth", "in_room", "colour_ok", "rooms", "types_ok")
        }
        out[m]["reflected"] = reflected[m]
    return out


# -- one world as a run of the batch runner -------------------------------------------------------------

#: The mission each world's batch run opens: it ends at its first tick (``Succeed``, before the robot's
#: clock moves), so the session has built the robot (world and seed of the run) and the models, and the
#: probe then runs the world's whole evaluation on them in the worker (:class:`SceneEvalProbe`).
MISSION = """version: 1
description: >
  One world of the scene-graph evaluation (benchmarks/scene_graph_eval.py): the session builds the
  robot and the models; the evaluation's probe drives the robot once this mission has ended.
run:
  backend: sim
  tick_hz: 10
root:
  Succeed: {name: session_open}
"""


@dataclasses.dataclass(frozen=True)
class EvalOptions:
    """The flags a worker's evaluation needs (picklable, handed to every probe)."""

    changes_seed: int = 7
    debug: bool = False
    single_pass: bool = False
    verify: bool = False
    diagnose: bool = False
    depth_method: str = "centre"
    second_look: bool = False


class SceneEvalProbe:
    """Runs one world's evaluation in the batch worker, on the run's robot and models.

    The mission ends at its first tick; :meth:`finish` then visits, scores, changes the world, patrols
    and scores again (:func:`run_world`), and returns the world's row and everything it printed (the
    ``--debug`` and ``--diagnose`` lines) as the run's figures: the caller prints them per world, so
    they read the same whether the world ran here, in a pool worker or on a Dask worker.
    """

    def __init__(self, options: EvalOptions) -> None:
        self.options = options

    def on_tick(self, session: Any) -> None:
        """Nothing between ticks (the mission has one)."""

    def finish(self, session: Any, result: Any) -> dict[str, Any]:
        """The world's row (``scene_eval``) and its printed lines (``scene_eval_output``)."""
        import io

        global DEBUG, SINGLE_PASS, VERIFY, DIAGNOSE, DEPTH_METHOD, SECOND_LOOK
        o = self.options
        DEBUG, SINGLE_PASS, VERIFY, DIAGNOSE, DEPTH_METHOD, SECOND_LOOK = (
            o.debug,
            o.single_pass,
            o.verify,
            o.diagnose,
            o.depth_method,
            o.second_look,
        )
        name = str(session.request.world)
        seed = int(session.settings["seed"])
        printed = io.StringIO()
        t0 = time.perf_counter()
        try:
            with contextlib.redirect_stdout(printed):
                row = run_world(name, seed, session.robot, session.models, o.changes_seed)
        except BaseException:
            sys.stdout.write(printed.getvalue())  # what the world printed before it failed
            sys.stdout.flush()
            raise
        row["wall_s"] = time.perf_counter() - t0
        return {"scene_eval": row, "scene_eval_output": printed.getvalue()}


def run_worlds(
    worlds: list[tuple[int, str]], models: str, workers: int, options: EvalOptions, on_row: Any
) -> list[dict[str, Any]]:
    """Each (seed, world) on the batch runner (a pool of ``workers``, or this process for 1).

    ``on_row(row, printed)`` is called in plan order as rows arrive (a world waits for the ones before
    it). A world whose run did not succeed is reported on stderr and left out. Returns the rows.
    """
    import functools
    import tempfile
    from pathlib import Path

    from missiontree.evaluation import BatchPlan, PoolEngine, RunSpec, SerialEngine, run_batch

    specs = [RunSpec(world=name, seed=seed, run_seed=seed) for seed, name in worlds]
    arrived: dict[str, Any] = {}
    rows: list[dict[str, Any]] = []
    shown = 0

    with tempfile.TemporaryDirectory(prefix="scene_graph_eval_") as tmp:
        folder = Path(tmp)
        out = folder / "batch"

        def take(record: Any, skipped: bool) -> None:
            nonlocal shown
            arrived[record.run_id] = record
            while shown < len(specs) and specs[shown].run_id in arrived:
                done = arrived[specs[shown].run_id]
                shown += 1
                if done.status == "SUCCESS" and "scene_eval" in done.figures:
                    rows.append(done.figures["scene_eval"])
                    on_row(done.figures["scene_eval"], done.figures.get("scene_eval_output", ""))
                    continue
                trace = ""
                if done.run_dir is not None:
                    with contextlib.suppress(OSError, ValueError):
                        record_file = out / done.run_dir / "record.json"
                        trace = json.loads(record_file.read_text(encoding="utf-8")).get("traceback", "")
                why = f"{done.status}: {done.reason}"
                print(f"{done.world}: the evaluation did not finish ({why})", file=sys.stderr)
                if trace:
                    print(trace, file=sys.stderr, end="")

        mission = folder / "scene_graph_eval_world.yaml"
        mission.write_text(MISSION, encoding="utf-8")
        plan = BatchPlan(mission=mission, runs=specs, request={"models": models})
        engine = PoolEngine(workers) if workers > 1 else SerialEngine()
        with engine:
            run_batch(
                plan,
                engine,
                out,
                probe=functools.partial(SceneEvalProbe, options),
                write_log=False,
                on_record=take,
            )
    return rows


# -- rebuild time at 300 objects -------------------------------------------------------------------------


# (timed by benchmarks/scene_rebuild.py, beside the previous implementation: rebuild_figures)


#: Figures of ours that are rates (successes over trials): the keys of their counts in a split's totals.
RATES = {
    "object_precision": ("tp", "pred"),
    "object_recall": ("tp", "truth"),
    "room_accuracy": ("in_room", "tp"),
    "room_type_accuracy": ("types_ok", "rooms"),
    "colour_accuracy": ("colour_ok", "tp"),
    "changes_reflected": ("reflected", "changes"),
}
#: The figures the dev-test gap and the markdown table show.
HEADLINE = (
    "object_precision",
    "object_recall",
    "changes_reflected",
    "room_accuracy",
    "room_type_accuracy",
    "colour_accuracy",
    "relation_precision",
)


def split_figures(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """One split's figures: ours (with 95 % Wilson intervals and counts of every rate) and nais."""
    from missiontree.evaluation.report import wilson

    out: dict[str, Any] = {"worlds": len(rows)}
    for m in ("ours", "nais"):
        tot: Counter[str] = Counter()
        for row in rows:
            tot.update({k: v for k, v in row[m].items()})
            tot["changes"] += row["changes"]
        ms = [row["ms_per_frame"][m] for row in rows]
        figures: dict[str, Any] = {
            "object_precision": round(tot["tp"] / max(tot["pred"], 1), 4),
            "object_precision_strict": round(tot["tp"] / max(tot["pred_all"], 1), 4),
            "object_recall": round(tot["tp"] / max(tot["truth"], 1), 4),
            "room_accuracy": round(tot["in_room"] / max(tot["tp"], 1), 4),
            "room_type_accuracy": round(tot["types_ok"] / max(tot["rooms"], 1), 4),
            "colour_accuracy": round(tot["colour_ok"] / max(tot["tp"], 1), 4),
            "changes_reflected": round(tot["reflected"] / max(tot["changes"], 1), 4),
            "ms_per_frame_median": round(statistics.median(ms), 3) if ms else None,
        }
        if m == "ours":
            figures["ci95"] = {
                k: [round(v, 4) for v in wilson(tot[a], tot[b])] for k, (a, b) in RATES.items()
            }
            figures["counts"] = {k: [tot[a], tot[b]] for k, (a, b) in RATES.items()}
            good = sum(r["relations_good"] for r in rows)
            total = sum(r["relations"] for r in rows)
            figures["relation_precision"] = round(good / max(total, 1), 4)
            figures["ci95"]["relation_precision"] = [round(v, 4) for v in wilson(good, total)]
            figures["counts"]["relation_precision"] = [good, total]
            out.update(figures)
        else:
            figures["relation_precision"] = None  # its relations come from GPT-4 reading descriptions
            out["nais"] = figures
    return out


def markdown_table(result: dict[str, Any]) -> list[str]:
    """Ours per split (test with its 95 % interval) and the dev-test gap, as a markdown table."""
    splits = [s for s in ("dev", "test") if s in result]
    head = "| figure | " + " | ".join(f"{s} ({result[s]['worlds']} worlds)" for s in splits)
    head += " | gap dev-test |" if "gap" in result else " |"
    lines = [head, "|---" * (len(splits) + 1 + ("gap" in result)) + "|"]
    for key in HEADLINE:
        cells = []
        for s in splits:
            value = result[s].get(key)
            ci = result[s].get("ci95", {}).get(key)
            counts = result[s].get("counts", {}).get(key)
            text = "-" if value is None else f"{value:.3f}"
            if ci is not None and counts is not None:
                text += f" [{ci[0]:.3f}, {ci[1]:.3f}] ({counts[0]}/{counts[1]})"
            cells.append(text)
        gap = result.get("gap", {}).get(key)
        row = f"| {key} | " + " | ".join(cells)
        row += (f" | {gap:+.3f} |" if gap is not None else " | - |") if "gap" in result else " |"
        lines.append(row)
    return lines


def dev_worlds(args: argparse.Namespace) -> list[tuple[str, str]]:
    """The dev split: generated apartments from ``--first-seed`` and the shipped office world."""
    count = 3 if args.quick else args.worlds
    names = [f"generated:{args.first_seed + i}" for i in range(count)]
    return [(n, n) for n in names] + ([] if args.no_office else [("office", "office")])


def test_worlds(args: argparse.Namespace, folder: Any) -> list[tuple[str, str]]:
    """The test split (``missiontree.evaluation.splits``), each world written to ``folder``: (name, path)."""
    try:
        from missiontree.evaluation.splits import split_worlds, write_split_world
    except ImportError as exc:  # the splits module is not in this checkout
        raise SystemExit(f"the test split needs missiontree.evaluation.splits: {exc}") from None
    count = 4 if args.quick else args.test_worlds
    worlds = split_worlds("test", count, first_seed=args.test_first_seed, min_objects=6)
    return [(w.name, str(write_split_world(w, folder))) for w in worlds]


def main(argv: list[str] | None = None) -> int:
    import tempfile
    from pathlib import Path

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--split",
        choices=("dev", "test", "both"),
        default="both",
        help="dev (generated apartments and the office, tuned on), test (held out), or both",
    )
    parser.add_argument("--worlds", type=int, default=20, help="dev: generated worlds (default 20)")
    parser.add_argument("--first-seed", type=int, default=100, help="dev: seed of the first generated world")
    parser.add_argument("--no-office", action="store_true", help="dev: leave out the shipped office world")
    parser.add_argument(
        "--test-worlds", type=int, default=12, help="test: worlds of the test split (default 12)"
    )
    parser.add_argument("--test-first-seed", type=int, default=0, help="test: the split's first seed")
    parser.add_argument(
        "--world-file",
        action="append",
        default=[],
        help="run these world files instead of the splits, reported as split 'files' (diagnostics)",
    )
    parser.add_argument("--models", default="offline", help="models config (default offline)")
    parser.add_argument("--changes-seed", type=int, default=7, help="seed of the dynamic phase's changes")
    parser.add_argument(
        "--quick", action="store_true", help="dev: 3 generated worlds and the office; test: 4"
    )
    parser.add_argument("--workers", type=int, default=2, help="worlds run at once (processes, default 2)")
    parser.add_argument("--debug", action="store_true", help="list each world's false and missed objects")
    parser.add_argument(
        "--diagnose",
        action="store_true",
        help="print each false and missed object of ours with its cause, and each change (reads the "
        "simulator's truth for the diagnosis only)",
    )
    parser.add_argument(
        "--depth-method",
        choices=("centre", "robust"),
        default="centre",
        help="ours' depth: the median at the box centre (NAIS, the leaf's default) or the box's nearest "
        "depth cluster",
    )
    parser.add_argument("--only", help="comma-separated world names to run (diagnostics)")
    parser.add_argument("--single-pass", action="store_true", help="skip the dynamic phase (diagnostics)")
    parser.add_argument(
        "--second-look",
        action="store_true",
        help="after each pass, look again at the places ours left doubtful (a candidate seen a few times)",
    )
    parser.add_argument(
        "--verify",
        action="store_true",
        help="ours asks the VLM whether a 20%% larger crop shows the label before adding an instance "
        "(off by default: the offline stand-in turns down most true small objects)",
    )
    args = parser.parse_args(argv)
    global DEBUG, SINGLE_PASS
    DEBUG = args.debug
    SINGLE_PASS = args.single_pass
    started = time.perf_counter()
    options = EvalOptions(
        changes_seed=args.changes_seed,
        debug=DEBUG,
        single_pass=SINGLE_PASS,
        verify=args.verify,
        diagnose=args.diagnose,
        depth_method=args.depth_method,
        second_look=args.second_look,
    )
    result: dict[str, Any] = {}
    failed = 0
    with tempfile.TemporaryDirectory(prefix="scene_graph_eval_worlds_") as tmp:
        plans: dict[str, list[tuple[str, str]]] = {}
        if args.world_file:
            plans["files"] = [(Path(f).stem, str(Path(f).resolve())) for f in args.world_file]
        else:
            if args.split in ("dev", "both"):
                plans["dev"] = dev_worlds(args)
            if args.split in ("test", "both"):
                plans["test"] = test_worlds(args, Path(tmp))
        for split, named in plans.items():
            if args.only:
                named = [(n, w) for n, w in named if n in args.only.split(",")]
            display = {w: n for n, w in named}

            def show(row: dict[str, Any], printed: str, split: str = split, display: dict = display) -> None:
                if printed:
                    print(printed, end="", flush=True)  # the world's --debug / --diagnose lines
                row["world"] = display.get(row["world"], row["world"])
                o, n = row["ours"], row["nais"]
                print(
                    f"{split:4s} {row['world']:22s} {row['wall_s']:5.1f} s wall, {row['sim_s']:5.0f} s sim, "
                    f"{row['frames']} frames | ours tp {o['tp']}/{o['pred']} of {o['truth']}, "
                    f"rooms {o['in_room']}, colour {o['colour_ok']}, "
                    f"changes {o['reflected']}/{row['changes']} | "
                    f"nais tp {n['tp']}/{n['pred']}, rooms {n['in_room']}, "
                    f"colour {n['colour_ok']}, changes {n['reflected']}/{row['changes']}",
                    flush=True,
                )

            worlds = [(k, w) for k, (_, w) in enumerate(named)]
            rows = run_worlds(worlds, args.models, args.workers, options, show)
            failed += len(worlds) - len(rows)
            if rows:
                result[split] = split_figures(rows)
    if not result:
        print("no world finished its evaluation", file=sys.stderr)
        return 1
    if "dev" in result and "test" in result:
        result["gap"] = {
            k: round(result["dev"][k] - result["test"][k], 4)
            for k in HEADLINE
            if result["dev"].get(k) is not None and result["test"].get(k) is not None
        }
    for split in ("files", "dev", "test"):
        if split in result:
            r = result[split]
            print(
                f"{split}: {r['worlds']} worlds, ours precision {r['object_precision']:.3f} recall "
                f"{r['object_recall']:.3f} changes {r['changes_reflected']:.3f} | nais precision "
                f"{r['nais']['object_precision']:.3f} recall {r['nais']['object_recall']:.3f}"
            )
    if "test" in result:
        ci = result["test"]["ci95"]
        print(
            "test, 95 % Wilson intervals: " + ", ".join(f"{k} {v[0]:.3f}-{v[1]:.3f}" for k, v in ci.items())
        )
    if "gap" in result:
        print("dev - test gap: " + ", ".join(f"{k} {v:+.3f}" for k, v in result["gap"].items()))
    if "files" not in result:
        print()
        for line in markdown_table(result):
            print(line)
        print()
    result.update(rebuild_figures())  # rebuild_ms_300 and its min/median/max, printed too
    result["wall_s"] = round(time.perf_counter() - started, 1)
    print(json.dumps(result))
    if failed:
        print(f"{failed} worlds did not finish (left out of the figures)", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
