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

For each world the benchmark runs the shipped mission, ``trees/map_scene.yaml`` (``Explore`` with
``look_around`` beside ``BuildSceneGraph``, on an unknown map), through the session as
``missiontree run`` does, until the exploration ends it (or its ``max_duration``). The scores of
``ours`` are those of the mission's own graph. A probe (:class:`SceneEvalProbe`) reads, after every
tick, the frame the mission's ``BuildSceneGraph`` took and the detections the mission's detector gave
it, and hands the same frame and detections to the NAIS reference, so both methods see exactly the
frames the mission's camera produced on the mission's own route:

- ``ours`` -- the mission's :class:`~missiontree.semantics.builder.SceneBuilder`: the NAIS
  filters, fusion that refines, removes what is seen gone and moves what moved, rooms segmented
  from the learned map and typed from the objects seen in them, colours measured in the pixels;
- ``nais`` -- the NAIS paper's pipeline: :class:`~missiontree.perception.tracking.NaisTracker` (its
  filters at the paper's values: confidence 0.7, no dynamic classes, depth at the box centre,
  4.5 m, 10 frames, 0.5 m over the last 100, room-change replacement), the room context from the
  vision-language model on the current frame about once a second (LLaVA's rate in the paper),
  colours from the VLM's description of a crop 20 % larger than the box, and no update once an
  object is confirmed (the paper's stated limit). The models are those of ``--models`` (default
  ``offline``: the shipped detector and the offline VLM stand-in).

After the first pass: **object precision / recall** (same class — the simulator draws desks and
dining tables as tables, so those count as ``table`` — and planar position within 0.5 m, greedy
nearest matching; truth = every object of the detector's classes), **object_recall_in_view**
(recall over the true objects the camera showed with at least 100 pixels within the leaf's
``max_range`` in some frame, from the simulator's visibility log: misses split into objects the
route never showed and objects shown but not put in the graph, :mod:`scene_graph_view`),
**room_accuracy** (matched
objects whose room node is the one paired with their true room; graph rooms and true rooms paired
one to one to agree on the most objects), **room_type_accuracy** (true rooms whose paired node
names their type), **colour_accuracy** (matched objects with the true colour name), and
**relation_precision** (ours: relations between matched objects that also hold between the true
objects, by the same geometry). Each world's row also gives the mission's outcome, robot time and
explored share. Then the **dynamic phase**, driven by the benchmark and not by the mission (the
shipped mission ends when its exploration ends, and exploring a known map again ends at once):
three objects are moved, two removed and one added (``--changes-seed``), then the robot patrols
viewpoints chosen from its own learned map (free cells with room to turn spread over each
segmented room, then near every wall and furniture side: :func:`viewpoints`), turning a full circle
at each, plus a look (face the place, sweep 0.5 rad to each side) from a free cell near every object *its own
graph* holds that no viewpoint is within 2.2 m of, and at the end a look with a clear line of
sight in its map at every place of its graph that no frame of the pass could check (every view of
it occluded: the fusion's own bookkeeping; the route reads the robot's map and graph only);
**changes_reflected** is the share of those six changes the final graph shows (a moved object
found at its new place and nothing of its label at the old, a removed one gone, an added one
found). Every frame of this patrol goes through the mission's own builder (its state as the
mission left it) with the mission's detector, and to the NAIS reference. **rebuild_ms_300**
times rebuilding relations and graph for 300 objects (min / median / max over repetitions),
beside the NAIS reference's rebuild, which is a GPT-4 round trip not timed here.

``--set KEY=VALUE`` (repeatable) gives the mission's params (comparisons on dev).
``--diagnose`` prints each false and missed object of ours with its cause and each change of the
dynamic phase with what the fusion judged at its places (``scene_graph_diagnosis.py``).

Each world is one run of the batch runner (:func:`missiontree.evaluation.run_batch`, the wiring every
evaluation benchmark shares) of the shipped mission with the world and its seed; the probe hands back
the world's figures and what it printed (``--debug``, ``--diagnose``), which are printed here per
world, in order, and aggregated. ``--workers N`` runs worlds on a process pool of N (one world a
task), ``--workers 1`` in this process. A world whose evaluation raised is reported on stderr and
left out (exit 1).

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
from pathlib import Path
from typing import Any

import numpy as np
from scene_eval_route import (  # benchmarks/scene_eval_route.py, beside this script
    Stop,
    add_object,
    free_spot,
    move_object,
    reachable_floor,
    remove_object,
    revisit_points,
    surface_viewpoints,
    viewpoints,
)
from scene_graph_view import PoseTrack, frames_in_view, recall_in_view  # beside this script
from scene_rebuild import rebuild_figures  # benchmarks/scene_rebuild.py, beside this script
from scipy.optimize import linear_sum_assignment

from missiontree.backends.sim.world import World
from missiontree.perception.colour import canonical_colour
from missiontree.perception.projection import project
from missiontree.perception.tracking import NaisTracker
from missiontree.reasoning.prompts import object_description_prompt
from missiontree.reasoning.scene_prompts import expanded_crop
from missiontree.reasoning.schemas import ObjectDescription, RoomClassification
from missiontree.semantics.builder import SceneBuilder
from missiontree.semantics.relations import Body, compute_relations
from missiontree.types import Pose2D, Tolerance

__all__ = ["surface_viewpoints"]  # re-exported for the route's tests

#: Truth labels the simulator draws as another class's prism (the detector's README).
TRUTH_ALIAS = {"desk": "table", "dining table": "table", "coffee table": "table"}
MATCH_RADIUS = 0.5
TURN_SPEED = 0.5
#: Radians swept to each side of a revisited place.
LOOK_SWEEP = 0.5
NAIS_ROOM_PERIOD = 1.0


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


# -- one world: the shipped mission, then the dynamic phase ----------------------------------------------

#: The mission each world runs: the shipped scene-graph mission (Explore + BuildSceneGraph, unknown map).
MISSION = Path(__file__).resolve().parents[1] / "trees" / "map_scene.yaml"


@dataclasses.dataclass(frozen=True)
class EvalOptions:
    """The flags a worker's evaluation needs (picklable, handed to every probe)."""

    changes_seed: int = 7
    debug: bool = False
    single_pass: bool = False
    diagnose: bool = False


def scene_leaf(session: Any) -> Any:
    """The mission's BuildSceneGraph leaf (None when the tree has none)."""
    from missiontree.behaviours.scene import BuildSceneGraph

    for node in session.root.iterate():
        if isinstance(node, BuildSceneGraph):
            return node
    return None


class SceneEvalProbe:
    """Scores one world's run of the shipped mission, in the batch worker.

    After every tick it hands the frame the mission's ``BuildSceneGraph`` took (with the detections
    the mission's detector gave it) to the NAIS reference, so both methods see the same frames. When
    the mission has ended, :meth:`finish` scores the mission's own graph and the reference's against
    the simulator's truth, then runs the dynamic phase (:func:`dynamic_phase`).
    """

    def __init__(self, options: EvalOptions) -> None:
        self.options = options
        self.leaf: Any = None
        self.nais: NaisPipeline | None = None
        self.diag: Any = None
        self.last = -math.inf
        self.frames = 0
        self.wall_nais = 0.0
        self.track = PoseTrack()

    def __getstate__(self) -> dict[str, Any]:
        return {"options": self.options}

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__init__(state["options"])  # type: ignore[misc]

    def on_tick(self, session: Any) -> None:
        """Give the frame the mission's leaf took this tick to the NAIS reference (and the diagnosis)."""
        if self.leaf is None:
            self.leaf = scene_leaf(session)
        if self.leaf is None or self.leaf.builder is None:
            return
        true_pose = session.robot.truth.robot_pose()  # scoring only: which objects were in view
        self.track.record(session.robot.now(), true_pose.x, true_pose.y)
        if self.nais is None:
            self.nais = NaisPipeline(session.models["vlm"])
            if self.options.diagnose:
                from scene_graph_diagnosis import Diagnosis

                builder = self.leaf.builder
                self.diag = Diagnosis(session.robot, _classes(session), builder.params.depth_method)
                self.diag.watch(builder.scene.map, builder.fusion)
        seen = self.leaf.last_input
        if seen is None or seen[0].stamp <= self.last:
            return
        frame, detections = seen
        self.last = frame.stamp
        self.frames += 1
        if self.diag is not None:
            self.diag.frame(frame, detections)
        t0 = time.perf_counter()
        self.nais.add_frame(frame, detections)
        self.wall_nais += time.perf_counter() - t0

    def finish(self, session: Any, result: Any) -> dict[str, Any]:
        """The world's row (``scene_eval``) and its printed lines (``scene_eval_output``)."""
        import io

        name = str(session.request.world)
        seed = int(session.settings["seed"])
        printed = io.StringIO()
        t0 = time.perf_counter()
        try:
            with contextlib.redirect_stdout(printed):
                row = self.evaluate(name, seed, session, result)
        except BaseException:
            sys.stdout.write(printed.getvalue())  # what the world printed before it failed
            sys.stdout.flush()
            raise
        row["eval_wall_s"] = time.perf_counter() - t0
        return {"scene_eval": row, "scene_eval_output": printed.getvalue()}

    def evaluate(self, name: str, seed: int, session: Any, result: Any) -> dict[str, Any]:
        """Score the mission's graph and the reference's, then the dynamic phase; the world's row."""
        if self.leaf is None or self.leaf.builder is None or self.nais is None:
            raise RuntimeError("the mission's BuildSceneGraph never took a frame")
        robot, ours, nais = session.robot, self.leaf.builder, self.nais
        classes = _classes(session)
        ours.rebuild(robot.now())
        world = robot.world
        first = {
            "ours": score_phase(ours_predictions(ours), world, classes),
            "nais": score_phase(nais.predictions(), world, classes),
        }
        rel_good, rel_total = relation_precision(ours, first["ours"], world)
        if self.diag is not None:
            for line in self.diag.report(
                name, first["ours"], world, lambda p, w: on_unknown_object(p, w, classes), truth_label
            ):
                print(line)
        if self.options.debug:
            debug_lines(first, world)
        coverage = self.leaf.coverage.to_dict() if self.leaf.coverage is not None else {}
        mission = {
            "status": result.status.name,
            "sim_s": round(result.duration, 1),
            "explored_share": coverage.get("explored_share"),
        }
        frames = self.frames
        reflected = {"ours": 0, "nais": 0}
        changes: list[dict[str, Any]] = []
        if not self.options.single_pass:
            changes, reflected = dynamic_phase(
                session, ours, nais, classes, first, self.options.changes_seed + seed, self.diag
            )
            if self.options.debug:
                for c in changes:
                    print(
                        f"  change {c['kind']} {c['id']} {c['label']} from {c.get('from')} to {c.get('to')}"
                    )
        out: dict[str, Any] = {
            "world": name,
            "frames": frames,
            "sim_s": robot.now(),
            "mission": mission,
            "changes": len(changes),
            "relations_good": rel_good,
            "relations": rel_total,
            "ms_per_frame": {
                "ours": 1000 * self.leaf.work_s / max(self.leaf.frames, 1),
                "nais": 1000 * self.wall_nais / max(frames, 1),
            },
        }
        in_view = frames_in_view(robot.truth.visibility, self.track, first["ours"]["truths"],
                                 self.leaf.params.max_range)
        for m in ("ours", "nais"):
            s = first[m]
            out[m] = {
                k: s[k]
                for k in ("tp", "pred", "pred_all", "truth", "in_room", "colour_ok", "rooms", "types_ok")
            }
            out[m]["reflected"] = reflected[m]
            out[m]["tp_view"], out[m]["truth_view"] = recall_in_view(s, in_view)
        return out


def _classes(session: Any) -> set[str]:
    """The detector's classes that the graph may hold (not people)."""
    return set(session.models["detector"].labels) - {"person"}


def debug_lines(first: dict[str, Any], world: World) -> None:
    """Print each method's false and missed objects (``--debug``)."""
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


def dynamic_phase(
    session: Any,
    ours: SceneBuilder,
    nais: NaisPipeline,
    classes: set[str],
    first: dict[str, Any],
    rng_seed: int,
    diag: Any,
) -> tuple[list[dict[str, Any]], dict[str, int]]:
    """Change the world (move 3, remove 2, add 1) and patrol once more; the changes and how many each shows.

    The shipped mission ends when its exploration ends, so this phase is driven by the benchmark:
    the robot patrols viewpoints chosen from its own learned map (:func:`viewpoints`) plus a look at
    every place its graph holds an object (:func:`revisit_points`), then a clear-line look at every
    place no frame of the pass could check (the fusion's own bookkeeping). Every frame goes through
    the mission's own ``SceneBuilder`` (its state continued from the mission) with the mission's
    detector, and to the NAIS reference. Nothing of the route reads the simulator's truth.
    """
    robot, detector = session.robot, session.models["detector"]
    world = robot.world
    rng = np.random.default_rng(rng_seed)
    candidates = [
        o
        for o in world.objects
        if o.movable and truth_label(o.label) in classes and o.size[0] * o.size[1] < 0.5 and o.elevation < 0.3
    ]
    rng.shuffle(candidates)
    # objects the robot has seen first (found by either method): a change to an object nobody saw says little
    seen = {id(first[m]["truths"][j]) for m in first for _, j in first[m]["pairs"]}
    candidates.sort(key=lambda o: id(o) not in seen)
    route = viewpoints(robot)
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
    if diag is not None:
        diag.new_phase()
    walker = Patrol(robot, detector, ours, nais, diag)
    pass_start = robot.now()
    walker.patrol(revisit_points(robot, [inst.xy for inst in ours.scene.map], route))
    unchecked = [inst.xy for inst in ours.fusion.unchecked_since(pass_start)]
    if unchecked:
        walker.patrol(revisit_points(robot, unchecked, [], clear_view=True))
    ours.rebuild(robot.now())
    after = {"ours": ours_predictions(ours), "nais": nais.predictions()}
    reflected = {m: sum(change_reflected(after[m], c) for c in changes) for m in after}
    if diag is not None:
        for line in diag.report_changes(str(session.request.world), changes, after["ours"], change_reflected):
            print(line)
    return changes, reflected


class Patrol:
    """The dynamic phase's scripted drive: every new frame to the mission's builder and the reference."""

    def __init__(self, robot: Any, detector: Any, ours: SceneBuilder, nais: NaisPipeline, diag: Any) -> None:
        self.robot, self.detector, self.ours, self.nais, self.diag = robot, detector, ours, nais, diag
        self.last = -math.inf

    def tick(self) -> None:
        """One tenth of a second: the newest frame to both methods, rooms and rebuilds for ours."""
        robot = self.robot
        robot.spin_until(robot.now() + 0.1)
        frame = robot.rgbd()
        if frame is not None and frame.stamp > self.last:
            self.last = frame.stamp
            detections = self.detector.detect(frame.color)
            if self.diag is not None:
                self.diag.frame(frame, detections)
            self.ours.add_frame(frame, detections)
            self.nais.add_frame(frame, detections)
        pose = robot.pose()
        self.ours.update_rooms(robot.occupancy(), (pose.pose.x, pose.pose.y), robot.now())
        self.ours.step(robot.now())

    def turn(self, speed: float, seconds: float) -> None:
        """Turn in place at ``speed`` rad/s for ``seconds`` of robot time."""
        self.robot.drive(0.0, speed)
        end = self.robot.now() + seconds
        while self.robot.now() < end:
            self.tick()
        self.robot.stop()

    def patrol(self, points: list[Stop]) -> None:
        """Go to each stop; a full circle there, or face its place and sweep."""
        robot = self.robot
        for x, y, look in points:
            handle = robot.navigate_to(Pose2D(x, y, 0.0), Tolerance(0.35, 2 * math.pi))
            limit = robot.now() + 90.0
            while not handle.status().done and robot.now() < limit:
                self.tick()
            if not handle.status().done:
                handle.cancel()
            if look is None:
                self.turn(TURN_SPEED, 2 * math.pi / TURN_SPEED)
                continue
            here = robot.pose().pose
            error = math.remainder(math.atan2(look[1] - here.y, look[0] - here.x) - here.yaw, 2 * math.pi)
            self.turn(math.copysign(TURN_SPEED, error), abs(error) / TURN_SPEED)  # face the place
            self.turn(TURN_SPEED, LOOK_SWEEP / TURN_SPEED)
            self.turn(-TURN_SPEED, 2 * LOOK_SWEEP / TURN_SPEED)
            self.turn(TURN_SPEED, LOOK_SWEEP / TURN_SPEED)


def run_worlds(
    worlds: list[tuple[int, str]],
    models: str,
    workers: int,
    options: EvalOptions,
    on_row: Any,
    max_duration: float | None = None,
    params: tuple[tuple[str, str], ...] = (),
) -> list[dict[str, Any]]:
    """Each (seed, world) on the batch runner (a pool of ``workers``, or this process for 1).

    ``on_row(row, printed)`` is called in plan order as rows arrive (a world waits for the ones before
    it). A world whose run did not succeed is reported on stderr and left out. Returns the rows.
    """
    import functools
    import tempfile

    from missiontree.evaluation import BatchPlan, PoolEngine, RunSpec, SerialEngine, run_batch

    specs = [RunSpec(world=name, seed=seed, run_seed=seed, params=params) for seed, name in worlds]
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
                # the mission's own outcome (SUCCESS, FAILURE when exploration ended partial, RUNNING at
                # its max_duration) is in the row; a run without the probe's row raised (ERROR)
                if "scene_eval" in (done.figures or {}):
                    done.figures["scene_eval"]["wall_s"] = done.wall_time_s  # mission and evaluation
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

        request: dict[str, Any] = {"models": models}
        if max_duration is not None:
            request["max_duration"] = max_duration
        plan = BatchPlan(mission=MISSION, runs=specs, request=request)
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
    "object_recall_in_view": ("tp_view", "truth_view"),
    "room_accuracy": ("in_room", "tp"),
    "room_type_accuracy": ("types_ok", "rooms"),
    "colour_accuracy": ("colour_ok", "tp"),
    "changes_reflected": ("reflected", "changes"),
}
#: The figures the dev-test gap and the markdown table show.
HEADLINE = (
    "object_precision",
    "object_recall",
    "object_recall_in_view",
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
            "object_recall_in_view": round(tot["tp_view"] / max(tot["truth_view"], 1), 4),
            "room_accuracy": round(tot["in_room"] / max(tot["tp"], 1), 4),
            "room_type_accuracy": round(tot["types_ok"] / max(tot["rooms"], 1), 4),
            "colour_accuracy": round(tot["colour_ok"] / max(tot["tp"], 1), 4),
            # None without a dynamic phase (--single-pass): no change was made, none measured
            "changes_reflected": round(tot["reflected"] / tot["changes"], 4) if tot["changes"] else None,
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


def _fmt(value: float | None) -> str:
    """A figure with three decimals, or a dash when it was not measured."""
    return "-" if value is None else f"{value:.3f}"


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
            if value is not None and ci is not None and counts is not None:
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
    parser.add_argument("--only", help="comma-separated world names to run (diagnostics)")
    parser.add_argument(
        "--max-duration",
        type=float,
        help="stop each mission after this many robot seconds (smoke runs; default: the mission's own)",
    )
    parser.add_argument("--single-pass", action="store_true", help="skip the dynamic phase (diagnostics)")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                        help="a value for the mission's params (repeatable; comparisons on dev)")
    args = parser.parse_args(argv)
    started = time.perf_counter()
    options = EvalOptions(
        changes_seed=args.changes_seed,
        debug=args.debug,
        single_pass=args.single_pass,
        diagnose=args.diagnose,
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
                mission = row.get("mission", {})
                print(
                    f"{split:4s} {row['world']:22s} {row['wall_s']:5.1f} s wall, {row['sim_s']:5.0f} s sim, "
                    f"mission {mission.get('status')} after {mission.get('sim_s')} s, "
                    f"explored {mission.get('explored_share')}, "
                    f"{row['frames']} frames | ours tp {o['tp']}/{o['pred']} of {o['truth']} "
                    f"({o.get('tp_view')} of {o.get('truth_view')} in view), "
                    f"rooms {o['in_room']}, types {o['types_ok']}/{o['rooms']}, colour {o['colour_ok']}, "
                    f"changes {o['reflected']}/{row['changes']} | "
                    f"nais tp {n['tp']}/{n['pred']}, rooms {n['in_room']}, "
                    f"colour {n['colour_ok']}, changes {n['reflected']}/{row['changes']}",
                    flush=True,
                )

            worlds = [(k, w) for k, (_, w) in enumerate(named)]
            sets = tuple(tuple(kv.split("=", 1)) for kv in args.set)
            rows = run_worlds(worlds, args.models, args.workers, options, show, args.max_duration, sets)
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
                f"{r['object_recall']:.3f} changes {_fmt(r['changes_reflected'])} | nais precision "
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
