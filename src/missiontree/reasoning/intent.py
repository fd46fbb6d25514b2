"""From a user's words to a checked navigation goal over a scene graph (NAIS interpretation, checked).

The NAIS paper's interpretation node hands GPT-4 the command and the scene graph, takes the
candidate objects it answers, picks the one nearest the robot in a straight line and sends the
object's own position as the goal. Nothing checks the answer. Here every step is checked:

1. :func:`graph_objects` reads the scene graph (the NAIS JSON shape, or any object with
   ``to_json()``) into :class:`GraphObject` values: id, label, description, coordinates, room,
   relations. Graph text is *data*: it is only ever compared with words, never obeyed.
2. :func:`prompt_objects` turns them into the object list of
   :func:`~missiontree.reasoning.prompts.intent_messages` (the model sees ids, labels, colour and
   size words, the room and the graph's relations; it answers ids).
3. :func:`plan_candidates` checks every id the model named — it must be an object of the graph,
   not marked doubtful, with coordinates inside the known map and a free place to stand near it
   that the robot can reach — and ranks the survivors by **path length** from the robot. Each
   rejected id comes back with its reason. The goal of a candidate is a **standoff pose**: a
   reachable free pose near the object, facing it (the object's own position is inside an obstacle).
   No coordinate ever comes from the model: goals are computed from graph coordinates and the map.
4. :func:`match_detection` and :func:`look_crop` serve the look on arrival: the detector must see
   the object's class where the graph puts it, and the vision-language model must confirm the
   asked-for attributes on a crop of that detection.

:func:`nais_goal` is the reference method as the NAIS paper published it, for the evaluation.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from missiontree.mapping.planner import path_lengths
from missiontree.perception.colour import ALIASES, COLOUR_NAMES, canonical_colour
from missiontree.perception.projection import project
from missiontree.reasoning.phrases import colour_words, fold_label, size_words, split_relation
from missiontree.reasoning.standoff import (
    MAX_REACH,
    Space,
    cell_path_lengths,
    outside_known_map,
    prepare_space,
    standoff_cells,
    view_distance,
)
from missiontree.types import Detection, OccupancyGrid, Pose2D, RGBDFrame, wrap_angle

#: Relations of the graph that are containment, not spatial relations between objects.
CONTAINS = "contains"
#: A second look comes from a side at least this far round the object (rad) ...
OTHER_SIDE = math.radians(60.0)
#: ... or, when the object is seen from one side only, this much nearer or farther (m).
OTHER_RANGE = 0.3
#: A detection is the object when it lies this near the graph's place (m), beyond the object's own
#: half-width: the live graph's position error and the robot's localisation error ...
POSITION_SLACK = 0.35
#: ... plus this much per metre of distance, for the heading error (m/m).
RANGE_SLACK = 0.05
#: The object's own half-width counts at most this (m): the box of a long sofa seen close says little.
MAX_HALF_WIDTH = 0.5


@dataclass(frozen=True)
class Relation:
    """A spatial relation of the graph from one object to another (``in_front_of`` the sofa)."""

    relation: str
    target_id: str
    target_label: str


@dataclass(frozen=True)
class GraphObject:
    """An object node of the scene graph, as the intent pipeline reads it.

    Attributes:
        id: The node id (as text).
        label: The class label.
        description: The graph's free text (data, never instructions).
        xy: Map-frame position, None when the node has no usable coordinates.
        z: Height of the object's point above the floor (0 when the graph gives none).
        room: The label of the room that contains it, "" when none.
        relations: Spatial relations from this object to others (not ``contains``).
        kind: The node type (``object``; rooms and the building are kept apart).
    """

    id: str
    label: str
    description: str = ""
    xy: tuple[float, float] | None = None
    z: float = 0.0
    room: str = ""
    relations: tuple[Relation, ...] = ()
    kind: str = "object"

    @property
    def attributes(self) -> list[str]:
        """Colour and size words of the object itself: the description's head, before any relation phrase.

        "an open laptop in front of the grey sofa" gives no colour (grey is the sofa's).
        """
        head, _, _ = split_relation(self.description)
        return colour_words(head) + size_words(head)


@dataclass(frozen=True)
class SceneObjects:
    """The scene graph read for intent: objects by id, and the ids of its other nodes (rooms, building)."""

    objects: dict[str, GraphObject]
    others: dict[str, str] = field(default_factory=dict)  # id -> type ("room", "building")

    def __len__(self) -> int:
        return len(self.objects)


@dataclass(frozen=True)
class Candidate:
    """A checked candidate: an object of the graph with a reachable standoff goal.

    Attributes:
        id: Graph id.
        label: Its label.
        xy: Its position (from the graph).
        goal: The standoff pose facing it (computed from the map, never from the model).
        path_length: Length of the robot's path to ``goal`` (m).
        straight_line: Straight-line distance from the robot to the object (m), for comparison.
    """

    id: str
    label: str
    xy: tuple[float, float]
    goal: Pose2D
    path_length: float
    straight_line: float

    def as_dict(self) -> dict[str, Any]:
        """JSON-friendly form (blackboard and tick log)."""
        return {
            "id": self.id,
            "label": self.label,
            "x": round(self.xy[0], 3),
            "y": round(self.xy[1], 3),
            "goal": {"x": round(self.goal.x, 3), "y": round(self.goal.y, 3), "yaw": round(self.goal.yaw, 3)},
            "path_length": round(self.path_length, 3),
            "straight_line": round(self.straight_line, 3),
        }


@dataclass(frozen=True)
class Rejection:
    """A candidate id the checks turned down, and why."""

    id: str
    reason: str

    def as_dict(self) -> dict[str, str]:
        """JSON-friendly form."""
        return {"id": self.id, "reason": self.reason}


@dataclass(frozen=True)
class Ranking:
    """What :func:`plan_candidates` found: the checked candidates by path length, and the rejections."""

    candidates: list[Candidate]
    rejected: list[Rejection]


# -- the graph ---------------------------------------------------------------------------------------


def graph_document(graph: Any) -> dict[str, Any]:
    """The NAIS JSON document of ``graph``: a dict, JSON text, or an object with ``to_json()``.

    Raises:
        ValueError: It is not a graph in the NAIS shape (says what was found).
    """
    data: Any = graph
    to_json = getattr(graph, "to_json", None)
    if callable(to_json):
        data = to_json()
    if isinstance(data, str | bytes):
        try:
            data = json.loads(data)
        except json.JSONDecodeError as exc:
            raise ValueError(f"the scene graph is not JSON ({exc.msg} at line {exc.lineno})") from None
    if not isinstance(data, Mapping) or not isinstance(data.get("nodes"), list):
        raise ValueError(
            'expected a scene graph in the NAIS shape: {"nodes": [...], "edges": [...]}, '
            f"found {type(data).__name__}"
        )
    return dict(data)


def graph_objects(graph: Any) -> SceneObjects:
    """Read the object nodes of a scene graph with their rooms and spatial relations.

    Malformed nodes (no id) are skipped; an object without usable coordinates keeps ``xy=None`` so
    that a candidate naming it is rejected with that reason.

    Raises:
        ValueError: ``graph`` is not in the NAIS shape.
    """
    doc = graph_document(graph)
    nodes = [n for n in doc.get("nodes", []) if isinstance(n, Mapping) and n.get("id") is not None]
    edges = [e for e in doc.get("edges", []) or [] if isinstance(e, Mapping)]
    types = {str(n["id"]): str(n.get("type", "object")).lower() for n in nodes}
    labels = {str(n["id"]): str(n.get("label", "")) for n in nodes}
    room_of: dict[str, str] = {}
    relations: dict[str, list[Relation]] = {}
    for edge in edges:
        source, target = str(edge.get("source_id")), str(edge.get("target_id"))
        relation = str(edge.get("relation", "")).strip().lower().replace(" ", "_")
        if relation == CONTAINS:
            if types.get(source) == "room" and types.get(target) == "object":
                room_of[target] = labels.get(source, "")
            continue
        if types.get(source) == "object" and target in types:
            relations.setdefault(source, []).append(
                Relation(relation, target, labels.get(target, str(edge.get("target_label", ""))))
            )
    objects: dict[str, GraphObject] = {}
    others: dict[str, str] = {}
    for node in nodes:
        node_id = str(node["id"])
        if types[node_id] != "object":
            others[node_id] = types[node_id]
            continue
        description = node.get("description", "")
        objects[node_id] = GraphObject(
            id=node_id,
            label=str(node.get("label", "")),
            description=str(description or ""),
            xy=_coordinates(node.get("coordinates")),
            z=_height(node.get("coordinates")),
            room=room_of.get(node_id, ""),
            relations=tuple(relations.get(node_id, ())),
        )
    return SceneObjects(objects, others)


def _coordinates(value: Any) -> tuple[float, float] | None:
    """(x, y) from ``[x, y, z]``, ``{"x":, "y":}`` or ``"x, y, z"``; None when unusable."""
    try:
        if isinstance(value, Mapping):
            x, y = float(value["x"]), float(value["y"])
        elif isinstance(value, str):
            parts = [float(p) for p in value.replace("(", " ").replace(")", " ").replace(",", " ").split()]
            x, y = parts[0], parts[1]
        elif isinstance(value, Sequence):
            x, y = float(value[0]), float(value[1])
        else:
            return None
    except (KeyError, IndexError, TypeError, ValueError):
        return None
    return (x, y) if math.isfinite(x) and math.isfinite(y) else None


def _height(value: Any) -> float:
    """The height from ``[x, y, z]`` or ``{"z": ...}``; 0 when absent or unusable."""
    try:
        z = float(value["z"]) if isinstance(value, Mapping) else float(value[2])
    except (KeyError, IndexError, TypeError, ValueError):
        return 0.0
    return z if math.isfinite(z) else 0.0


def prompt_objects(scene: SceneObjects, exclude: Iterable[str] = ()) -> list[dict[str, Any]]:
    """The object list the intent conversation shows the model (ids the model may answer).

    Each entry: ``id``, ``label``, ``attributes`` (colour and size words of the object itself),
    ``description`` (the graph's text, fenced as data by the prompt), ``room``, ``x``/``y`` and
    ``relations`` (``[{"relation", "target", "target_id"}]`` from the graph's edges).
    """
    skip = set(exclude)
    listing: list[dict[str, Any]] = []
    for obj in scene.objects.values():
        if obj.id in skip:
            continue
        entry: dict[str, Any] = {"id": obj.id, "label": obj.label, "attributes": obj.attributes}
        if obj.description:
            entry["description"] = obj.description
        if obj.room:
            entry["room"] = obj.room
        if obj.xy is not None:
            entry["x"], entry["y"] = round(obj.xy[0], 2), round(obj.xy[1], 2)
        if obj.relations:
            entry["relations"] = [
                {"relation": r.relation, "target": r.target_label, "target_id": r.target_id}
                for r in obj.relations
            ]
        listing.append(entry)
    return listing


def look_for(label: str, attributes: Sequence[str] = ()) -> str:
    """What the robot must see on arrival: "grey backpack" (colour and size words, then the label)."""
    known = set(COLOUR_NAMES) | set(ALIASES)
    words = [canonical_colour(a) if a.lower() in known else a.lower() for a in attributes]
    return " ".join([*dict.fromkeys(words), label]).strip()


# -- checks and ranking --------------------------------------------------------------------------------


def plan_candidates(
    ids: Sequence[str],
    scene: SceneObjects,
    grid: OccupancyGrid | None,
    robot: Pose2D,
    robot_radius: float = 0.17,
    doubtful: Iterable[str] = (),
    allow_unknown: bool = False,
    camera: tuple[float, float] | None = None,
) -> Ranking:
    """Check every id the model named and rank the survivors by path length from the robot.

    ``camera`` is (height of the camera, tangent of its view below the optical axis): standoff poses
    are then far enough for the camera to see the object's point (its graph height) on arrival — a
    cup on the floor is out of view right in front of a TurtleBot 4's camera.

    Rejected, each with its reason: ids not in the graph, rooms and the building, objects marked
    doubtful, objects without coordinates, objects outside the known map, objects with no free place
    to stand near them and objects the robot has no path to. Duplicates are dropped. Ties in path
    length keep the model's order.
    """
    wanted, rejected = _graph_checked(ids, scene, doubtful)
    if not wanted:
        return Ranking([], rejected)
    if grid is None:
        return Ranking([], rejected + [Rejection(o.id, "no map to plan on") for o in wanted])
    space = prepare_space(grid, robot_radius, allow_unknown)
    places = _standoff_places(space, wanted, robot_radius, camera, rejected)
    if not places:
        return Ranking([], rejected)
    return _rank_by_path(space, grid, robot, places, rejected)


#: Objects that passed the checks, each with its standoff cells (row, column, penalty).
_Places = list[tuple[GraphObject, list[tuple[int, int, float]]]]


def _graph_checked(
    ids: Sequence[str], scene: SceneObjects, doubtful: Iterable[str]
) -> tuple[list[GraphObject], list[Rejection]]:
    """The graph's checks: the named objects of the graph, not doubted, with coordinates; the rest, why."""
    rejected: list[Rejection] = []
    doubtful_ids = set(doubtful)
    seen: set[str] = set()
    wanted: list[GraphObject] = []
    for raw in ids:
        oid = str(raw)
        if oid in seen:
            continue
        seen.add(oid)
        obj = scene.objects.get(oid)
        if obj is None:
            kind = scene.others.get(oid)
            why = f"is a {kind}, not an object" if kind else "not in the scene graph"
            rejected.append(Rejection(oid, why))
        elif oid in doubtful_ids:
            rejected.append(Rejection(oid, "marked doubtful: not seen there on an earlier look"))
        elif obj.xy is None:
            rejected.append(Rejection(oid, "has no coordinates in the scene graph"))
        else:
            wanted.append(obj)
    return wanted, rejected


def _standoff_places(
    space: Space,
    wanted: Sequence[GraphObject],
    robot_radius: float,
    camera: tuple[float, float] | None,
    rejected: list[Rejection],
) -> _Places:
    """The map's checks: each object inside the known map with free cells to stand by it (else rejected)."""
    places: _Places = []
    for obj in wanted:
        assert obj.xy is not None
        where = outside_known_map(space, obj.xy)
        if where:
            rejected.append(Rejection(obj.id, where))
            continue
        cells = standoff_cells(space, obj.xy, robot_radius, view_distance(camera, obj.z))
        if not cells:
            rejected.append(
                Rejection(
                    obj.id,
                    f"no free place to stand within {MAX_REACH:g} m of its edge "
                    f"at ({obj.xy[0]:.2f}, {obj.xy[1]:.2f})",
                )
            )
            continue
        places.append((obj, cells))
    return places


def _rank_by_path(
    space: Space, grid: OccupancyGrid, robot: Pose2D, places: _Places, rejected: list[Rejection]
) -> Ranking:
    """The objects ordered by path length to their best standoff cell (ties keep the given order).

    Each object's goal is its cell of least path length plus penalty, facing the object; an object
    with no path to any of its cells is rejected.
    """
    lengths = cell_path_lengths(space, robot, [c for _, cells in places for c in cells])
    if lengths is None:
        why = "the robot is outside the map or boxed in: no path"
        return Ranking([], rejected + [Rejection(obj.id, why) for obj, _ in places])
    ranked: list[tuple[float, int, Candidate]] = []
    at = 0
    for order, (obj, cells) in enumerate(places):
        assert obj.xy is not None
        mine = lengths[at : at + len(cells)]
        at += len(cells)
        k = min(range(len(cells)), key=lambda i: mine[i] + cells[i][2])
        length = mine[k]
        if not math.isfinite(length):
            rejected.append(
                Rejection(obj.id, f"no path from the robot to it at ({obj.xy[0]:.2f}, {obj.xy[1]:.2f})")
            )
            continue
        gx, gy = grid.cell_to_world(cells[k][0], cells[k][1])
        goal = Pose2D(gx, gy, math.atan2(obj.xy[1] - gy, obj.xy[0] - gx))
        straight = math.hypot(obj.xy[0] - robot.x, obj.xy[1] - robot.y)
        ranked.append((length, order, Candidate(obj.id, obj.label, obj.xy, goal, length, straight)))
    ranked.sort(key=lambda item: (item[0], item[1]))
    return Ranking([c for _, _, c in ranked], rejected)


def other_viewpoint(
    obj: GraphObject,
    grid: OccupancyGrid,
    robot: Pose2D,
    first: Pose2D,
    robot_radius: float = 0.17,
    allow_unknown: bool = False,
    camera: tuple[float, float] | None = None,
) -> Pose2D | None:
    """A second standoff pose to look at ``obj`` from when the first look (from ``first``) did not see it.

    A detector misses a small object seen edge-on, against a clutter of others or cut by the view's
    edge; another side shows it differently. Among the object's standoff cells (those
    :func:`~missiontree.reasoning.standoff.standoff_cells` gives, far enough for the camera to see its
    height), the reachable one of least path length plus penalty whose bearing from the object
    differs from the first pose's by at least :data:`OTHER_SIDE` is chosen; failing that, one at
    least :data:`OTHER_RANGE` nearer or farther.
    None when there is no such place (then the object is doubted as before).
    """
    if obj.xy is None:
        return None
    space = prepare_space(grid, robot_radius, allow_unknown)
    cells = standoff_cells(space, obj.xy, robot_radius, view_distance(camera, obj.z))
    if not cells:
        return None
    ox, oy = obj.xy
    first_bearing = math.atan2(first.y - oy, first.x - ox)
    first_range = math.hypot(first.x - ox, first.y - oy)
    places = [(grid.cell_to_world(r, c), pen) for r, c, pen in cells]
    aside = [(xy, pen) for xy, pen in places
             if abs(wrap_angle(math.atan2(xy[1] - oy, xy[0] - ox) - first_bearing)) >= OTHER_SIDE]
    if not aside:
        aside = [(xy, pen) for xy, pen in places
                 if abs(math.hypot(xy[0] - ox, xy[1] - oy) - first_range) >= OTHER_RANGE]
    if not aside:
        return None
    lengths = path_lengths(space.costmap, robot, [xy for xy, _ in aside])
    scored = [(float(length) + pen, xy) for (xy, pen), length in zip(aside, lengths, strict=True)
              if length is not None]
    if not scored:
        return None
    _, (gx, gy) = min(scored, key=lambda item: item[0])
    return Pose2D(gx, gy, math.atan2(oy - gy, ox - gx))


def nearest_note(ranking: Ranking, scene: SceneObjects) -> str:
    """A note for the log when the request fits several objects of the same class (ambiguity).

    Every candidate satisfies the request as the model read it ("the chair" with five chairs), so
    the nearest by path is chosen; the note names it and the others.
    """
    if len(ranking.candidates) < 2:
        return ""
    first = ranking.candidates[0]
    same = [c for c in ranking.candidates if c.label == first.label]
    if len(same) < 2:
        return ""
    others = ", ".join(f"{c.id} {c.path_length:.1f} m" for c in same[1:4])
    return (
        f"ambiguous: {len(same)} {first.label}s fit; going to the nearest by path, {first.id} "
        f"({first.path_length:.1f} m; then {others})"
    )


# -- the NAIS reference ----------------------------------------------------------------------------------


def nais_goal(ids: Sequence[str], scene: SceneObjects, robot: Pose2D) -> tuple[str, Pose2D] | None:
    """The NAIS paper's choice: of the model's candidates, the one nearest in a straight line; goal at it.

    Ids the graph lacks are skipped as NAIS skips what it cannot look up; nothing else is checked.
    """
    best: tuple[float, str, Pose2D] | None = None
    for raw in ids:
        obj = scene.objects.get(str(raw))
        if obj is None or obj.xy is None:
            continue
        d = math.hypot(obj.xy[0] - robot.x, obj.xy[1] - robot.y)
        if best is None or d < best[0]:
            yaw = math.atan2(obj.xy[1] - robot.y, obj.xy[0] - robot.x)
            best = (d, obj.id, Pose2D(obj.xy[0], obj.xy[1], yaw))
    return (best[1], best[2]) if best is not None else None


# -- looking on arrival ---------------------------------------------------------------------------------


def match_detection(
    detections: Sequence[Detection],
    label: str,
    frame: RGBDFrame,
    xy: tuple[float, float],
    min_score: float = 0.5,
    position_slack: float = POSITION_SLACK,
) -> tuple[Detection | None, str]:
    """The detection of ``label`` that is the object the graph puts at ``xy``, and a reason when none is.

    A detection is that object only where it shows something at the graph's place: the bearing of
    ``xy`` must fall within the box's bearings, widened by the slack (``position_slack`` plus
    :data:`RANGE_SLACK` a metre of distance: the graph's error and the robot's pose error), and
    the detection placed in the map by its depth must lie within the object's own half-width (as
    measured, at most :data:`MAX_HALF_WIDTH`) plus that slack of ``xy``. A neighbour of the same
    class beside, before or behind the object fails one of the two. Of those that fit, the one
    placed nearest ``xy`` is taken, not the highest-scoring: a neighbour in view must not answer
    for the object. A box with no depth reading is judged by its bearing alone, after any placed.
    """
    want = fold_label(label)
    detections = [d for d in detections if d.score >= min_score]
    same = [d for d in detections if fold_label(d.label) == want]
    if not same:
        seen = sorted({d.label for d in detections})
        return None, f"the detector sees no {label} (it sees {', '.join(seen) or 'nothing'})"
    cam = frame.camera_pose
    distance = math.hypot(xy[0] - cam.x, xy[1] - cam.y)
    slack = position_slack + RANGE_SLACK * distance
    fits: list[tuple[int, float, Detection]] = []
    why = ""
    for d in same:
        side = _beside_box(frame, d, xy, distance)
        if side > slack:
            why = f"a {d.label} {side:.1f} m to the side of where the graph puts it"
            continue
        placed = project(frame, d, method="robust")
        if placed is None:
            fits.append((1, side, d))
            continue
        off = math.hypot(placed.xy[0] - xy[0], placed.xy[1] - xy[1])
        if off > min(placed.size[0] / 2.0, MAX_HALF_WIDTH) + slack:
            where = f"({placed.xy[0]:.1f}, {placed.xy[1]:.1f})"
            why = f"a {d.label} at {where}, {off:.1f} m from where the graph puts it"
            continue
        fits.append((0, off, d))
    if not fits:
        return None, f"the detector sees no {label} where the graph puts it ({why})"
    return min(fits, key=lambda f: (f[0], f[1]))[2], ""


def _beside_box(frame: RGBDFrame, det: Detection, xy: tuple[float, float], distance: float) -> float:
    """How far (m) the point ``xy``, ``distance`` from the camera, lies to the side of the box's bearings."""
    bearing = frame.camera_pose.bearing_to(*xy)
    left = frame.intrinsics.pixel_bearing(det.box[0])
    right = frame.intrinsics.pixel_bearing(det.box[2])
    outside = max(0.0, wrap_angle(bearing - left), wrap_angle(right - bearing))
    return distance * math.sin(min(outside, math.pi / 2.0))


def look_crop(
    image: np.ndarray, box: tuple[float, float, float, float], grow: float = 0.2, fill: int = 128
) -> np.ndarray:
    """The frame with everything outside the detection's box (grown by ``grow`` a side) painted ``fill``.

    The object keeps its place and scale in the frame (a detector finds it as it did in the whole
    frame, where a small cut-out would be too small to see), and nothing else in view — another
    object of the same class in another colour — can answer for it.
    """
    h, w = image.shape[:2]
    x1, y1, x2, y2 = box
    gx, gy = max(x2 - x1, 1.0) * grow, max(y2 - y1, 1.0) * grow
    a, b = int(max(0, math.floor(x1 - gx))), int(max(0, math.floor(y1 - gy)))
    c, d = int(min(w, math.ceil(x2 + gx))), int(min(h, math.ceil(y2 + gy)))
    out = np.full_like(image, fill)
    out[b:d, a:c] = image[b:d, a:c]
    return out
