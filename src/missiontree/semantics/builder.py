"""From frames to the live scene graph: projection, fusion, rooms, relations, graph.

:class:`SceneBuilder` is the pipeline the ``BuildSceneGraph`` leaf runs and the scene-graph
benchmark measures. Each camera frame with its detections goes through
:func:`~missiontree.perception.projection.project` (depth at the box centre, the camera pose of
the frame's instant), a check of its depth support against the latest map
(:mod:`~missiontree.semantics.plausibility`: a wall boxed as a refrigerator is dropped) and
:class:`~missiontree.semantics.fusion.InstanceFusion` (the NAIS filters,
association, removal and moves). Rooms come from segmenting the occupancy map every
``segment_every`` seconds (or from fixed polygons); each instance is placed in the room holding it,
rooms are typed by an injected ``room_typer`` (the vision-language model's votes, or the offline
stand-in's reasoning over the objects seen there) and instances described by an injected
``describer``; a ``verifier`` (the vision-language model on a crop 20 % larger than the box) may
turn down a candidate before it becomes an instance. The graph is rebuilt at once when something
was added, moved, removed or changed room, and every ``refresh`` seconds while positions are being
refined.

It reads nothing but what it is given: frames, detections, the occupancy map, the robot's
position. This module imports no reasoning (the layers allow only the reverse): model-backed
typing and descriptions are passed in as functions.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from missiontree.perception.projection import DepthMethod, project
from missiontree.semantics.fusion import FusionParams, InstanceFusion, Verifier
from missiontree.semantics.live import LiveScene
from missiontree.semantics.plausibility import SupportParams, plausible
from missiontree.semantics.relations import RelationParams, relations_of
from missiontree.semantics.rooms import (
    RoomRegion,
    RoomTracker,
    Segmentation,
    SegmentationParams,
    polygon_segmentation,
)
from missiontree.semantics.scene_graph import SceneGraph
from missiontree.semantics.semantic_map import Change, Instance
from missiontree.types import Detection, OccupancyGrid, RGBDFrame

#: Metres from an object's middle within which the nearest room floor is its room (at least).
ROOM_REACH = 0.8
#: Metres beyond half an object's footprint within which the nearest room floor is its room.
ROOM_REACH_MARGIN = 0.3
#: Room typer: a room and the labels of the objects seen in it → (type, confidence, evidence).
RoomTyper = Callable[[RoomRegion, list[str]], tuple[str, float, list[str]]]
#: Describer: an instance → (description, shape, relative size), or None to leave it.
Describer = Callable[[Instance], "tuple[str, str, str] | None"]


@dataclass(frozen=True)
class BuilderParams:
    """Parameters of the pipeline.

    Attributes:
        fusion: Filters, association and removal (:class:`~missiontree.semantics.fusion.FusionParams`).
        depth_method: ``centre`` (the NAIS paper's median at the box centre) or ``robust``.
        window: Side of the centre square, pixels.
        segmentation: Room segmentation parameters.
        segment_every: Seconds between re-segmentations of a changing map.
        relations: Relation thresholds.
        refresh: Seconds between rebuilds while only positions are refined.
        support: A projection whose depth support the latest map shows thinner than its class's
            least depth (a wall boxed as a refrigerator) is dropped before fusion
            (:mod:`~missiontree.semantics.plausibility`).
        doubtful_frames: A candidate seen in this many frames that is not an instance is a
            doubtful place (``scene.doubtful``) worth a second look.
    """

    fusion: FusionParams = field(default_factory=FusionParams)
    depth_method: DepthMethod = "centre"
    window: int = 7
    segmentation: SegmentationParams = field(default_factory=SegmentationParams)
    segment_every: float = 5.0
    relations: RelationParams = field(default_factory=RelationParams)
    refresh: float = 5.0
    support: SupportParams = field(default_factory=SupportParams)
    doubtful_frames: int = 3


@dataclass
class BuildTimes:
    """Wall-clock milliseconds spent, per stage (for benchmarks and the run summary)."""

    fusion: list[float] = field(default_factory=list)
    rooms: list[float] = field(default_factory=list)
    rebuild: list[float] = field(default_factory=list)


class SceneBuilder:
    """Frames and detections → the live scene (see module docstring)."""

    def __init__(
        self,
        params: BuilderParams | None = None,
        *,
        rooms: Sequence[RoomRegion] | None = None,
        room_typer: RoomTyper | None = None,
        describer: Describer | None = None,
        verifier: Verifier | None = None,
    ) -> None:
        self.params = params or BuilderParams()
        self.scene = LiveScene()
        self.fusion = InstanceFusion(self.scene.map, self.params.fusion, verifier)
        self.fixed_rooms = list(rooms) if rooms is not None else None
        self.tracker = RoomTracker(self.params.segmentation)
        self.segmentation: Segmentation | None = None
        self.room_typer = room_typer
        self.describer = describer
        self.times = BuildTimes()
        self._grid_stamp = -math.inf
        #: The latest occupancy map given to :meth:`update_rooms` (projections are judged against it).
        self.grid: OccupancyGrid | None = None
        self._last_segment = -math.inf
        self._last_rebuild = -math.inf
        self._last_check = -math.inf
        self._built_from: tuple[object, ...] | None = None
        self._described: dict[str, tuple[object, ...]] = {}
        self._dirty = False
        self._pending: list[Change] = []
        if self.fixed_rooms is not None:
            self.scene.rooms = list(self.fixed_rooms)

    # -- inputs ----------------------------------------------------------------------------------

    def add_frame(self, frame: RGBDFrame, detections: list[Detection]) -> None:
        """Project a frame's detections and fuse them into the semantic map."""
        t0 = time.perf_counter()
        opts = {"method": self.params.depth_method, "window": self.params.window}
        projections = [p for p in (project(frame, d, **opts) for d in detections) if p is not None]  # type: ignore[arg-type]
        projections, thin = plausible(projections, self.grid, self.params.support)
        if thin:
            self.fusion.dropped["thin support"] = self.fusion.dropped.get("thin support", 0) + len(thin)
        self.fusion.process(frame, projections, detections)
        self._dirty = self._dirty or bool(projections)
        self._note_doubtful()
        self.times.fusion.append((time.perf_counter() - t0) * 1000.0)

    def _note_doubtful(self) -> None:
        """Keep ``scene.doubtful`` (see :class:`LiveScene`): new unconfirmed places, less the confirmed.

        A candidate is forgotten after the fusion's ``candidate_memory``; its place stays here, so a
        second look after a long exploration still finds it.
        """
        doubtful = self.scene.doubtful
        radius = self.fusion.params.associate_radius
        for cand in self.fusion.unconfirmed(self.params.doubtful_frames):
            if self._inside_an_instance(cand.x, cand.y):
                continue  # part of an object already known, named another way: a look confirms the confusion
            near = (math.hypot(x - cand.x, y - cand.y) <= radius for b, x, y in doubtful if b == cand.label)
            if not any(near):
                doubtful.append((cand.label, cand.x, cand.y))
        self.scene.doubtful = [
            (lab, x, y)
            for lab, x, y in doubtful
            if not any(i.distance_to(x, y) <= radius for i in self.fusion.instances_labelled(lab))
        ]

    def _inside_an_instance(self, x: float, y: float) -> bool:
        """Whether (x, y) lies within the footprint (half its larger side) of an instance of any label."""
        return any(i.distance_to(x, y) < 0.5 * max(i.size[0], i.size[1]) for i in self.scene.map)

    def update_rooms(
        self, grid: OccupancyGrid | None, inside: tuple[float, float] | None, now: float
    ) -> bool:
        """Segment the map again if it is new and ``segment_every`` has passed; return True if done."""
        if grid is None:
            return False
        self.grid = grid
        if self.fixed_rooms is not None:
            if self.segmentation is None:
                self.segmentation = polygon_segmentation(grid, self.fixed_rooms)
                return True
            return False
        if grid.stamp == self._grid_stamp and self.segmentation is not None:
            return False
        if now - self._last_segment < self.params.segment_every and self.segmentation is not None:
            return False
        previous = self.segmentation.grid if self.segmentation is not None else None
        if (
            previous is not None
            and previous.origin == grid.origin
            and np.array_equal(previous.data, grid.data)
        ):
            self._grid_stamp = grid.stamp  # the same map, stamped anew (a known map): nothing to redo
            self._last_segment = now
            return False
        t0 = time.perf_counter()
        self.tracker.params = self.params.segmentation
        self.segmentation = _segment(self.tracker, grid, inside)
        self.scene.rooms = list(self.segmentation.rooms)
        self._grid_stamp = grid.stamp
        self._last_segment = now
        self._dirty = True
        self.times.rooms.append((time.perf_counter() - t0) * 1000.0)
        return True

    # -- outputs ---------------------------------------------------------------------------------

    def step(self, now: float) -> list[Change] | None:
        """Place instances in rooms, type rooms, describe, rebuild if due; return the changes rebuilt for.

        A change of the map (added, moved, removed, updated) rebuilds at once. Otherwise, while
        frames keep coming, the graph is refreshed every ``refresh`` seconds, and only if what it
        is built from (positions, sizes, colours, descriptions, rooms and their types) differs
        from what the last rebuild used: a robot watching an unchanged scene rebuilds nothing.

        Returns:
            The changes since the last rebuild when the graph was rebuilt now (possibly empty, for a
            refresh), None when it was not.
        """
        self._pending.extend(self.scene.map.drain_changes())
        self._assign_rooms(now)
        self._pending.extend(self.scene.map.drain_changes())
        structural = any(c.kind in ("added", "moved", "removed", "updated") for c in self._pending)
        due = self._dirty and now - self._last_check >= self.params.refresh
        if not (structural or due):
            return None
        self._last_check = now
        self._type_rooms()
        if not structural and self._fingerprint() == self._built_from:
            self._dirty = False
            return None
        self._describe()
        self.rebuild(now)
        self._built_from = self._fingerprint()
        changes, self._pending = self._pending, []
        return changes

    def rebuild(self, now: float) -> SceneGraph:
        """Recompute the relations and the graph from the map and the rooms."""
        t0 = time.perf_counter()
        rooms = self.scene.rooms
        centres = {r.id: r.centroid for r in rooms}
        objects = list(self.scene.map)
        relations = relations_of(objects, centres, self.params.relations)
        used = {o.room for o in objects}
        shown = [r for r in rooms if r.id in used or r.type != "unknown"]
        self.scene.graph = SceneGraph.build(objects, shown, relations)
        self.scene.version += 1
        self.scene.stamp = now
        self._last_rebuild = now
        self._dirty = False
        self._built_from = None  # step() records what it rebuilt from; a direct call is not checked
        self.times.rebuild.append((time.perf_counter() - t0) * 1000.0)
        return self.scene.graph

    # -- internals -------------------------------------------------------------------------------

    def _fingerprint(self) -> tuple[object, ...]:
        """What the graph is built from: each instance's and each room's attributes the graph shows."""
        return (
            tuple(
                (i.id, i.label, i.position, i.size, i.colour, i.room, i.description) for i in self.scene.map
            ),
            tuple(
                (r.id, r.type, r.type_confidence, tuple(r.evidence), r.area, tuple(r.centroid), r.name)
                for r in self.scene.rooms
            ),
        )

    def _assign_rooms(self, now: float) -> None:
        if self.segmentation is None:
            return
        instances = list(self.scene.map)
        if not instances:
            return
        table = np.array([(*i.position[:2], *i.size[:2]) for i in instances], dtype=np.float64)
        # furniture is an obstacle in the map and its middle no room's floor: the room is the one
        # whose floor is nearest, looked for beyond half the object's footprint (a bed's middle
        # lies a metre from any floor)
        reach = np.maximum(ROOM_REACH, 0.5 * table[:, 2:].max(axis=1) + ROOM_REACH_MARGIN)
        for inst, room in zip(instances, self.segmentation.rooms_at(table[:, :2], reach), strict=True):
            room_id = room.id if room is not None else None
            if room_id != inst.room:
                announce = inst.room is not None  # a first room is part of being added
                self.scene.map.update(
                    inst.id, now, announce=announce, room=room_id, reason=f"now in {room_id or 'no room'}"
                )

    def _type_rooms(self) -> None:
        if self.room_typer is None:
            return
        by_room: dict[str, list[str]] = {}
        for inst in self.scene.map:
            if inst.room is not None:
                by_room.setdefault(inst.room, []).append(inst.label)
        for room in self.scene.rooms:
            if self.fixed_rooms is not None and room.type_confidence >= 1.0:
                continue  # typed by the user's file
            room_type, confidence, evidence = self.room_typer(room, by_room.get(room.id, []))
            room.type, room.type_confidence, room.evidence = room_type, confidence, list(evidence)

    def _describe(self) -> None:
        """Describe the instances whose description inputs changed since they were last described.

        A describer answers from the instance (its label, colour, size and what it already says):
        an instance unchanged since its last answer would get the same answer again, so it is not
        asked (measuring 300 descriptions took longer than rebuilding the graph).
        """
        if self.describer is None:
            return
        asked = self._described
        for inst in self.scene.map:
            key = (inst.label, inst.colour, inst.size, inst.description, inst.shape, inst.relative_size)
            if asked.get(inst.id) == key:
                continue
            answer = self.describer(inst)
            if answer is not None:
                description, shape, size = answer
                self.scene.map.update(inst.id, description=description, shape=shape, relative_size=size)
            asked[inst.id] = (
                inst.label,
                inst.colour,
                inst.size,
                inst.description,
                inst.shape,
                inst.relative_size,
            )
        if len(asked) > 2 * len(self.scene.map):
            self._described = {k: v for k, v in asked.items() if k in self.scene.map}


def _segment(tracker: RoomTracker, grid: OccupancyGrid, inside: tuple[float, float] | None) -> Segmentation:
    """Segment with the tracker (stable ids), passing the point inside the building."""
    return tracker.update(grid, inside)
