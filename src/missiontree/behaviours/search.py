"""Object search: scan, colour attention, locate, approach, verify (the object-search report, working).

The vision-language object-search report searches with a state machine IDLE -> MOVING_TO_SCAN ->
SCANNING -> APPROACHING -> VERIFYING -> DONE. Here each state is a leaf a tree composes:

- :class:`ScanRotate`: a full turn in steps with a pause and a fresh camera frame (a look) at each;
  the angle is integrated from the heading's change, so it really turns 360 degrees.
- :class:`ColourAttention`: the report's HSV colour mapper (the target's colour -> HSV class of
  :mod:`missiontree.perception.colour`, present when >= 1 % of the pixels match, the mask's
  centroid -> left / centre / right); with ``wait`` it stays RUNNING until the colour shows, so it
  can interrupt a scan (a Parallel).
- :class:`Locate`: a candidate of the target from what is known — the live semantic map that
  ``BuildSceneGraph`` fuses every frame into (a candidate seen once is not forgotten when the robot
  turns away) or a loaded scene graph — else exploration (the ``Explore`` leaf's frontiers) ordered
  by where the target is likely (:mod:`missiontree.reasoning.search_priors`: a cup -> kitchen first)
  and by the frontiers' gain, until a candidate appears. FAILURE "not found" when the reachable
  space is explored and no candidate is left.
- :class:`Approach`: to a standoff pose facing the candidate (the intent leaf's standoff search on
  the learned map), then a look that measures the object's place from the depth image; when it is
  elsewhere than believed, another step (bounded attempts). ``mode: box_area`` is the report's
  approach: fixed steps toward the detection's bearing, distance from the box's area
  (d = 3.0 * (1 - A_box / A_frame)).
- :class:`Verify`: the vision-language model confirms label and attributes on a close frame (the
  detection where the candidate is, the rest of the frame painted out); the offline stand-in
  measures colour in HSV. A wrong candidate is marked (``search_rejected`` and doubtful in the
  semantic map) and the leaf fails, so the tree goes on searching. ``mode: frame`` is the report's
  verification: the whole frame asked about.

Tick-log events: ``scan_look``, ``colour_attention``, ``search_candidate``, ``search_explored``,
``approach_step``, ``object_found``, ``candidate_rejected``.
"""

from __future__ import annotations

import enum
import math
from dataclasses import replace
from typing import Annotated, Any, Literal

from pydantic import BaseModel, Field

from missiontree.behaviours.explore import Explore
from missiontree.behaviours.intent import _camera_view, find_scene_graph
from missiontree.engine.leaf import Leaf, Status
from missiontree.engine.ports import Input, Output
from missiontree.mapping.exploration import Candidate as Frontier
from missiontree.mapping.exploration import ExplorationPlanner
from missiontree.perception.colour import canonical_colour, find_colour
from missiontree.perception.detectors import detection_job
from missiontree.perception.projection import project
from missiontree.reasoning.calls import CallStatus, ModelCall, model_caller
from missiontree.reasoning.intent import (
    GraphObject,
    SceneObjects,
    graph_objects,
    look_crop,
    match_detection,
    plan_candidates,
)
from missiontree.reasoning.phrases import fold_label
from missiontree.reasoning.prompts import crop_match_prompt
from missiontree.reasoning.schemas import CropMatch
from missiontree.reasoning.search_priors import Target, parse_target, region_score, room_priors
from missiontree.robot.actions import ActionHandle, ActionStatus
from missiontree.types import Detection, Pose2D, RGBDFrame, Tolerance, wrap_angle

#: A goal aborted with the robot this close to it (m) counts as reached (the stack stopped just short).
NEAR_ENOUGH = 0.4
#: Heading error (rad) at which the robot faces the object, and the time allowed to turn (s).
FACING, FACE_TIMEOUT = 0.1, 10.0
#: A rejected candidate rules out instances of its class this close to where it was (m).
REJECT_RADIUS = 0.5
#: Seconds to wait for a camera frame newer than the moment a look began.
FRAME_TIMEOUT = 10.0


def _target(ctx: Any, text: str) -> Target:
    """The target phrase read against the detector's classes (any class when it lists none)."""
    labels = list(getattr(ctx.model("detector"), "labels", None) or []) if ctx is not None else []
    if not labels:
        words = text.split()
        return Target(text=text, label=words[-1] if words else text)
    return parse_target(text, labels)


def _fresh_frame(robot: Any, after: float) -> RGBDFrame | None:
    frame = robot.rgbd()
    return frame if frame is not None and frame.stamp > after else None


def _await_frame(robot: Any, after: float) -> tuple[RGBDFrame | None, str]:
    """A frame newer than ``after``, or None and why not yet: "" (wait on) or a reason to fail."""
    frame = _fresh_frame(robot, after)
    if frame is None and robot.now() - after > FRAME_TIMEOUT:
        return None, f"no camera frame within {FRAME_TIMEOUT:g} s"
    return frame, ""


def _rejected(entries: Any) -> list[dict[str, Any]]:
    return [e for e in entries if isinstance(e, dict)] if isinstance(entries, list) else []


# -- ScanRotate -----------------------------------------------------------------------------------


class ScanRotate(Leaf):
    """Turn a full circle in steps, pausing at each for a look (a camera frame newer than the stop).

    The angle turned is integrated from the heading's change tick by tick. What looks at the frames
    runs beside it (``BuildSceneGraph`` fuses every frame into the semantic map; ``ColourAttention``
    can interrupt the scan in a Parallel).
    """

    class Params(BaseModel):
        steps: int = Field(
            8, ge=1, le=72, description="Stops of the full turn (the report pauses at fixed angles)."
        )
        pause: float = Field(0.6, ge=0, description="Least pause at each stop (s).")
        turn_speed: float = Field(0.9, gt=0, description="Angular speed between stops (rad/s).")
        angle: float = Field(
            2 * math.pi, gt=0, description="Angle to turn in all (rad); a full turn by default."
        )
        timeout: float = Field(60.0, gt=0, description="Fail when the turn is not done in this many s.")
        turned: Annotated[str, Output("degrees turned when the leaf ended", type="float")] = "scan_turned_deg"

    params: Params

    def __init__(self, name: str, params: BaseModel | None = None) -> None:
        super().__init__(name, params)
        self.turned = 0.0
        self.last_yaw = 0.0
        self.started = 0.0
        self.stops = 0
        self.pause_started: float | None = None

    def initialise(self) -> None:
        """Start integrating the heading; the first look is taken before turning."""
        robot = self.context.robot
        stamped = robot.pose()
        if stamped is None:
            raise RuntimeError(f"{self.name}: the robot has no pose yet; wait for localisation")
        self.turned = 0.0
        self.last_yaw = stamped.pose.yaw
        self.started = robot.now()
        self.stops = 0
        self.pause_started = self.started

    def update(self) -> Status:
        """Pause and look at each stop, turn to the next; SUCCESS after the last stop's look."""
        robot = self.context.robot
        p = self.params
        now = robot.now()
        stamped = robot.pose()
        assert stamped is not None
        self.turned += wrap_angle(stamped.pose.yaw - self.last_yaw)
        self.last_yaw = stamped.pose.yaw
        if now - self.started > p.timeout:
            robot.drive(0.0, 0.0)
            self.write("turned", round(math.degrees(self.turned), 1))
            return self.fail(
                f"turned {math.degrees(self.turned):.0f} of {math.degrees(p.angle):.0f} deg "
                f"in {p.timeout:g} s"
            )
        if self.pause_started is not None:
            robot.drive(0.0, 0.0)
            if now - self.pause_started < p.pause or _fresh_frame(robot, self.pause_started) is None:
                return self.running(f"looking at stop {self.stops + 1} of {p.steps + 1}")
            self.emit(
                "scan_look",
                stop=self.stops,
                turned_deg=round(math.degrees(self.turned), 1),
                yaw=round(stamped.pose.yaw, 3),
            )
            self.pause_started = None
            self.stops += 1
            if self.stops > p.steps:
                self.write("turned", round(math.degrees(self.turned), 1))
                return self.succeed(
                    f"scanned: turned {math.degrees(self.turned):.0f} deg, {self.stops} looks"
                )
        step = p.angle / p.steps
        goal = min(p.angle, self.stops * step)
        remaining = goal - self.turned
        if remaining <= 0.03:
            robot.drive(0.0, 0.0)
            self.pause_started = now
            return self.running(f"stop {self.stops + 1}: {math.degrees(self.turned):.0f} deg")
        robot.drive(0.0, min(p.turn_speed, max(0.25, 2.5 * remaining)))
        return self.running(f"turning: {math.degrees(self.turned):.0f} of {math.degrees(p.angle):.0f} deg")

    def terminate(self, new_status: Status) -> None:
        """Stop turning."""
        if self.ctx is not None and new_status == Status.INVALID:
            self.ctx.robot.drive(0.0, 0.0)


# -- ColourAttention ------------------------------------------------------------------------------


class ColourAttention(Leaf):
    """The report's HSV colour mapper: is the target's colour in view, and left, centre or right?

    Present when at least ``min_fraction`` of the frame's pixels have the colour (colour names of
    :mod:`missiontree.perception.colour`). Writes ``{colour, fraction, position, u, v, bearing,
    stamp}`` to the blackboard. SUCCESS when present; otherwise FAILURE, or RUNNING with ``wait``.
    """

    class Params(BaseModel):
        colour: str = Field("", description="Colour to look for; empty: the colour word of `target`.")
        target: str = Field("", description="The target phrase ('red backpack'), read for its colour.")
        min_fraction: float = Field(0.01, gt=0, le=1, description="Share of pixels that makes it present.")
        wait: bool = Field(False, description="Stay RUNNING until the colour shows (interrupts a scan).")
        seen: Annotated[str, Output("where the colour was seen", type="dict")] = "colour_attention"

    params: Params

    def __init__(self, name: str, params: BaseModel | None = None) -> None:
        super().__init__(name, params)
        self.colour = ""
        self.last = -math.inf

    def on_setup(self) -> None:
        """Resolve the colour name (an unknown name fails here, before the first tick)."""
        from missiontree.perception.colour import COLOUR_NAMES
        from missiontree.reasoning.phrases import colour_words

        words = (
            [canonical_colour(self.params.colour)]
            if self.params.colour.strip()
            else colour_words(self.params.target)
        )
        if not words or words[0] not in COLOUR_NAMES:
            raise ValueError(
                f"{self.name}: no known colour in colour={self.params.colour!r} / "
                f"target={self.params.target!r}; known: {', '.join(COLOUR_NAMES)}"
            )
        self.colour = words[0]

    def initialise(self) -> None:
        """Look at frames from now on."""
        self.last = -math.inf

    def update(self) -> Status:
        """Threshold the newest frame for the colour."""
        robot = self.context.robot
        frame = _fresh_frame(robot, self.last)
        if frame is None:
            return self.running(f"waiting for a frame to look for {self.colour}")
        self.last = frame.stamp
        region = find_colour(frame.color, self.colour, self.params.min_fraction)
        if region is None:
            if self.params.wait:
                return self.running(f"no {self.colour} in view")
            return self.fail(f"no {self.colour} in view (under {self.params.min_fraction:.0%} of the pixels)")
        bearing = frame.intrinsics.pixel_bearing(region.centroid[0])
        seen = {
            "colour": region.colour,
            "fraction": round(region.fraction, 4),
            "position": region.position,
            "u": round(region.centroid[0], 1),
            "v": round(region.centroid[1], 1),
            "bearing": round(bearing, 4),
            "yaw": round(frame.camera_pose.yaw + bearing, 4),
            "stamp": frame.stamp,
        }
        self.write("seen", seen)
        self.emit("colour_attention", **seen)
        return self.succeed(f"{region.colour} {region.position} ({region.fraction:.1%} of the frame)")


# -- Locate ---------------------------------------------------------------------------------------


class PriorPlanner(ExplorationPlanner):
    """Exploration candidates re-scored by where the target is likely: score x (1 + weight x prior)."""

    def __init__(self, bias: Any, weight: float, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.bias = bias
        self.weight = weight

    def candidates(self, grid: Any, robot_xy: tuple[float, float]) -> list[Frontier]:
        """The planner's candidates, best first after the prior."""
        found = super().candidates(grid, robot_xy)
        if not found or self.weight <= 0:
            return found
        scored = [replace(c, score=c.score * (1.0 + self.weight * self.bias(c))) for c in found]
        return sorted(scored, key=lambda c: -c.score)


class ResumeExplore(Explore):
    """Explore that resumes where it left off when entered again, and may stop after each goal reached.

    Keeps its visited goals and blacklist across runs of the leaf (a tree that retries does not
    revisit what it saw). With ``max_goals`` it ends SUCCESS after reaching that many goals (the
    report's MOVING_TO_SCAN: one scan point at a time). With ``exhausted_fails`` it ends FAILURE
    "not found" once nothing is left to explore, at once on every later entry.
    """

    class Params(Explore.Params):
        max_goals: int = Field(
            0, ge=0, description="End SUCCESS after reaching this many goals (0: explore all)."
        )
        exhausted_fails: bool = Field(False, description="Nothing left to explore is FAILURE 'not found'.")
        second_chances: int = Field(
            0,
            ge=0,
            description="Times the goals given up as unreachable are tried again once nothing else "
            "is left (a doorway judged too narrow on a half-learned map often is not; costs time "
            "when the target is absent).",
        )

    params: Params

    def __init__(self, name: str, params: BaseModel | None = None) -> None:
        super().__init__(name, params)
        self.kept: ExplorationPlanner | None = None
        self.exhausted = False
        self.reached = 0
        self.chances_used = 0

    def planner_options(self) -> dict[str, Any]:
        """The exploration planner's options from the parameters (as Explore builds its planner)."""
        p = self.params
        return {
            "strategy": p.strategy,
            "footprint_radius": p.footprint_radius,
            "sensor_range": p.sensor_range,
            "min_frontier_m": p.min_frontier_size,
            "cost_rate": p.cost_rate,
        }

    def make_planner(self) -> ExplorationPlanner:
        """The planner kept for the whole mission (subclasses rank its goals)."""
        return ExplorationPlanner(**self.planner_options())

    def initialise(self) -> None:
        """Explore on with what earlier runs of this leaf learned (blacklist, visited goals)."""
        super().initialise()
        if self.kept is None:
            self.kept = self.make_planner()
        self.planner = self.kept
        self.reached = 0

    def emit(self, event: str, **fields: Any) -> None:
        """Send the event; count the goals reached (``explore_reached``)."""
        if event == "explore_reached":
            self.reached += 1
        super().emit(event, **fields)

    def update(self) -> Status:
        """One step of exploration; SUCCESS after ``max_goals`` goals; exhausted -> FAILURE when asked."""
        if self.exhausted and self.params.exhausted_fails:
            return self.fail(f"not found: nothing left to explore ({self.feedback_message})")
        status = super().update()
        if status == Status.SUCCESS and not (self.params.max_goals and self.reached >= self.params.max_goals):
            self.exhausted = True
            if self.params.exhausted_fails:
                return self.fail(f"not found: {self.feedback_message}")
        return status

    def _select(self, now: float, grid: Any, pose: Pose2D) -> Status:
        """Choose the next goal, unless ``max_goals`` goals were reached in this run of the leaf.

        When nothing is left but goals given up as unreachable, they get ``second_chances``.
        """
        if self.params.max_goals and self.reached >= self.params.max_goals:
            return self.succeed(f"reached {self.reached} goal{'s' if self.reached > 1 else ''}")
        status = super()._select(now, grid, pose)
        planner = self.planner
        if (
            status == Status.SUCCESS
            and planner is not None
            and planner.blacklist
            and self.chances_used < self.params.second_chances
        ):
            self.chances_used += 1
            self.emit("explore_second_chance", goals=len(planner.blacklist))
            planner.blacklist.clear()
            return super()._select(now, grid, pose)
        return status


class Locate(ResumeExplore):
    """A candidate of the target: from the semantic map or a loaded graph, else explore where it is likely.

    SUCCESS with ``search_candidate`` written as soon as an object of the target's class that was
    not rejected is known (colour matches first). Otherwise explores (frontiers by gain, weighted by
    the room priors) until one is seen; FAILURE "not found" when no reachable frontier is left.
    """

    class Params(ResumeExplore.Params):
        target: str = Field(description="What to find: colour words and a class ('red backpack').")
        scene_graph: str = Field(
            "", description="A scene graph file (NAIS JSON) whose objects are checked first."
        )
        priors: Literal["offline", "none"] = Field(
            "offline", description="Rank frontiers by where the target is likely (offline priors) or not."
        )
        prior_weight: float = Field(
            2.0, ge=0, description="How much the prior multiplies a frontier's score."
        )
        rejected: Annotated[
            str, Output("candidates rejected so far (emptied when the mission starts)", type="list")
        ] = "search_rejected"
        candidate: Annotated[str, Output("the candidate to approach", type="dict")] = "search_candidate"

    params: Params

    def __init__(self, name: str, params: BaseModel | None = None) -> None:
        super().__init__(name, params)
        self.goal: Target | None = None
        self.file_objects: list[GraphObject] = []
        self.priors: dict[str, float] = {}

    def on_setup(self) -> None:
        """Read the target against the detector's classes and load the graph file, if any."""
        # py_trees' blackboard outlives a mission in the same process (batch runs, benchmarks): the
        # rejected candidates start empty with each mission, never inherited from another one.
        self.write("rejected", [])
        if self.ctx is None:
            return
        self.goal = _target(self.ctx, self.params.target)
        self.priors = room_priors(self.goal.label) if self.params.priors == "offline" else {}
        if self.params.scene_graph:
            from missiontree.semantics.scene_graph import SceneGraph

            graph = SceneGraph.load(find_scene_graph(self.params.scene_graph))
            self.file_objects = list(graph_objects(graph).objects.values())

    def make_planner(self) -> ExplorationPlanner:
        """Frontiers by gain, their scores weighted by the room priors."""
        return PriorPlanner(self._prior, self.params.prior_weight, **self.planner_options())

    def update(self) -> Status:
        """A known candidate ends the leaf; else one step of exploration."""
        found = self._pick(with_mismatch=self.exhausted)
        if found is not None:
            return self._found(found)
        if self.exhausted:
            return self._not_found()
        status = Explore.update(self)
        if status == Status.SUCCESS:
            self.exhausted = True
            self.emit("search_explored", reason=self.feedback_message)
            found = self._pick(with_mismatch=True)
            return self._found(found) if found is not None else self._not_found()
        if status == Status.FAILURE:
            return self.fail(
                f"searching for the {self.goal.text if self.goal else '?'}: {self.failure_reason}"
            )
        return status

    def _found(self, found: dict[str, Any]) -> Status:
        self.write("candidate", found)
        self.emit("search_candidate", **found)
        return self.succeed(
            f"candidate {found['id']} ({found['colour']} {found['label']}) from "
            f"{found['source']} at ({found['x']:.2f}, {found['y']:.2f})"
        )

    def _not_found(self) -> Status:
        assert self.goal is not None
        tried = _rejected(self.read("rejected", []))
        shown = "; ".join(f"{e.get('id')}: {e.get('reason', '')}" for e in tried[:4])
        grid = self.last_grid
        known = ""
        if grid is not None:
            from missiontree.behaviours.explore import _known_area

            known = f", {_known_area(grid):.1f} m^2 known"
        return self.fail(
            f"not found: no {self.goal.text} in the reachable space explored{known}"
            + (f" ({len(tried)} candidates rejected: {shown})" if tried else "")
        )

    # -- candidates -------------------------------------------------------------------------------

    def _pick(self, with_mismatch: bool) -> dict[str, Any] | None:
        """The best known candidate not rejected: colour match first, then unknown colour, then nearest."""
        if self.goal is None:
            return None
        goal = self.goal
        rejected = _rejected(self.read("rejected", []))
        stamped = self.context.robot.pose()
        here = (stamped.pose.x, stamped.pose.y) if stamped is not None else (0.0, 0.0)
        options: list[tuple[int, float, dict[str, Any]]] = []
        scene = getattr(self.ctx, "scene", None)
        instances = getattr(scene, "map", None)
        for inst in list(instances) if instances is not None else []:
            if fold_label(inst.label) != fold_label(goal.label):
                continue
            entry = {
                "id": inst.id,
                "label": inst.label,
                "colour": inst.colour,
                "x": round(inst.position[0], 3),
                "y": round(inst.position[1], 3),
                "z": round(inst.position[2], 3),
                "source": "semantic map",
                "observations": inst.observations,
            }
            options.append(self._ranked(entry, rejected, here, with_mismatch))
        for obj in self.file_objects:
            if obj.xy is None or fold_label(obj.label) != fold_label(goal.label):
                continue
            colours = [c for c in obj.attributes if c in goal.colours] or obj.attributes[:1]
            entry = {
                "id": obj.id,
                "label": obj.label,
                "colour": colours[0] if colours else "unknown",
                "x": obj.xy[0],
                "y": obj.xy[1],
                "z": obj.z,
                "source": "scene graph",
            }
            options.append(self._ranked(entry, rejected, here, with_mismatch))
        options = [o for o in options if o[0] >= 0]
        if not options:
            return None
        return min(options, key=lambda o: (o[0], o[1]))[2]

    def _ranked(
        self,
        entry: dict[str, Any],
        rejected: list[dict[str, Any]],
        here: tuple[float, float],
        with_mismatch: bool,
    ) -> tuple[int, float, dict[str, Any]]:
        assert self.goal is not None
        for r in rejected:
            if r.get("id") == entry["id"] or (
                fold_label(str(r.get("label", ""))) == fold_label(entry["label"])
                and math.hypot(
                    float(r.get("x", math.inf)) - entry["x"], float(r.get("y", math.inf)) - entry["y"]
                )
                < REJECT_RADIUS
            ):
                return -1, 0.0, entry
        colour = canonical_colour(str(entry["colour"]))
        if not self.goal.colours or colour in self.goal.colours:
            rank = 0
        elif colour in ("", "unknown"):
            rank = 1
        else:
            rank = 2 if with_mismatch else -1
        return rank, math.hypot(entry["x"] - here[0], entry["y"] - here[1]), entry

    def _prior(self, frontier: Frontier) -> float:
        """Likelihood of the target beyond a frontier: its room's type and the objects seen near it."""
        if not self.priors:
            return 0.0
        scene = getattr(self.ctx, "scene", None)
        instances = getattr(scene, "map", None)
        seen = [(i.label, i.xy) for i in instances] if instances is not None else []
        room_type = None
        for room in getattr(scene, "rooms", None) or []:
            if _inside(room.polygon, frontier.x, frontier.y):
                room_type = room.type
                break
        return region_score((frontier.x, frontier.y), self.priors, seen, room_type)


def _inside(polygon: Any, x: float, y: float) -> bool:
    """Point in polygon (even-odd rule); False for an empty polygon."""
    pts = [(float(p[0]), float(p[1])) for p in polygon]
    inside = False
    for (x1, y1), (x2, y2) in zip(pts, pts[1:] + pts[:1], strict=True):
        if (y1 > y) != (y2 > y) and x < x1 + (y - y1) * (x2 - x1) / (y2 - y1):
            inside = not inside
    return inside


# -- Approach -------------------------------------------------------------------------------------


class _Step(enum.Enum):
    PLAN = "finding a standoff pose"
    DRIVE = "driving"
    FACE = "turning to face the object"
    FRAME = "waiting for a fresh frame"
    DETECT = "looking with the detector"


class Approach(Leaf):
    """Approach the candidate: a standoff pose facing it, refined by what the depth image shows.

    ``mode: standoff`` (ours): the intent leaf's standoff search on the map (a reachable free pose
    near the object, far enough for the camera to see it), drive, turn to face it, then look: the
    detector finds the class where the candidate is and the depth image places it; when it stands
    more than ``refine_distance`` from where it was believed, the candidate moves there and another
    attempt is made (at most ``max_attempts``). ``mode: box_area`` (the object-search report):
    fixed steps of ``step`` m toward the detection's (or the colour's) bearing, distance from the
    box's area, d = 3.0 * (1 - A_box / A_frame), until d is below ``stop_distance`` or the attempts
    are used up. A candidate that cannot be reached is rejected (``search_rejected``).
    """

    class Params(BaseModel):
        mode: Literal["standoff", "box_area"] = Field(
            "standoff",
            description="standoff: pose facing the object from depth; box_area: the report's steps.",
        )
        target: str = Field("", description="What is searched for (box_area: the class to detect).")
        max_attempts: int = Field(
            3, ge=1, description="Approach steps before giving up refining (or stepping)."
        )
        robot_radius: float = Field(
            0.17, gt=0, description="Footprint radius for standoff poses and paths (m)."
        )
        xy_tolerance: float = Field(0.15, gt=0, description="Distance to the goal that counts as there (m).")
        refine_distance: float = Field(
            0.35,
            gt=0,
            description="Step again when the depth image puts the object this far from the belief (m).",
        )
        goal_timeout: float = Field(120.0, gt=0, description="Give up a goal not reached in this many s.")
        step: float = Field(0.5, gt=0, description="box_area: length of one approach step (m).")
        stop_distance: float = Field(
            0.8, gt=0, description="box_area: stop when the estimated distance is below (m)."
        )
        min_score: float = Field(0.5, ge=0, le=1, description="Detector confidence filter.")
        candidate: Annotated[str, Output("the candidate (its place refined by depth)", type="dict")] = (
            "search_candidate"
        )
        rejected: Annotated[str, Output("candidates rejected so far", type="list")] = "search_rejected"
        colour_seen: Annotated[str, Input("box_area: the colour mapper's sighting", type="dict")] = (
            "colour_attention"
        )

    params: Params

    def __init__(self, name: str, params: BaseModel | None = None) -> None:
        super().__init__(name, params)
        self.goal: Target | None = None
        self._reset()

    def _reset(self) -> None:
        self.step = _Step.PLAN
        self.cand: dict[str, Any] | None = None
        self.call: ModelCall | None = None
        self.handle: ActionHandle | None = None
        self.attempts = 0
        self.started = 0.0
        self.goal_pose: Pose2D | None = None
        self.frame: RGBDFrame | None = None

    def on_setup(self) -> None:
        """Read the target against the detector's classes (box_area needs it)."""
        if self.ctx is not None and self.params.target:
            self.goal = _target(self.ctx, self.params.target)

    def initialise(self) -> None:
        """Take the candidate and start the first step."""
        self._reset()
        value = self.read("candidate")
        self.cand = dict(value) if isinstance(value, dict) else None
        self.started = self.context.robot.now()
        self.step = _Step.PLAN if self.params.mode == "standoff" else _Step.FRAME

    def update(self) -> Status:
        """Advance the current step; each returns at once."""
        if self.params.mode == "standoff" and self.cand is None:
            return self.fail("no candidate to approach (run Locate first)")
        if self.params.mode == "box_area" and self.goal is None:
            return self.fail("box_area needs the target's class: set `target`")
        handlers = {
            _Step.PLAN: self._plan,
            _Step.DRIVE: self._driven,
            _Step.FACE: self._faced,
            _Step.FRAME: self._framed,
            _Step.DETECT: self._detected,
        }
        return handlers[self.step]()

    def terminate(self, new_status: Status) -> None:
        """Cancel the model call and the goal in flight; stop turning."""
        if self.call is not None:
            self.call.cancel()
            self.call = None
        if self.handle is not None:
            self.handle.cancel()
            self.handle = None
        if self.ctx is not None and new_status == Status.INVALID and self.step is _Step.FACE:
            self.ctx.robot.stop()

    # -- standoff (ours) ----------------------------------------------------------------------------

    def _plan(self) -> Status:
        assert self.cand is not None
        robot = self.context.robot
        if self.call is None:
            stamped = robot.pose()
            if stamped is None:
                return self.running("waiting for a pose")
            c = self.cand
            scene = SceneObjects(
                {
                    str(c["id"]): GraphObject(
                        str(c["id"]), str(c["label"]), xy=(c["x"], c["y"]), z=float(c.get("z", 0.0))
                    )
                }
            )
            self.call = model_caller(self.context).submit(
                "planner",
                plan_candidates,
                [str(c["id"])],
                scene,
                robot.occupancy(),
                stamped.pose,
                self.params.robot_radius,
                (),
                False,
                _camera_view(robot.rgbd()),
                provider="search_standoff",
                node=self.name,
            )
            return self.running(_Step.PLAN.value)
        status = self.call.status()
        if not status.done:
            return self.running(_Step.PLAN.value)
        call, self.call = self.call, None
        if status is not CallStatus.SUCCEEDED:
            return self._reject(f"finding a standoff pose failed: {call.error()}")
        ranking = call.result()
        if not ranking.candidates:
            why = ranking.rejected[0].reason if ranking.rejected else "no standoff pose"
            return self._reject(f"cannot be approached: {why}")
        goal = ranking.candidates[0].goal
        self.goal_pose = goal
        self.attempts += 1
        self.started = robot.now()
        self.handle = robot.navigate_to(goal, Tolerance(self.params.xy_tolerance, 0.3))
        self.emit(
            "approach_step",
            mode="standoff",
            attempt=self.attempts,
            object=self.cand["id"],
            x=round(goal.x, 3),
            y=round(goal.y, 3),
            yaw=round(goal.yaw, 3),
            object_x=self.cand["x"],
            object_y=self.cand["y"],
        )
        self.context.mark("goal", goal.x, goal.y, str(self.cand["id"]))
        self.step = _Step.DRIVE
        return self.running(f"to a standoff pose facing {self.cand['id']} (attempt {self.attempts})")

    def _driven(self) -> Status:
        assert self.handle is not None and self.goal_pose is not None
        robot = self.context.robot
        status = self.handle.status()
        if not status.done:
            if robot.now() - self.started > self.params.goal_timeout:
                self.handle.cancel()
                self.handle = None
                return self._after_drive(False, f"not reached within {self.params.goal_timeout:g} s")
            feedback = self.handle.feedback()
            left = f"{feedback.distance_remaining:.1f} m to go" if feedback is not None else status.value
            return self.running(f"approaching: {left}")
        result = self.handle.result()
        self.handle = None
        stamped = robot.pose()
        off = stamped.pose.distance_to(self.goal_pose) if stamped is not None else math.inf
        ok = status is ActionStatus.SUCCEEDED or off <= NEAR_ENOUGH
        why = (
            f"{status.value}: {result.reason if result is not None and result.reason else 'no reason given'}"
        )
        return self._after_drive(ok, why)

    def _after_drive(self, ok: bool, why: str) -> Status:
        if self.params.mode == "box_area":
            self.step = _Step.FRAME
            self.started = self.context.robot.now()
            if self.attempts >= self.params.max_attempts:
                return self.succeed(
                    f"approach steps used up ({self.attempts}); last: {why if not ok else 'reached'}"
                )
            return self.running("looking again after a step")
        if not ok:
            if self.attempts < self.params.max_attempts:
                self.step = _Step.PLAN
                return self.running(f"standoff pose not reached ({why}); trying again")
            return self._reject(f"not reached in {self.attempts} attempts ({why})")
        self.started = self.context.robot.now()
        self.step = _Step.FACE
        return self._faced()

    def _faced(self) -> Status:
        assert self.cand is not None
        robot = self.context.robot
        stamped = robot.pose()
        error = stamped.pose.bearing_to(self.cand["x"], self.cand["y"]) if stamped is not None else 0.0
        if abs(error) > FACING and robot.now() - self.started < FACE_TIMEOUT:
            robot.drive(0.0, max(-1.0, min(1.0, 2.0 * error)))
            return self.running(f"turning to face {self.cand['id']} ({math.degrees(error):.0f} deg)")
        robot.stop()
        self.started = robot.now()
        self.step = _Step.FRAME
        return self.running(_Step.FRAME.value)

    def _framed(self) -> Status:
        frame, late = _await_frame(self.context.robot, self.started)
        if frame is None:
            return self.fail(late) if late else self.running(_Step.FRAME.value)
        self.frame = frame
        self.call = model_caller(self.context).submit(
            "detector",
            detection_job(self.context.model("detector"), frame),
            node=self.name,
            log_success=False,
        )
        self.step = _Step.DETECT
        return self.running(_Step.DETECT.value)

    def _detected(self) -> Status:
        assert self.call is not None and self.frame is not None
        status = self.call.status()
        if not status.done:
            return self.running(_Step.DETECT.value)
        call, self.call = self.call, None
        detections: list[Detection] = call.result() if status is CallStatus.SUCCEEDED else []
        if self.params.mode == "box_area":
            return self._box_step(detections)
        assert self.cand is not None
        found, why = match_detection(
            detections,
            str(self.cand["label"]),
            self.frame,
            (self.cand["x"], self.cand["y"]),
            min_score=self.params.min_score,
        )
        where = project(self.frame, found, method="robust") if found is not None else None
        if where is None:
            return self.succeed(
                f"facing {self.cand['id']} at its standoff pose (not placed by depth: "
                f"{why or 'no depth in its box'})"
            )
        moved = math.hypot(where.xy[0] - self.cand["x"], where.xy[1] - self.cand["y"])
        self.cand.update(x=round(where.xy[0], 3), y=round(where.xy[1], 3), z=round(where.position[2], 3))
        self.write("candidate", dict(self.cand))
        if moved > self.params.refine_distance and self.attempts < self.params.max_attempts:
            self.step = _Step.PLAN
            return self.running(f"the depth image puts it {moved:.2f} m from the belief: another step")
        return self.succeed(f"facing {self.cand['id']} at {where.range:.2f} m (depth image)")

    # -- box area (the report) ----------------------------------------------------------------------

    def _box_step(self, detections: list[Detection]) -> Status:
        assert self.frame is not None and self.goal is not None
        robot = self.context.robot
        frame = self.frame
        k = frame.intrinsics
        mine = [
            d
            for d in detections
            if fold_label(d.label) == fold_label(self.goal.label) and d.score >= self.params.min_score
        ]
        if mine:
            best = max(mine, key=lambda d: d.score)
            area = max(0.0, best.box[2] - best.box[0]) * max(0.0, best.box[3] - best.box[1])
            distance = 3.0 * (1.0 - area / float(k.width * k.height))
            bearing = k.pixel_bearing(best.center[0])
        else:
            seen = self.read("colour_seen")
            if not isinstance(seen, dict) or self.attempts > 0:
                if self.attempts > 0:
                    return self.succeed(f"target out of view after {self.attempts} steps; verifying here")
                return self.fail(f"no {self.goal.label} detected and no colour sighting to approach")
            distance, bearing = 3.0, float(seen.get("yaw", frame.camera_pose.yaw)) - frame.camera_pose.yaw
        if distance <= self.params.stop_distance:
            return self.succeed(f"estimated {distance:.2f} m from the box's area: close enough")
        stamped = robot.pose()
        assert stamped is not None
        pose = stamped.pose
        length = min(self.params.step, distance - self.params.stop_distance)
        heading = pose.yaw + bearing
        goal = Pose2D(pose.x + length * math.cos(heading), pose.y + length * math.sin(heading), heading)
        self.goal_pose = goal
        self.attempts += 1
        self.started = robot.now()
        self.handle = robot.navigate_to(goal, Tolerance(0.2, 0.3))
        self.emit(
            "approach_step",
            mode="box_area",
            attempt=self.attempts,
            x=round(goal.x, 3),
            y=round(goal.y, 3),
            estimated_distance=round(distance, 3),
            bearing=round(bearing, 3),
        )
        self.step = _Step.DRIVE
        return self.running(f"step {self.attempts}: {length:.2f} m toward it (estimated {distance:.2f} m)")

    def _reject(self, reason: str) -> Status:
        if self.cand is not None:
            _mark_rejected(self, self.cand, reason)
        return self.fail(f"{self.cand['id'] if self.cand else 'candidate'}: {reason}")


def _mark_rejected(leaf: Leaf, cand: dict[str, Any], reason: str) -> None:
    """Add a candidate to ``search_rejected`` and mark its instance doubtful in the semantic map."""
    try:
        entries = _rejected(leaf.bb.get(leaf.params.rejected))  # type: ignore[attr-defined]
    except KeyError:
        entries = []
    entry = {
        "id": cand.get("id"),
        "label": cand.get("label"),
        "x": cand.get("x"),
        "y": cand.get("y"),
        "reason": reason,
    }
    leaf.write("rejected", [*entries, entry])
    scene = getattr(leaf.ctx, "scene", None)
    instances = getattr(scene, "map", None)
    oid = str(cand.get("id"))
    if instances is not None and oid in instances and leaf.ctx is not None:
        instances.update(oid, leaf.ctx.robot.now(), announce=True, reason=reason, doubtful=True)
    leaf.emit(
        "candidate_rejected",
        object=oid,
        label=cand.get("label"),
        x=cand.get("x"),
        y=cand.get("y"),
        reason=reason,
    )


# -- Verify ---------------------------------------------------------------------------------------


class Verify(Leaf):
    """The vision-language model confirms the target's class and attributes on a close frame.

    ``mode: crop`` (ours): the detector must see the class where the candidate is (bearing and
    depth), and the model is shown that detection with the rest of the frame painted out, asked
    whether it is the target ("red backpack"); up to ``frames`` frames. ``mode: frame`` (the
    report's verification): the whole frame is asked about. SUCCESS: ``object_found``. A wrong
    candidate is rejected (``search_rejected``, doubtful in the semantic map) and the leaf fails.
    """

    class Params(BaseModel):
        target: str = Field(description="What must be confirmed ('red backpack').")
        mode: Literal["crop", "frame"] = Field(
            "crop",
            description="crop: the detection where the candidate is; frame: the whole frame (the report).",
        )
        frames: int = Field(3, ge=1, le=10, description="Frames to look at before rejecting.")
        min_score: float = Field(0.5, ge=0, le=1, description="Detector confidence for the look.")
        grow: float = Field(
            1.0, ge=0, description="crop: share of the box shown around the detection, a side."
        )
        max_distance: float = Field(
            0.0,
            ge=0,
            description="Reject when the robot ends farther than this from the object (m); 0: no limit.",
        )
        candidate: Annotated[str, Input("the candidate to verify", type="dict")] = "search_candidate"
        rejected: Annotated[str, Output("candidates rejected so far", type="list")] = "search_rejected"
        found: Annotated[str, Output("the object found: id, label, x, y", type="dict")] = "search_found"

    params: Params

    def __init__(self, name: str, params: BaseModel | None = None) -> None:
        super().__init__(name, params)
        self.goal: Target | None = None
        self.cand: dict[str, Any] | None = None
        self.call: ModelCall | None = None
        self.frame: RGBDFrame | None = None
        self.stage = "frame"
        self.looks = 0
        self.started = 0.0
        self.why = ""

    def on_setup(self) -> None:
        """Read the target against the detector's classes."""
        if self.ctx is not None:
            self.goal = _target(self.ctx, self.params.target)

    def initialise(self) -> None:
        """Take the candidate; wait for a frame newer than now."""
        value = self.read("candidate") if self.params.mode == "crop" else None
        self.cand = dict(value) if isinstance(value, dict) else None
        self.call = None
        self.stage = "frame"
        self.looks = 0
        self.why = ""
        self.started = self.context.robot.now()

    def update(self) -> Status:
        """Frame -> detector -> vision-language model, up to ``frames`` looks."""
        if self.goal is None:
            return self.fail("no target to verify")
        if self.params.mode == "crop" and self.cand is None:
            return self.fail("no candidate to verify (run Locate and Approach first)")
        if self.stage == "frame":
            return self._framed()
        assert self.call is not None
        status = self.call.status()
        if not status.done:
            return self.running(f"{'detecting' if self.stage == 'detect' else 'asking the model'}")
        call, self.call = self.call, None
        if status is not CallStatus.SUCCEEDED:
            return self._again(
                f"the {'detector' if self.stage == 'detect' else 'model'} failed: {call.error()}"
            )
        if self.stage == "detect":
            return self._ask(call.result())
        verdict: CropMatch = call.result().value
        if not verdict.matches:
            return self._again(
                f"the vision-language model does not see a {self.goal.wanted}: {verdict.reason}"
            )
        return self._confirmed(verdict)

    def terminate(self, new_status: Status) -> None:
        """Cancel the call in flight."""
        if self.call is not None:
            self.call.cancel()
            self.call = None

    def _framed(self) -> Status:
        frame, late = _await_frame(self.context.robot, self.started)
        if frame is None:
            return self.fail(late) if late else self.running("waiting for a fresh frame")
        self.frame = frame
        self.looks += 1
        if self.params.mode == "frame":
            return self._ask(None)
        self.call = model_caller(self.context).submit(
            "detector",
            detection_job(self.context.model("detector"), frame),
            node=self.name,
            log_success=False,
        )
        self.stage = "detect"
        return self.running("detecting")

    def _ask(self, detections: list[Detection] | None) -> Status:
        assert self.frame is not None and self.goal is not None
        image = self.frame.color
        if detections is not None:
            assert self.cand is not None
            found, why = match_detection(
                detections,
                self.goal.label,
                self.frame,
                (self.cand["x"], self.cand["y"]),
                min_score=self.params.min_score,
            )
            if found is None:
                return self._again(why)
            image = look_crop(self.frame.color, found.box, grow=self.params.grow)
        self.call = model_caller(self.context).ask(
            "vlm", [image], crop_match_prompt(self.goal.wanted), CropMatch, node=self.name
        )
        self.stage = "ask"
        return self.running(f"asking the vision-language model: is it a {self.goal.wanted}?")

    def _again(self, why: str) -> Status:
        self.why = why
        if self.looks < self.params.frames:
            assert self.frame is not None
            self.started = self.frame.stamp
            self.stage = "frame"
            return self.running(f"look {self.looks + 1} of {self.params.frames} ({why})")
        reason = f"{why} (in {self.looks} frames)"
        if self.cand is not None:
            _mark_rejected(self, self.cand, reason)
        return self.fail(f"not the {self.goal.text if self.goal else 'target'}: {reason}")

    def _confirmed(self, verdict: CropMatch) -> Status:
        assert self.goal is not None
        robot = self.context.robot
        stamped = robot.pose()
        cand = self.cand or {}
        distance = bearing = math.nan
        if stamped is not None and "x" in cand:
            distance = math.hypot(cand["x"] - stamped.pose.x, cand["y"] - stamped.pose.y)
            bearing = stamped.pose.bearing_to(cand["x"], cand["y"])
        if self.params.max_distance and distance > self.params.max_distance:
            self.looks = self.params.frames
            return self._again(
                f"confirmed, but {distance:.2f} m away (more than {self.params.max_distance:g} m)"
            )
        found = {
            "id": cand.get("id", ""),
            "label": self.goal.label,
            "x": cand.get("x"),
            "y": cand.get("y"),
            "distance": round(distance, 3) if math.isfinite(distance) else None,
            "bearing_deg": round(math.degrees(bearing), 1) if math.isfinite(bearing) else None,
        }
        self.write("found", found)
        self.emit(
            "object_found",
            target=self.goal.text,
            reason=verdict.reason,
            confidence=verdict.confidence,
            **found,
        )
        where = f" at {distance:.2f} m" if math.isfinite(distance) else ""
        return self.succeed(f"found the {self.goal.text}{where}: {verdict.reason}")
