"""Scene-graph rebuild time at 300 objects: missiontree's rebuild beside the previous implementation.

The issue's figure **rebuild_ms_300**: wall-clock milliseconds for
:meth:`~missiontree.semantics.builder.SceneBuilder.rebuild` (relations from geometry, then building
→ rooms → objects with ``contains`` and the relation edges, in the NAIS JSON shape) on 300 objects
of 8 classes, sizes 0.1–1.5 m, spread over 10 rooms of 6 m × 30 m. The target is ≤ 20 ms.

The reference, timed in the same run and alternating with ours repetition by repetition, is the
implementation the project shipped before the rebuild was tuned (kept verbatim below as
:func:`reference_rebuild`: one :class:`Body` per object, facing computed object by object, edges
added through the general checks of ``SceneGraph.add_relations``). The two are compared on the same
work: ours runs with the one rule added since turned off (two objects in different known rooms are
not related, ``RelationParams.same_room_only``), so both build the same edge set, which is checked
before timing (``tests/semantics/test_rebuild_identical.py`` compares them edge for edge too).
Ours with the rule on (the shipped default, fewer edges) is timed beside them and reported apart.
Each repetition's CPU time of the thread is the figure the ratio is taken on; the wall clock is
printed beside it (on a loaded machine it includes time spent waiting for a core: 0.02-5.6 there
while the CPU ratio held).

Run ``python benchmarks/scene_rebuild.py [--repeats N]``: one line per method with min / median /
max, then the ratio, then one JSON object as the last line. ``benchmarks/scene_graph_eval.py``
reports the same figures through :func:`rebuild_figures`.
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import sys
import time
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np
from scipy.spatial import cKDTree

from missiontree.semantics.builder import BuilderParams, SceneBuilder
from missiontree.semantics.relations import Body, RelationParams
from missiontree.semantics.rooms import RoomRegion
from missiontree.semantics.scene_graph import RelationEdge, SceneGraph

LABELS = ("chair", "table", "cup", "bottle", "sofa", "laptop", "backpack", "tv")


def layout(
    objects: int = 300,
    rooms: int = 10,
    seed: int = 0,
    room_width: float = 6.0,
    params: BuilderParams | None = None,
) -> SceneBuilder:
    """A builder (``params``, default ones by default) holding ``objects`` random objects in ``rooms`` rooms.

    The rooms stand side by side, 30 m deep. Objects lie at 0.4 m height with random sizes; each
    is in the room its x falls in. The default arguments are the layout the benchmark times.
    """
    rng = np.random.default_rng(seed)
    builder = SceneBuilder(params)
    builder.scene.rooms = [
        RoomRegion(
            f"room_{k}",
            "office",
            np.array(
                [
                    [k * room_width, 0],
                    [(k + 1) * room_width, 0],
                    [(k + 1) * room_width, 30],
                    [k * room_width, 30],
                ],
                float,
            ),
            room_width * 30.0,
            (k * room_width + room_width / 2, 15),
        )
        for k in range(rooms)
    ]
    smap = builder.scene.map
    for i in range(objects):
        x, y = rng.uniform(0, rooms * room_width), rng.uniform(0, 30)
        smap.add(
            LABELS[i % len(LABELS)],
            (x, y, 0.4),
            0.0,
            size=tuple(rng.uniform(0.1, 1.5, 3)),
            room=f"room_{int(x // room_width)}",
        )
    return builder


# -- the reference: the rebuild as shipped before it was tuned (verbatim, do not "improve") ----------


def reference_rebuild(builder: SceneBuilder) -> SceneGraph:
    """The previous ``SceneBuilder.rebuild`` body: relations, then the graph (the map is not touched)."""
    rooms = builder.scene.rooms
    centres = {r.id: r.centroid for r in rooms}
    objects = list(builder.scene.map)
    relations = _reference_relations(_reference_bodies(objects), centres, builder.params.relations)
    used = {o.room for o in objects}
    shown = [r for r in rooms if r.id in used or r.type != "unknown"]
    return _reference_build(objects, shown, relations)


def _reference_bodies(objects: Sequence[Any]) -> list[Body]:
    out = []
    for o in objects:
        x, y, z = o.position
        w, d, h = getattr(o, "size", (0.0, 0.0, 0.0))
        out.append(
            Body(
                str(o.id),
                float(x),
                float(y),
                float(z),
                max(float(w), 0.05),
                max(float(d), 0.05),
                max(float(h), 0.05),
                getattr(o, "room", None),
            )
        )
    return out


def _reference_relations(
    bodies: Sequence[Body],
    room_centres: Mapping[str, tuple[float, float]] | None = None,
    params: RelationParams | None = None,
) -> list[RelationEdge]:
    p = params or RelationParams()
    n = len(bodies)
    if n < 2:
        return []
    centres = room_centres or {}
    b = sorted(bodies, key=lambda o: o.id)
    table = np.array([(o.x, o.y, o.z, o.w, o.d, o.h) for o in b], dtype=float)
    xy = table[:, :2]
    half = table[:, 3:5] / 2.0
    radius = half.max(axis=1)
    bottom = table[:, 2] - table[:, 5] / 2.0
    top = table[:, 2] + table[:, 5] / 2.0
    area = table[:, 3] * table[:, 4]
    tree = cKDTree(xy)
    pairs = tree.query_pairs(p.near_gap + 2.0 * float(radius.max()), output_type="ndarray")
    if not len(pairs):
        return []
    a, c = pairs[:, 0], pairs[:, 1]
    a_small = (area[a] < area[c]) | ((area[a] == area[c]) & (a > c))
    src = np.where(a_small, a, c)
    anc = np.where(a_small, c, a)
    offset = xy[src] - xy[anc]
    dist = np.hypot(offset[:, 0], offset[:, 1])
    gap = dist - radius[src] - radius[anc]
    keep = gap <= p.near_gap
    src, anc, offset, gap = src[keep], anc[keep], offset[keep], gap[keep]
    order = np.lexsort((anc, gap, src))
    src, anc, offset, gap = src[order], anc[order], offset[order], gap[order]
    first = np.r_[0, np.flatnonzero(np.diff(src)) + 1]
    rank = np.arange(len(src)) - np.repeat(first, np.diff(np.r_[first, len(src)]))
    keep = rank < p.max_per_object
    src, anc, offset, gap = src[keep], anc[keep], offset[keep], gap[keep]
    over = (np.abs(offset[:, 0]) <= half[anc, 0] + p.on_margin) & (
        np.abs(offset[:, 1]) <= half[anc, 1] + p.on_margin
    )
    on = over & (np.abs(bottom[src] - top[anc]) <= p.on_tolerance) & (bottom[src] > 0.05)
    facing = np.zeros((n, 2))
    has_facing = np.zeros(n, bool)
    for j, o in enumerate(b):
        centre = centres.get(o.room) if o.room is not None else None
        if centre is None:
            continue
        fx, fy = centre[0] - o.x, centre[1] - o.y
        norm = math.hypot(fx, fy)
        if norm >= p.min_facing_distance:
            facing[j] = (fx / norm, fy / norm)
            has_facing[j] = True
    f = facing[anc]
    along = offset[:, 0] * f[:, 0] + offset[:, 1] * f[:, 1]
    own_left = -offset[:, 0] * f[:, 1] + offset[:, 1] * f[:, 0]
    relation = np.where(gap <= p.next_gap, "next_to", "near").astype(object)
    sided = has_facing[anc]
    front_back = sided & (np.abs(along) >= p.side_ratio * np.abs(own_left))
    left_right = sided & ~front_back & (np.abs(own_left) >= p.side_ratio * np.abs(along))
    relation[front_back] = np.where(along[front_back] > 0, "in_front_of", "behind")
    relation[left_right] = np.where(own_left[left_right] > 0, "right_of", "left_of")
    relation[on] = "on"
    ids = [o.id for o in b]
    return [
        RelationEdge(ids[i], ids[j], str(r))
        for i, j, r in zip(src.tolist(), anc.tolist(), relation, strict=True)
    ]


def _reference_build(
    objects: Sequence[Any], rooms: Sequence[Any], relations: Sequence[RelationEdge]
) -> SceneGraph:
    label = "Building"
    nodes: list[dict[str, Any]] = [{"id": 0, "type": "building", "label": label, "description": ""}]
    edges: list[dict[str, Any]] = []
    room_labels: dict[str, str] = {}
    for room in rooms:
        nodes.append({"id": room.id, "type": "room", "label": room.label, "description": room.describe()})
        edges.append(
            {
                "source_id": 0,
                "source_label": label,
                "target_id": room.id,
                "target_label": room.label,
                "relation": "contains",
            }
        )
        room_labels[room.id] = room.label
    for obj in objects:
        x, y, z = obj.position
        nodes.append(
            {
                "id": obj.id,
                "type": "object",
                "label": obj.label,
                "description": obj.description or f"a {obj.label}",
                "coordinates": [round(x, 3), round(y, 3), round(z, 3)],
            }
        )
        parent = obj.room if obj.room is not None and obj.room in room_labels else None
        edges.append(
            {
                "source_id": parent if parent is not None else 0,
                "source_label": room_labels[parent] if parent is not None else label,
                "target_id": obj.id,
                "target_label": obj.label,
                "relation": "contains",
            }
        )
    index = {str(n["id"]): n for n in nodes}
    existing = {(str(e["source_id"]), str(e["target_id"]), e["relation"]) for e in edges}
    dropped = []
    for rel in relations:
        source, target = index.get(str(rel.source_id)), index.get(str(rel.target_id))
        edge = {
            "source_id": rel.source_id,
            "source_label": source["label"] if source else "",
            "target_id": rel.target_id,
            "target_label": target["label"] if target else "",
            "relation": str(rel.relation or ""),
        }
        if source is None or target is None or not edge["relation"]:
            dropped.append(edge)
            continue
        key = (str(rel.source_id), str(rel.target_id), edge["relation"])
        if key not in existing:
            existing.add(key)
            edges.append(edge)
    return SceneGraph(nodes=nodes, edges=edges, dropped=dropped)


# -- timing --------------------------------------------------------------------------------------------


def _timed(fn: Callable[[], object]) -> tuple[float, float]:
    """(wall ms, thread CPU ms) of one call."""
    c0, t0 = time.thread_time(), time.perf_counter()
    fn()
    return (time.perf_counter() - t0) * 1000.0, (time.thread_time() - c0) * 1000.0


#: The builder's parameters as the reference worked: no same-room rule (the same edge set).
AS_BEFORE = BuilderParams(relations=RelationParams(same_room_only=False))


def same_edges(builder: SceneBuilder) -> bool:
    """Whether ours (on ``builder``) and the reference build the same nodes and edges, in order."""
    ours, ref = builder.rebuild(0.0), reference_rebuild(builder)
    return ours.edges == ref.edges and ours.nodes == ref.nodes


def measure(repeats: int = 30, warmup: int = 2) -> dict[str, dict[str, list[float]]]:
    """Time ours, the reference and ours as shipped in turn on the 300-object layout; wall and CPU ms.

    ``ours`` and ``reference`` run on one builder with the same-room rule off (the same edges,
    checked first); ``ours_shipped`` on a builder of the same layout with the rule on.

    Raises:
        RuntimeError: The two do not build the same graph (the comparison would not be like for like).
    """
    builder = layout(params=AS_BEFORE)
    if not same_edges(builder):
        raise RuntimeError("ours and the reference build different graphs on the benchmark's layout")
    shipped = layout()
    ours = lambda: builder.rebuild(0.0)  # noqa: E731
    reference = lambda: reference_rebuild(builder)  # noqa: E731
    ours_shipped = lambda: shipped.rebuild(0.0)  # noqa: E731
    methods = [("ours", ours), ("reference", reference), ("ours_shipped", ours_shipped)]
    for _ in range(warmup):
        for _, fn in methods:
            fn()
    out: dict[str, dict[str, list[float]]] = {m: {"wall": [], "cpu": []} for m, _ in methods}
    for k in range(repeats):
        turn = k % len(methods)
        for name, fn in methods[turn:] + methods[:turn]:
            wall, cpu = _timed(fn)
            out[name]["wall"].append(wall)
            out[name]["cpu"].append(cpu)
    return out


def rebuild_times(repeats: int = 15) -> list[float]:
    """Wall-clock ms of ``repeats`` rebuilds of the 300-object layout (ours only)."""
    builder = layout()
    builder.rebuild(0.0)  # warm-up
    return [_timed(lambda: builder.rebuild(0.0))[0] for _ in range(repeats)]


def _mmm(values: list[float]) -> list[float]:
    return [round(min(values), 3), round(statistics.median(values), 3), round(max(values), 3)]


def rebuild_figures(repeats: int = 30, out: Any = None) -> dict[str, Any]:
    """Measure, print one line per method (min / median / max) and the ratio; return the JSON keys.

    Keys: ``rebuild_ms_300`` (median wall ms, ours as shipped), ``rebuild_ms_300_min_median_max``,
    ``rebuild_cpu_ms_300_min_median_max`` (thread CPU time, as shipped), the like-for-like pair's
    ``rebuild_cpu_ms_300_same_edges_min_median_max`` and
    ``rebuild_cpu_ms_300_previous_min_median_max``, and
    ``rebuild_ratio_ours_to_previous_min_median_max`` (per repetition, CPU time, same edges), with
    the wall clock's ratio apart (``..._wall_min_median_max``).
    """
    stream = out if out is not None else sys.stdout
    times = measure(repeats)
    ours, ref, shipped = times["ours"], times["reference"], times["ours_shipped"]
    ratio = [a / max(b, 1e-9) for a, b in zip(ours["cpu"], ref["cpu"], strict=True)]
    ratio_wall = [a / max(b, 1e-9) for a, b in zip(ours["wall"], ref["wall"], strict=True)]
    for name, t in (("ours (same edges)", ours), ("previous", ref), ("ours shipped", shipped)):
        w, c = _mmm(t["wall"]), _mmm(t["cpu"])
        print(
            f"rebuild at 300 objects, {name:17s}: CPU ms min {c[0]:.3f} / median {c[1]:.3f} / "
            f"max {c[2]:.3f}; wall ms {w[0]:.3f} / {w[1]:.3f} / {w[2]:.3f} ({repeats} repetitions, "
            f"order turning)",
            file=stream,
            flush=True,
        )
    r, rw = _mmm(ratio), _mmm(ratio_wall)
    print(f"rebuild ratio ours / previous (CPU, same edges): min {r[0]:.3f} / median {r[1]:.3f} / "
          f"max {r[2]:.3f}; on wall time {rw[0]:.3f} / {rw[1]:.3f} / {rw[2]:.3f}", file=stream)
    return {
        "rebuild_ms_300": round(statistics.median(shipped["wall"]), 3),
        "rebuild_ms_300_min_median_max": _mmm(shipped["wall"]),
        "rebuild_cpu_ms_300_min_median_max": _mmm(shipped["cpu"]),
        "rebuild_cpu_ms_300_same_edges_min_median_max": _mmm(ours["cpu"]),
        "rebuild_cpu_ms_300_previous_min_median_max": _mmm(ref["cpu"]),
        "rebuild_ms_300_previous_min_median_max": _mmm(ref["wall"]),
        "rebuild_ratio_ours_to_previous_min_median_max": r,
        "rebuild_ratio_ours_to_previous_wall_min_median_max": rw,
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=30, help="repetitions of each method (default 30)")
    args = parser.parse_args(argv)
    if args.repeats < 1:
        print("error: --repeats must be at least 1", file=sys.stderr)
        return 2
    print(json.dumps(rebuild_figures(args.repeats)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
