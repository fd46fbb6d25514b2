"""Approach a search candidate: a standoff pose facing it, refined by depth (or the report's box-area steps).

The vision-language object-search report's APPROACHING state moves in small steps toward the detection,
its distance estimated from the box's area (d = 3.0 * (1 - A_box / A_frame)), a bounded number of
attempts; its verdict: "often failing to reach precise target positions". Here (``mode: standoff``)
the robot drives to a standoff pose facing the candidate that the intent leaf's standoff search picks
on the learned map, turns to face it and places it by the depth image. When the navigation stack
cannot reach that pose (on a half-learned map it often lies nearer a wall than the stack allows), the
next attempt asks for more room around the pose and avoids the places that failed (another side of the
object). ``mode: box_area`` is the report's approach, kept as its reference.

Tick-log events: ``approach_step`` (and ``candidate_rejected`` for a candidate no pose of which was reached).
"""

from __future__ import annotations

import enum
import math
from typing import Annotated, Any, Literal

from pydantic import BaseModel, Field

from missiontree.behaviours.intent_look import camera_view
from missiontree.behaviours.search_common import await_frame, mark_rejected, read_target
from missiontree.engine.leaf import Leaf, Status
from missiontree.engine.ports import Input, Output
from missiontree.perception.detectors import detection_job
from missiontree.perception.projection import project
from missiontree.reasoning.calls import CallStatus, ModelCall, model_caller
from missiontree.reasoning.intent import (
    GraphObject,
    SceneObjects,
    match_detection,
    other_viewpoint,
    plan_candidates,
)
from missiontree.reasoning.phrases import fold_label
from missiontree.reasoning.search_priors import Target
from missiontree.robot.actions import ActionHandle, ActionStatus
from missiontree.types import Detection, OccupancyGrid, Pose2D, PoseStamped, RGBDFrame, Tolerance

#: A goal aborted with the robot this close to it (m) counts as reached (the stack stopped just short).
NEAR_ENOUGH = 0.4
#: Heading error (rad) at which the robot faces the object, and the time allowed to turn (s).
FACING, FACE_TIMEOUT = 0.1, 10.0
#: A new standoff pose this close (m) to one the robot failed to reach is the same place.
SAME_PLACE = 0.25


def view_height(cand: dict[str, Any]) -> float:
    """The height the camera must see down to at the standoff pose: the candidate's lower quarter.

    The standoff pose is chosen far enough for the camera to see this point (the intent leaf's
    view distance). Seeing only the object's centre leaves its lower half below the view at the
    nearest such pose, and the detector then misreads the cut-off object (a backpack as a laptop
    or a sofa): with a belief a few decimetres beyond the real object, as positions fused over a
    network can be, Verify then rejected the right object. Three quarters of the object in view
    is enough for the detector and keeps the pose close (the whole of a backpack would need 0.9 m,
    beyond what a search counts as reached). The point is the centre ``z`` less a quarter of the
    ``height`` when the candidate carries one, else half the centre's height.
    """
    z = float(cand.get("z", 0.0) or 0.0)
    height = float(cand.get("height", 0.0) or 0.0)
    if not (math.isfinite(z) and math.isfinite(height)):
        return 0.0
    return max(0.0, z - height / 4.0) if height > 0.0 else max(0.0, z / 2.0)


def standoff_goal(
    obj: GraphObject,
    grid: OccupancyGrid | None,
    robot: Pose2D,
    robot_radius: float,
    camera: tuple[float, float] | None,
    failed: list[Pose2D],
) -> tuple[Pose2D | None, str]:
    """A standoff pose facing ``obj`` (or None and why), away from the poses in ``failed``.

    The nearest reachable standoff pose by path (:func:`missiontree.reasoning.intent.plan_candidates`
    for a robot of ``robot_radius``); when it is one that failed, the reachable pose on another side of
    the object or at another range (:func:`missiontree.reasoning.intent.other_viewpoint`).
    """
    ranking = plan_candidates(
        [obj.id], SceneObjects({obj.id: obj}), grid, robot, robot_radius, (), False, camera
    )
    if not ranking.candidates:
        return None, ranking.rejected[0].reason if ranking.rejected else "no standoff pose"
    goal = ranking.candidates[0].goal
    tried = [f for f in failed if math.hypot(f.x - goal.x, f.y - goal.y) < SAME_PLACE]
    if not tried or grid is None:
        return goal, ""
    other = other_viewpoint(obj, grid, robot, tried[-1], robot_radius, False, camera)
    if other is None or any(math.hypot(f.x - other.x, f.y - other.y) < SAME_PLACE for f in failed):
        return None, f"no standoff pose other than ({goal.x:.2f}, {goal.y:.2f}), which was not reached"
    return other, ""


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
    attempt is made (at most ``max_attempts``). A standoff pose the robot does not reach is
    followed by one with ``clearance_step`` more room around the robot, elsewhere than the poses
    that failed (:func:`standoff_goal`). ``mode: box_area`` (the object-search report): fixed steps
    of ``step`` m toward the detection's (or the colour's) bearing, distance from the box's area,
    d = 3.0 * (1 - A_box / A_frame), until d is below ``stop_distance`` or the attempts are used
    up. A candidate no standoff pose of which was reached is marked ``unreached`` in
    ``search_rejected`` (Locate offers it again once nothing is left to explore).
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
        clearance_step: float = Field(
            0.1,
            ge=0,
            description="After a standoff pose was not reached, the next asks for this much more "
            "room around the robot (m), and another place.",
        )
        xy_tolerance: float = Field(0.15, gt=0, description="Distance to the goal that counts as there (m).")
        refine_distance: float = Field(
            0.35,
            gt=0,
            description="Step again when the depth image puts the object this far from the belief (m).",
        )
        reach: float = Field(
            1.0,
            gt=0,
            description="A standoff goal the stack aborted just short of counts as reached only when "
            "the robot stands within this distance of the candidate (m), else another pose is tried; "
            "and when the depth image places it farther than this, another step is made.",
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
        self.failed: list[Pose2D] = []
        self.why = ""

    def on_setup(self) -> None:
        """Read the target against the detector's classes (box_area needs it)."""
        if self.ctx is not None and self.params.target:
            self.goal = read_target(self.ctx, self.params.target)

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
        if self._past_deadline():
            return self._reject("the search's time ran out before it was reached")
        handlers = {
            _Step.PLAN: self._plan,
            _Step.DRIVE: self._driven,
            _Step.FACE: self._faced,
            _Step.FRAME: self._framed,
            _Step.DETECT: self._detected,
        }
        return handlers[self.step]()

    def _past_deadline(self) -> bool:
        """Whether the candidate's ``deadline`` (robot s, from Locate's time budget) passed on the way to it.

        Checked while planning and driving only: the mission keeps the time to say "not found" rather
        than run into its limit in the middle of an approach.
        """
        deadline = self.cand.get("deadline") if self.cand is not None else None
        if not isinstance(deadline, (int, float)) or self.step not in (_Step.PLAN, _Step.DRIVE):
            return False
        if self.context.robot.now() <= deadline:
            return False
        self._cancel_in_flight()
        return True

    def _cancel_in_flight(self) -> None:
        """Cancel the model call and the navigation goal in flight, if any."""
        if self.call is not None:
            self.call.cancel()
            self.call = None
        if self.handle is not None:
            self.handle.cancel()
            self.handle = None

    def terminate(self, new_status: Status) -> None:
        """Cancel the model call and the goal in flight; stop turning."""
        self._cancel_in_flight()
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
            obj = GraphObject(str(c["id"]), str(c["label"]), xy=(c["x"], c["y"]), z=view_height(c))
            radius = self.params.robot_radius + self.params.clearance_step * len(self.failed)
            self.call = model_caller(self.context).submit(
                "planner",
                standoff_goal,
                obj,
                robot.occupancy(),
                stamped.pose,
                radius,
                camera_view(robot.rgbd()),
                list(self.failed),
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
        goal, why = call.result()
        if goal is None:
            return self._reject(f"cannot be approached: {why}" + (f" ({self.why})" if self.why else ""))
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
        ok = status is ActionStatus.SUCCEEDED or (off <= NEAR_ENOUGH and self._within_reach(stamped))
        why = (
            f"{status.value}: {result.reason if result is not None and result.reason else 'no reason given'}"
        )
        return self._after_drive(ok, why)

    def _within_reach(self, stamped: PoseStamped | None) -> bool:
        """Whether the robot stands within ``reach`` of the candidate (always, in box_area mode)."""
        if self.params.mode == "box_area" or self.cand is None:
            return True
        if stamped is None:
            return False
        away = math.hypot(stamped.pose.x - self.cand["x"], stamped.pose.y - self.cand["y"])
        return away <= self.params.reach

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
            assert self.goal_pose is not None
            self.failed.append(self.goal_pose)
            self.why = why
            if self.attempts < self.params.max_attempts:
                self.step = _Step.PLAN
                return self.running(f"standoff pose not reached ({why}); trying another with more room")
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
        frame, late = await_frame(self.context.robot, self.started)
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
        if self.attempts < self.params.max_attempts:
            if moved > self.params.refine_distance:
                self.step = _Step.PLAN
                return self.running(f"the depth image puts it {moved:.2f} m from the belief: another step")
            if not self._within_reach(self.context.robot.pose()):
                self.step = _Step.PLAN
                return self.running(f"beyond reach ({self.params.reach:g} m) of it: another step")
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
            mark_rejected(self, self.cand, reason, kind="unreached")
        return self.fail(f"{self.cand['id'] if self.cand else 'candidate'}: {reason}")
