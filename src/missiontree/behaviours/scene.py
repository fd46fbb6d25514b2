"""BuildSceneGraph: build the scene graph while the robot explores or patrols, and keep it true.

Runs beside exploration or a patrol (a Parallel) and never finishes by itself. On each new camera
frame that is a new view (``detect_period``, ``view_move``, ``view_turn``:
:class:`~missiontree.semantics.view_gate.ViewGate`) it runs the detector as a model call off the tick
thread, and on its answer the :class:`~missiontree.semantics.builder.SceneBuilder` (NAIS
filters, projection from depth at the frame's instant, fusion that removes what has gone and
moves what has moved); it segments the occupancy map into rooms (or takes the user's polygons),
types the rooms and describes the objects, and rebuilds the graph when it changes.

Where it shows:

- ``context.scene`` — the :class:`~missiontree.semantics.live.LiveScene` (semantic map, rooms,
  latest graph) for later leaves of the same run (intent, search);
- ``<run_dir>/scene_graph.json`` (the NAIS paper's JSON shape), rewritten on every change, and
  ``scene_graph.png`` (the map with rooms, their names and the instances) when the leaf stops; the
  instances and room names are also marked on the run's top-down picture;
- tick-log events: ``scene_graph_changed`` with ``added``, ``moved``, ``removed`` (and ``updated``)
  for every change, and ``scene_graph`` carrying the whole graph on change (at most one a second)
  and at least every ``publish_every`` seconds, which the ROS 2 backend mirrors to ``/scene_graph``
  and a MarkerArray;
- ``<run_dir>/scene_coverage.json`` and a ``scene_graph_explored`` event when the leaf stops: the
  explored share of the robot's own map (known reachable floor against the unknown its frontiers
  still bound, :mod:`~missiontree.semantics.coverage`), so a reader knows how much of the place the
  graph can hold; the share is also in the leaf's running text;
- ``context.scene.doubtful``: places seen a few times that did not become objects (too close, too
  far, too brief), for a second look (``LookAgain``, :mod:`~missiontree.behaviours.scene_look`).

Room types and descriptions come from the vision-language model (``room_types: vlm``,
``describe: vlm``: frames taken in the room with the NAIS room prompt; crops 20 % larger than the
box with the description prompt, both as JSON schemas, never blocking the tick) or from the offline
stand-ins (``objects``: the most probable room type for the objects seen in it and its shape,
:mod:`~missiontree.semantics.room_types`; ``measure``: colour from the
pixels, size from depth), which use only what the robot saw.
"""

from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import BaseModel, Field

from missiontree.engine.leaf import Leaf, Status
from missiontree.engine.ports import Output
from missiontree.perception.detectors import detection_job
from missiontree.perception.tracking import NaisFilterParams
from missiontree.reasoning.calls import CallStatus, ModelCall, model_caller
from missiontree.reasoning.prompts import object_description_prompt, room_prompt
from missiontree.reasoning.providers.offline_scene import measured_description
from missiontree.reasoning.scene_prompts import SemanticRelations, expanded_crop, semantic_relations_messages
from missiontree.reasoning.schemas import ObjectDescription, RoomClassification
from missiontree.semantics.builder import BuilderParams, SceneBuilder
from missiontree.semantics.coverage import Coverage, explored_share
from missiontree.semantics.fusion import FusionParams
from missiontree.semantics.room_types import classify_room
from missiontree.semantics.rooms import RoomRegion, SegmentationParams, load_room_polygons
from missiontree.semantics.semantic_map import Change, Instance
from missiontree.semantics.view_gate import ViewGate

SCENE_GRAPH_FILE = "scene_graph.json"
SCENE_PICTURE_FILE = "scene_graph.png"
#: The explored share when the leaf stops (``explored_share``, areas, open frontiers), as JSON.
SCENE_COVERAGE_FILE = "scene_coverage.json"
#: Least seconds between two ``scene_graph`` events after changes (a burst of changes sends one graph).
PUBLISH_GAP = 1.0
#: Detector calls failing in a row before the leaf fails (a dead detector cannot build a graph).
DETECTOR_FAILURES = 5


class BuildSceneGraph(Leaf):
    """Build the live scene graph (rooms, objects, relations) from the camera; keep it true. Always RUNNING.

    Puts the live scene on ``context.scene``, writes ``scene_graph.json`` in the run directory on
    every change and emits ``scene_graph_changed`` events (added / moved / removed).
    """

    class Params(BaseModel):
        rooms: str = Field(
            "segment",
            description="'segment' the occupancy map at doors and narrow passages, "
            "or a YAML/JSON file of room polygons ({name, type, polygon}).",
        )
        room_types: Literal["objects", "vlm"] = Field(
            "objects", description="Room types from the objects seen in each room (offline) or the VLM."
        )
        describe: Literal["measure", "vlm"] = Field(
            "measure", description="Object descriptions measured (colour, size) or asked of the VLM."
        )
        min_confidence: float = Field(0.7, ge=0, le=1, description="Detector confidence filter (NAIS: 0.7).")
        max_range: float = Field(4.5, gt=0, description="Farthest accepted detection, m (NAIS: 4.5).")
        min_frames: int = Field(10, ge=1, description="Frames before a new object is accepted (NAIS: 10).")
        dedup_radius: float = Field(
            0.5, gt=0, description="Same-label sightings this close are one object, m (NAIS: 0.5)."
        )
        miss_frames: int = Field(
            6, ge=1, description="Frames that should show an object and do not before it is removed."
        )
        depth_method: Literal["centre", "robust"] = Field(
            "centre", description="Depth at the box centre (NAIS) or the box's nearest depth cluster."
        )
        segment_every: float = Field(
            5.0, gt=0, description="Seconds between room segmentations of a changing map."
        )
        refresh: float = Field(5.0, gt=0, description="Seconds between rebuilds while positions are refined.")
        publish_every: float = Field(
            30.0, gt=0, description="Seconds between scene_graph events at most (also sent on every change)."
        )
        room_query_every: float = Field(
            10.0, gt=0, description="room_types vlm: seconds between room questions."
        )
        semantic_relations: bool = Field(
            False, description="Ask the language model (role llm) for semantic relations after each rebuild."
        )
        detector: str = Field("detector", description="Model role of the detector.")
        vlm: str = Field("vlm", description="Model role of the vision-language model.")
        llm: str = Field("llm", description="Model role of the language model.")
        timeout: float = Field(20.0, gt=0, description="Seconds to wait for a model answer.")
        detect_period: float = Field(
            0.0, ge=0, description="Least seconds between two frames the detector looks at "
            "(0: every new frame).")
        view_move: float = Field(
            0.0, ge=0, description="A frame is a new view once the camera moved this far (m) since the last "
            "one looked at, or turned view_turn; others are skipped (0 and 0: every frame).")
        view_turn: float = Field(0.0, ge=0, description="Degrees the camera must turn for a new view.")
        still_period: float = Field(
            1.0, gt=0, description="With view_move/view_turn: most seconds between two frames looked at "
            "while the camera stays still (a still robot still sees what changes).")
        objects: Annotated[str, Output("number of objects in the scene graph", type="int")] = "scene_objects"

    params: Params

    def __init__(self, name: str, params: BaseModel | None = None) -> None:
        super().__init__(name, params)
        self.builder: SceneBuilder | None = None
        self.last_frame = -math.inf
        self.last_publish = -math.inf
        self.changes = 0
        self.frames = 0
        self.skipped = 0
        self.gate = ViewGate()
        #: The detector's call in flight and the frame it looks at (read on a later tick).
        self.detecting: tuple[ModelCall, Any] | None = None
        self.detector_failures = 0
        self.pending: list[tuple[str, str, ModelCall]] = []
        self.room_votes: dict[str, dict[str, float]] = {}
        self.described: set[str] = set()
        self.asked: set[str] = set()
        self.last_room_query = -math.inf
        self.semantic_edges: list[dict[str, Any]] = []
        self.publish_due = False
        self.coverage: Coverage | None = None
        self.last_coverage = -math.inf
        #: The last frame the builder took and its detections (an evaluation's probe reads it after
        #: each tick to give a reference pipeline the very frames the mission's camera produced).
        self.last_input: tuple[Any, list[Any]] | None = None
        #: Wall seconds spent in the builder (frames, rooms, rebuilds): the method's cost per frame.
        self.work_s = 0.0

    # -- lifecycle -------------------------------------------------------------------------------

    def on_setup(self) -> None:
        """Check the models this configuration needs; read the room polygons file if one is given."""
        if self.ctx is None:
            return
        self.ctx.model(self.params.detector)
        if "vlm" in (self.params.room_types, self.params.describe):
            self.ctx.model(self.params.vlm)
        if self.params.semantic_relations:
            self.ctx.model(self.params.llm)
        self._polygons()

    def initialise(self) -> None:
        """Start a fresh builder and put its live scene on the context."""
        p = self.params
        filters = NaisFilterParams(
            min_confidence=p.min_confidence,
            max_range=p.max_range,
            min_frames=p.min_frames,
            candidate_radius=p.dedup_radius,
            dedup_radius=p.dedup_radius,
        )
        params = BuilderParams(
            fusion=FusionParams(filters=filters, associate_radius=p.dedup_radius, miss_frames=p.miss_frames),
            depth_method=p.depth_method,
            segmentation=SegmentationParams(),
            segment_every=p.segment_every,
            refresh=p.refresh,
        )
        self.builder = SceneBuilder(
            params, rooms=self._polygons(), room_typer=self._type_room, describer=self._describe
        )
        self.context.scene = self.builder.scene
        self.last_frame = -math.inf
        self.last_publish = -math.inf
        self.last_input = None
        self.coverage = None
        self.last_coverage = -math.inf
        self.gate = ViewGate(p.detect_period, p.view_move, p.view_turn, p.still_period)
        self.detecting = None
        self.detector_failures = 0

    def update(self) -> Status:
        """Take the newest frame, refresh rooms, rebuild and record what changed."""
        assert self.builder is not None
        robot = self.context.robot
        now = robot.now()
        self._settle(now)
        self._look(robot.rgbd())
        started = time.perf_counter()
        failed = self._collect(now)
        if failed is not None:
            return self.fail(failed)
        pose = robot.pose()
        inside = (pose.pose.x, pose.pose.y) if pose is not None else None
        grid = robot.occupancy()
        self.builder.update_rooms(grid, inside, now)
        if grid is not None and now - self.last_coverage >= self.params.segment_every:
            self.last_coverage = now
            self.coverage = explored_share(grid, inside)
        changes = self.builder.step(now)
        self.work_s += time.perf_counter() - started
        if changes is not None:
            self._record(changes, now)
        since = now - self.last_publish
        if since >= self.params.publish_every or (self.publish_due and since >= PUBLISH_GAP):
            self._publish(now)
        scene = self.builder.scene
        explored = f", {self.coverage.share:.0%} explored" if self.coverage is not None else ""
        return self.running(
            f"{len(scene.map)} objects in {len(scene.rooms)} rooms, {self.changes} changes, "
            f"{self.frames} frames ({self.skipped} skipped as no new view){explored}"
        )

    def terminate(self, new_status: Status) -> None:
        """Cancel model calls; write the final graph and its picture."""
        for _, _, call in self.pending:
            call.cancel()
        self.pending.clear()
        if self.detecting is not None:
            self.detecting[0].cancel()
            self.detecting = None
        if self.builder is None or self.ctx is None:
            return
        self.builder.rebuild(self.context.robot.now())
        self._save()
        self._report_coverage()
        scene = self.builder.scene
        for inst in scene.map:  # the run's top-down picture shows what the robot believes is where
            self.context.mark("scene_object", inst.position[0], inst.position[1], inst.id)
        for room in scene.rooms:
            self.context.mark("scene_room", room.centroid[0], room.centroid[1], f"{room.label} ({room.id})")
        run_dir = self.context.run_dir
        grid = self.context.robot.occupancy()
        if run_dir is not None and grid is not None:
            from missiontree.semantics.draw import draw_scene

            draw_scene(grid, self.builder.scene, Path(run_dir) / SCENE_PICTURE_FILE)

    # -- frames ----------------------------------------------------------------------------------

    def _look(self, frame: Any) -> None:
        """Send a new frame that is a new view to the detector, off the tick thread (one at a time)."""
        if frame is None or frame.stamp <= self.last_frame or self.detecting is not None:
            return
        self.last_frame = frame.stamp
        if not self.gate.due(frame.stamp, frame.camera_pose):
            self.skipped += 1
            return
        self.gate.take(frame.stamp, frame.camera_pose)
        detector = self.context.model(self.params.detector)
        call = model_caller(self.context).submit(
            self.params.detector, detection_job(detector, frame), node=self.name, log_success=False
        )
        self.detecting = (call, frame)

    def _collect(self, now: float) -> str | None:
        """Fuse the detector's answer once it is there; the reason to fail after repeated failures."""
        if self.detecting is None:
            return None
        call, frame = self.detecting
        status = call.status()
        if not status.done:
            return None
        self.detecting = None
        if status is CallStatus.CANCELLED:
            return None
        if status is not CallStatus.SUCCEEDED:
            self.detector_failures += 1
            self.emit("scene_question_failed", question="detect", subject="", error=call.error())
            if self.detector_failures >= DETECTOR_FAILURES:
                return f"the detector failed {self.detector_failures} times in a row: {call.error()}"
            return None
        self.detector_failures = 0
        detections = list(call.result())
        assert self.builder is not None
        self.frames += 1
        self.builder.add_frame(frame, detections)
        self.last_input = (frame, detections)
        self._ask_about(frame, now)
        return None

    # -- outputs ---------------------------------------------------------------------------------

    def _record(self, changes: list[Change], now: float) -> None:
        assert self.builder is not None
        scene = self.builder.scene
        if self.semantic_edges:
            scene.graph.add_relations(self.semantic_edges)
        kinds: dict[str, list[dict[str, Any]]] = {"added": [], "moved": [], "removed": [], "updated": []}
        for change in changes:
            kinds[change.kind].append(change.to_dict())
        structural = any(kinds[k] for k in ("added", "moved", "removed", "updated"))
        self.write("objects", len(scene.graph.objects()))
        self._save()
        if structural:
            self.changes += len(changes)
            self.emit(
                "scene_graph_changed",
                version=scene.version,
                objects=len(scene.map),
                rooms=len(scene.graph.rooms()),
                **kinds,
            )
            self.publish_due = True
            if self.params.semantic_relations:
                self._ask_relations(now)

    def _publish(self, now: float) -> None:
        assert self.builder is not None
        self.last_publish = now
        self.publish_due = False
        self.emit("scene_graph", version=self.builder.scene.version, graph=self.builder.scene.graph.to_dict())

    def _report_coverage(self) -> None:
        """The explored share of the robot's own map as the leaf stops: an event and a file.

        The graph holds only what the camera saw, so its reader needs to know how much of the place
        that was: known reachable floor against the unknown still bounded by frontiers (no truth).
        """
        robot = self.context.robot
        grid = robot.occupancy()
        if grid is None:
            return
        pose = robot.pose()
        self.coverage = explored_share(grid, (pose.pose.x, pose.pose.y) if pose is not None else None)
        figures = self.coverage.to_dict()
        assert self.builder is not None
        scene = self.builder.scene
        self.emit("scene_graph_explored", objects=len(scene.map), rooms=len(scene.rooms), **figures)
        share = figures.get("explored_share")
        self.context.report("scene_graph", {  # summary.json's outcome (and the run's result line)
            **figures, "objects": len(scene.map), "rooms": len(scene.rooms),
            "text": f"scene graph: {len(scene.map)} objects in {len(scene.rooms)} rooms"
                    + (f", {share:.0%} of the place explored (the robot's own map)"
                       if isinstance(share, float) else ""),
        })
        run_dir = self.context.run_dir
        if run_dir is not None:
            import json

            path = Path(run_dir) / SCENE_COVERAGE_FILE
            path.write_text(
                json.dumps({**figures, "objects": len(scene.map), "rooms": len(scene.rooms)}) + "\n",
                encoding="utf-8",
            )

    def _save(self) -> None:
        run_dir = self.context.run_dir
        if run_dir is None or self.builder is None:
            return
        self.builder.scene.graph.save(Path(run_dir) / SCENE_GRAPH_FILE)

    # -- rooms and descriptions ------------------------------------------------------------------

    def _polygons(self) -> list[RoomRegion] | None:
        if self.params.rooms == "segment":
            return None
        return load_room_polygons(self.params.rooms)

    def _type_room(self, room: RoomRegion, labels: list[str]) -> tuple[str, float, list[str]]:
        if self.params.room_types == "vlm":
            votes = self.room_votes.get(room.id, {})
            if not votes:
                return room.type, room.type_confidence, room.evidence
            best = max(sorted(votes), key=lambda t: votes[t])
            total = sum(votes.values())
            return best, votes[best] / total, [f"the VLM ({votes[best]:.1f} of {total:.1f} votes)"]
        known = getattr(self.context.model(self.params.detector), "labels", None)
        answer = classify_room(labels, room.polygon, known)
        return answer.room_type, answer.confidence, answer.evidence

    def _describe(self, inst: Instance) -> tuple[str, str, str] | None:
        if self.params.describe == "vlm" and inst.id in self.described:
            return None  # the VLM's description stands
        measured = measured_description(inst.label, inst.colour, inst.size)
        return measured.description, measured.shape, measured.size

    def _ask_about(self, frame: Any, now: float) -> None:
        """Submit the VLM questions this frame can answer (never waits for them)."""
        assert self.builder is not None
        caller = None
        if self.params.describe == "vlm":
            for inst_id, detection in self.builder.fusion.observed.items():
                if inst_id in self.asked or len(self.pending) >= 2:
                    continue
                inst = self.builder.scene.map.get(inst_id)
                if inst is None:
                    continue
                caller = caller or model_caller(self.context)
                crop = expanded_crop(frame.color, detection.box)
                call = caller.ask(
                    self.params.vlm,
                    [crop],
                    object_description_prompt(inst.label),
                    ObjectDescription,
                    timeout=self.params.timeout,
                    node=self.name,
                )
                self.asked.add(inst_id)
                self.pending.append(("describe", inst_id, call))
        if self.params.room_types == "vlm" and now - self.last_room_query >= self.params.room_query_every:
            seg = self.builder.segmentation
            pose = self.context.robot.pose_at(frame.stamp)
            room = seg.room_at(pose.x, pose.y) if seg is not None and pose is not None else None
            if room is not None:
                caller = caller or model_caller(self.context)
                call = caller.ask(
                    self.params.vlm,
                    [frame.color],
                    room_prompt(),
                    RoomClassification,
                    timeout=self.params.timeout,
                    node=self.name,
                )
                self.last_room_query = now
                self.pending.append(("room", room.id, call))

    def _ask_relations(self, now: float) -> None:
        assert self.builder is not None
        if any(kind == "relations" for kind, _, _ in self.pending):
            return
        caller = model_caller(self.context)
        messages = semantic_relations_messages(self.builder.scene.graph.to_dict())
        call = caller.chat(
            self.params.llm, messages, SemanticRelations, timeout=self.params.timeout, node=self.name
        )
        self.pending.append(("relations", "", call))

    def _settle(self, now: float) -> None:
        """Use the answers that arrived; a failed question is logged and asked again later."""
        assert self.builder is not None
        for entry in list(self.pending):
            kind, key, call = entry
            status = call.status()
            if not status.done:
                continue
            self.pending.remove(entry)
            if status is not CallStatus.SUCCEEDED:
                self.emit("scene_question_failed", question=kind, subject=key, error=call.error())
                self.asked.discard(key)
                continue
            value = call.result().value
            if kind == "describe" and isinstance(value, ObjectDescription) and key in self.builder.scene.map:
                self.described.add(key)
                self.builder.scene.map.update(
                    key,
                    description=value.description
                    or f"a {value.colour} {value.label}, {value.size}, {value.shape}",
                    shape=value.shape,
                    relative_size=value.size,
                )
            elif kind == "room" and isinstance(value, RoomClassification) and value.room_type != "unknown":
                votes = self.room_votes.setdefault(key, {})
                votes[value.room_type] = votes.get(value.room_type, 0.0) + max(value.confidence, 0.1)
            elif kind == "relations" and isinstance(value, SemanticRelations):
                self.semantic_edges = [e.model_dump() for e in value.edges]
                dropped = self.builder.scene.graph.add_relations(self.semantic_edges)
                self.emit("scene_relations_added", edges=len(value.edges) - dropped, dropped=dropped)
                self._save()
