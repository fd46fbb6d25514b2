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

import cv2
import numpy as np

from missiontree.mapping.planner import Costmap, path_lengths
from missiontree.perception.colour import ALIASES, COLOUR_NAMES, canonical_colour
from missiontree.reasoning.phrases import colour_words, fold_label, size_words, split_relation
from missiontree.types import Detection, OccupancyGrid, Pose2D, RGBDFrame, wrap_angle

#: Relations of the graph that are containment, not spatial relations between objects.
CONTAINS = "contains"
#: Occupancy values at or above this are obstacles (Nav2's map_server threshold, as the simulator plans).
OCCUPIED = 50
#: Extra clearance a standoff pose keeps beyond the robot's radius (m).
STANDOFF_MARGIN = 0.08
#: How far beyond the object's edge a standoff pose may be (m): the robot stands close to what it fetches.
STANDOFF_REACH = 0.5
#: A ray from a standoff pose must reach this close to the object's edge before hitting anything (m).
SIGHT_SLACK = 0.15
#: Metres of path a standoff pose may cost for each metre closer to the object.
NEAR_WEIGHT = 2.0
#: Clearance from other obstacles a standoff pose should have beyond the robot's radius (m), and the
#: metres of path each missing metre of it costs.
CLEAR_WANTED, CLEAR_WEIGHT = 0.25, 4.0
#: Extra distance beyond the camera's lower view limit (m): the camera sits ahead of the base's centre.
VIEW_MARGIN = 0.12
#: An object whose cell and surroundings (this radius, m) are all unknown is outside the known map.
KNOWN_RADIUS = 0.5
#: A second look comes from a side at least this far round the object (rad) ...
OTHER_SIDE = math.radians(60.0)
#: ... or, when the object is seen from one side only, this much nearer or farther (m).
OTHER_RANGE = 0.3


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


@dataclass
class _Space:
    """The map prepared for standoff search and path lengths (cached per map content)."""

    grid: OccupancyGrid
    occupied: np.ndarray  # bool, obstacle cells
    known: np.ndarray  # bool, cells that are not unknown
    clearance: np.ndarray  # float, metres from each cell to the nearest obstacle
    inside: np.ndarray  # float, metres from each obstacle cell to the nearest free cell
    costmap: Costmap  # the planner's inflated costmap (path lengths as the navigation stack drives)


_SPACE_CACHE: dict[tuple[Any, ...], _Space] = {}


def prepare_space(grid: OccupancyGrid, robot_radius: float, allow_unknown: bool = False) -> _Space:
    """Obstacles, clearance and the planner's costmap of ``grid`` for a robot of ``robot_radius``.

    Cached by map content, so a static map is prepared once per process.
    """
    data = np.asarray(grid.data)
    key = (
        data.shape,
        grid.resolution,
        grid.origin.x,
        grid.origin.y,
        round(robot_radius, 4),
        allow_unknown,
        hash(data.tobytes()),
    )
    cached = _SPACE_CACHE.get(key)
    if cached is not None:
        return cached
    res = float(grid.resolution)
    occupied = data >= OCCUPIED
    known = data >= 0
    blocked = occupied | (~known if not allow_unknown else np.zeros_like(occupied))
    clearance = cv2.distanceTransform((~blocked).astype(np.uint8), cv2.DIST_L2, 5) * res
    inside = cv2.distanceTransform(occupied.astype(np.uint8), cv2.DIST_L2, 5) * res
    costmap = Costmap(grid, robot_radius, allow_unknown=allow_unknown)
    space = _Space(grid, occupied, known, clearance, inside, costmap)
    if len(_SPACE_CACHE) > 16:
        _SPACE_CACHE.clear()
    _SPACE_CACHE[key] = space
    return space


def object_extent(space: _Space, xy: tuple[float, float]) -> float:
    """How far the object's footprint reaches from its position (m): 0 when the cell is free."""
    row, col = space.grid.world_to_cell(*xy)
    rows, cols = space.occupied.shape
    if not (0 <= row < rows and 0 <= col < cols) or not space.occupied[row, col]:
        return 0.0
    return float(space.inside[row, col])


def standoff_cells(
    space: _Space, xy: tuple[float, float], robot_radius: float, min_distance: float = 0.0
) -> list[tuple[int, int, float]]:
    """Free cells near the object from which it is in sight: (row, col, penalty in metres).

    A cell qualifies when the robot fits there with a margin, it lies between the object's edge plus
    the robot's radius and :data:`STANDOFF_REACH` beyond, and a ray from it towards the object meets
    no obstacle before coming within :data:`SIGHT_SLACK` of the object's edge (no wall between).
    The penalty, added to the path length when choosing among them, prefers cells close to the
    object (what sits on a table is reached across its edge) and clear of other obstacles (a goal
    hugging a wall makes the navigation stack stop short). ``min_distance`` keeps the robot at
    least that far from the object's position (so that the camera sees down to it).
    """
    grid = space.grid
    res = grid.resolution
    extent = object_extent(space, xy)
    near = max(extent + robot_radius + 0.02, min_distance)
    far = max(extent + robot_radius + STANDOFF_REACH, near + 0.3)
    rows, cols = space.occupied.shape
    r_c, c_c = grid.world_to_cell(*xy)
    span = int(math.ceil(far / res)) + 1
    r0, r1 = max(0, r_c - span), min(rows, r_c + span + 1)
    c0, c1 = max(0, c_c - span), min(cols, c_c + span + 1)
    if r0 >= r1 or c0 >= c1:
        return []
    rr, cc = np.mgrid[r0:r1, c0:c1]
    cx = grid.origin.x + (cc + 0.5) * res
    cy = grid.origin.y + (rr + 0.5) * res
    d = np.hypot(cx - xy[0], cy - xy[1])
    clear = space.clearance[r0:r1, c0:c1]
    ok = (d >= near) & (d <= far) & (clear >= robot_radius + STANDOFF_MARGIN)
    penalty = NEAR_WEIGHT * (d - near) + CLEAR_WEIGHT * np.maximum(0.0, robot_radius + CLEAR_WANTED - clear)
    found: list[tuple[int, int, float]] = []
    for row, col, cost in zip(rr[ok], cc[ok], penalty[ok], strict=True):
        if _in_sight(space, int(row), int(col), xy, extent):
            found.append((int(row), int(col), float(cost)))
    # every other cell each way is enough choice (10 cm at 5 cm cells) and a quarter of the goals to search
    return [c for c in found if c[0] % 2 == 0 and c[1] % 2 == 0] or found


def _in_sight(space: _Space, row: int, col: int, xy: tuple[float, float], extent: float) -> bool:
    grid = space.grid
    x0, y0 = grid.cell_to_world(row, col)
    length = math.hypot(xy[0] - x0, xy[1] - y0)
    steps = max(1, int(length / (grid.resolution * 0.5)))
    for i in range(1, steps + 1):
        t = i / steps
        x, y = x0 + t * (xy[0] - x0), y0 + t * (xy[1] - y0)
        r, c = grid.world_to_cell(x, y)
        if space.occupied[r, c]:
            return (1.0 - t) * length <= extent + SIGHT_SLACK
    return True


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
    if not wanted:
        return Ranking([], rejected)
    if grid is None:
        return Ranking([], rejected + [Rejection(o.id, "no map to plan on") for o in wanted])
    space = prepare_space(grid, robot_radius, allow_unknown)
    places: list[tuple[int, GraphObject, list[tuple[int, int, float]]]] = []
    for order, obj in enumerate(wanted):
        assert obj.xy is not None
        where = _outside_known_map(space, obj.xy)
        if where:
            rejected.append(Rejection(obj.id, where))
            continue
        cells = standoff_cells(space, obj.xy, robot_radius, _view_distance(camera, obj.z))
        if not cells:
            rejected.append(
                Rejection(
                    obj.id,
                    f"no free place to stand within {STANDOFF_REACH:g} m of it "
                    f"at ({obj.xy[0]:.2f}, {obj.xy[1]:.2f})",
                )
            )
            continue
        places.append((order, obj, cells))
    if not places:
        return Ranking([], rejected)
    lengths = cell_path_lengths(space, robot, [c for _, _, cells in places for c in cells])
    if lengths is None:
        why = "the robot is outside the map or boxed in: no path"
        return Ranking([], rejected + [Rejection(obj.id, why) for _, obj, _ in places])
    ranked: list[tuple[float, int, Candidate]] = []
    at = 0
    for order, obj, cells in places:
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
    :func:`standoff_cells` gives, far enough for the camera to see its height), the reachable one of
    least path length plus penalty whose bearing from the object differs from the first pose's by at
    least :data:`OTHER_SIDE` is chosen; failing that, one at least :data:`OTHER_RANGE` nearer or farther.
    None when there is no such place (then the object is doubted as before).
    """
    if obj.xy is None:
        return None
    space = prepare_space(grid, robot_radius, allow_unknown)
    cells = standoff_cells(space, obj.xy, robot_radius, _view_distance(camera, obj.z))
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


def _view_distance(camera: tuple[float, float] | None, z: float) -> float:
    """How far the camera must stand for a point ``z`` high to be in view (0: no camera given)."""
    if camera is None or camera[1] <= 0:
        return 0.0
    height, tan_down = camera
    return max(0.0, (height - z) / tan_down) + VIEW_MARGIN


def cell_path_lengths(
    space: _Space, robot: Pose2D, cells: Sequence[tuple[int, int, float]]
) -> list[float] | None:
    """Path length from the robot to each (row, col) cell (inf: unreachable); None when boxed in.

    One Dijkstra search of :func:`missiontree.mapping.planner.path_lengths` on the planner's costmap,
    so a length is that of the path the navigation stack would plan.
    """
    goals = [space.grid.cell_to_world(r, c) for r, c, _ in cells]
    lengths = path_lengths(space.costmap, robot, goals)
    if goals and all(v is None for v in lengths):
        return None
    return [math.inf if v is None else float(v) for v in lengths]


def _outside_known_map(space: _Space, xy: tuple[float, float]) -> str:
    grid = space.grid
    rows, cols = space.occupied.shape
    row, col = grid.world_to_cell(*xy)
    if not (0 <= row < rows and 0 <= col < cols):
        x0, y0 = grid.origin.x, grid.origin.y
        x1, y1 = x0 + cols * grid.resolution, y0 + rows * grid.resolution
        return (
            f"outside the known map: ({xy[0]:.2f}, {xy[1]:.2f}) is not in "
            f"[{x0:.2f}, {x1:.2f}] x [{y0:.2f}, {y1:.2f}]"
        )
    reach = int(math.ceil(KNOWN_RADIUS / grid.resolution))
    window = space.known[max(0, row - reach) : row + reach + 1, max(0, col - reach) : col + reach + 1]
    if not window.any():
        return f"outside the known map: ({xy[0]:.2f}, {xy[1]:.2f}) lies in unexplored space"
    return ""


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
    bearing_slack: float = math.radians(12.0),
    depth_slack: float = 0.8,
    min_score: float = 0.5,
) -> tuple[Detection | None, str]:
    """The detection of ``label`` where the graph puts the object, and a reason when there is none.

    It must score at least ``min_score``, lie within the object's angular half-width plus
    ``bearing_slack`` of the bearing of ``xy`` from the camera, and where the depth image has a
    reading at its centre, that depth must be within ``depth_slack`` of the object's distance.
    """
    want = fold_label(label)
    detections = [d for d in detections if d.score >= min_score]
    same = [d for d in detections if fold_label(d.label) == want]
    if not same:
        seen = sorted({d.label for d in detections})
        return None, f"the detector sees no {label} (it sees {', '.join(seen) or 'nothing'})"
    cam = frame.camera_pose
    bearing = cam.bearing_to(*xy)
    distance = math.hypot(xy[0] - cam.x, xy[1] - cam.y)
    best: tuple[float, Detection] | None = None
    why = ""
    for d in same:
        u, v = d.center
        off = abs(wrap_angle(frame.intrinsics.pixel_bearing(u) - bearing))
        half = abs(frame.intrinsics.pixel_bearing(d.box[0]) - frame.intrinsics.pixel_bearing(d.box[2])) / 2.0
        if off > half + bearing_slack:
            why = f"a {d.label} {math.degrees(off):.0f} deg off where the graph puts it"
            continue
        depth = _depth_at(frame, d)
        if depth is not None and abs(depth - distance) > depth_slack + 0.3:
            why = f"a {d.label} at {depth:.1f} m, the graph puts it at {distance:.1f} m"
            continue
        if best is None or d.score > best[1].score:
            best = (off, d)
    if best is None:
        return None, f"the detector sees no {label} where the graph puts it ({why})"
    return best[1], ""


def _depth_at(frame: RGBDFrame, det: Detection) -> float | None:
    depth = np.asarray(frame.depth)
    h, w = depth.shape[:2]
    x1, y1, x2, y2 = (int(round(v)) for v in det.box)
    cx, cy = (x1 + x2) // 2, (y1 + y2) // 2
    rx, ry = max(1, (x2 - x1) // 6), max(1, (y2 - y1) // 6)
    patch = depth[max(0, cy - ry) : min(h, cy + ry + 1), max(0, cx - rx) : min(w, cx + rx + 1)]
    valid = patch[np.isfinite(patch) & (patch > 0)]
    return float(np.median(valid)) if valid.size else None


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
