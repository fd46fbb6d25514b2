"""The approach as steps a tree sequences: plan a standoff pose, drive to it, face the object.

The shared subtree ``trees/subtrees/approach_confirm.yaml`` runs them in a ``Retry``, each a node of
its own in the tick log and the viewer:

- :class:`PlanStandoff`: a reachable standoff pose facing the object, far enough for the camera to
  see its lower part (:func:`standoff_goal`, over the intent helpers' standoff search), away from the
  poses that failed; every failed pose asks for ``clearance_step`` more room around the robot. A
  candidate that carries its ``goal`` (the intent's ranking planned one) is driven to that first.
- :class:`DriveToStandoff`: the navigation goal (``goal_sent``); a goal the stack aborted just short
  of counts as reached only within ``reach`` of the object.
- :class:`FaceTarget`: turn in place until the object is straight ahead.

The attempts of one approach are the blackboard list ``tries`` (the subtree empties it first): one
entry per standoff pose tried (``x``, ``y``, ``yaw``, ``reached``, ``why``; ``looked``: a place looked
from without confirming it, see :mod:`~missiontree.behaviours.confirm_steps`), and an entry with
``stop`` when the approach is over whatever the ``Retry`` has left (no pose, the time ran out): the
steps then fail at once with that reason. A candidate given up is marked ``unreached`` in
``search_rejected`` (the search's :func:`~missiontree.behaviours.search_common.mark_rejected`).

Tick-log events: ``approach_step``, ``goal_sent``, ``goal_result``, ``candidate_rejected``.
"""

from __future__ import annotations

import math
from typing import Annotated, Any, Literal

from pydantic import BaseModel, Field

from missiontree.behaviours.background import Background, waits
from missiontree.behaviours.motion import GoalLeaf
from missiontree.behaviours.search_common import RejectKind, mark_rejected
from missiontree.engine.leaf import Leaf, Status
from missiontree.engine.ports import Input, Output
from missiontree.reasoning.intent import GraphObject, SceneObjects, other_viewpoint, plan_candidates
from missiontree.robot.actions import ActionStatus
from missiontree.types import OccupancyGrid, Pose2D, PoseStamped, RGBDFrame, Tolerance

#: A goal aborted with the robot this close to it (m) counts as reached (the stack stopped just short).
NEAR_ENOUGH = 0.4
#: A new standoff pose this close (m) to one the robot failed to reach is the same place.
SAME_PLACE = 0.25


def camera_view(frame: RGBDFrame | None) -> tuple[float, float] | None:
    """(camera height, tangent of the view below its axis) from a frame, None before the first frame."""
    if frame is None:
        return None
    k = frame.intrinsics
    return frame.camera_height, (k.height - k.cy) / k.fy


def view_height(cand: dict[str, Any]) -> float:
    """The height the camera must see down to at the standoff pose: the candidate's lower quarter.

    Seeing only the object's centre leaves its lower half below the view at the nearest pose, and
    the detector then misreads the cut-off object (a backpack as a laptop): with a belief a few
    decimetres beyond the real object the right object was rejected. Three quarters in view is
    enough for the detector and keeps the pose close. The point is the centre ``z`` less a quarter of
    the ``height`` when the candidate carries one, else half the centre's height.
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
    looked: tuple[Pose2D, ...] = (),
) -> tuple[Pose2D | None, str]:
    """A standoff pose facing ``obj`` (or None and why), away from the poses in ``failed``.

    The nearest reachable standoff pose by path (:func:`missiontree.reasoning.intent.plan_candidates`
    for a robot of ``robot_radius``); when it is one that failed (not reached, or ``looked`` from
    without confirming the object), the reachable pose on another side of the object or at another
    range (:func:`missiontree.reasoning.intent.other_viewpoint`), which must be away from the poses
    not reached (a place looked from may be looked from again at another range).
    """
    ranking = plan_candidates(
        [obj.id], SceneObjects({obj.id: obj}), grid, robot, robot_radius, (), False, camera
    )
    if not ranking.candidates:
        return None, ranking.rejected[0].reason if ranking.rejected else "no standoff pose"
    goal = ranking.candidates[0].goal
    tried = [f for f in [*failed, *looked] if math.hypot(f.x - goal.x, f.y - goal.y) < SAME_PLACE]
    if not tried or grid is None:
        return goal, ""
    other = other_viewpoint(obj, grid, robot, tried[-1], robot_radius, False, camera)
    if other is None or any(math.hypot(f.x - other.x, f.y - other.y) < SAME_PLACE for f in failed):
        return None, f"no standoff pose other than ({goal.x:.2f}, {goal.y:.2f}), which was not reached"
    return other, ""


class ApproachStep(Leaf):
    """What the approach steps share: the candidate, the attempts so far, giving the candidate up."""

    class Params(BaseModel):
        max_attempts: int = Field(
            3, ge=1, description="Standoff poses tried before the candidate is given up.")
        candidate: Annotated[str, Input("the candidate approached: id, label, x, y (z, height, deadline)",
                                        type="dict")] = "search_candidate"
        tries: Annotated[str, Output("this approach's standoff poses tried (the subtree empties it first)",
                                     type="list[dict]")] = "approach_tries"
        rejected: Annotated[str, Output("candidates rejected so far", type="list")] = "search_rejected"

    params: Params

    def __init__(self, name: str, params: BaseModel | None = None) -> None:
        super().__init__(name, params)
        self.cand: dict[str, Any] | None = None

    def initialise(self) -> None:
        """Take the candidate as it is now."""
        value = self.read("candidate")
        self.cand = dict(value) if isinstance(value, dict) else None

    def tries(self) -> list[dict[str, Any]]:
        """The standoff poses tried so far in this approach."""
        return self.read_entries("tries")

    def drives(self) -> int:
        """Standoff poses driven to so far (places looked from are counted by the looks, not here)."""
        return sum(1 for t in self.tries() if "x" in t and not t.get("looked"))

    def stopped(self) -> str:
        """Why this approach is over ("" while it goes on)."""
        tries = self.tries()
        return str(tries[-1].get("stop", "")) if tries else ""

    def give_up(self, reason: str, kind: RejectKind = "unreached") -> Status:
        """End the approach: the candidate marked ``kind``, the remaining attempts failing at once."""
        if self.cand is not None:
            mark_rejected(self, self.cand, reason, kind=kind)
        why = f"{self.cand['id'] if self.cand else 'candidate'}: {reason}"
        self.write("tries", [*self.tries(), {"stop": why}])
        return self.fail(why)

    def past_deadline(self) -> bool:
        """Whether the candidate's ``deadline`` (robot s, from Locate's time budget) has passed."""
        deadline = self.cand.get("deadline") if self.cand is not None else None
        return isinstance(deadline, int | float) and self.context.robot.now() > deadline

    def early_exit(self) -> Status | None:
        """FAILURE when there is nothing (more) to do: no candidate, the approach over, its time up."""
        if self.cand is None:
            return self.fail("no candidate to approach (run Locate first)")
        stop = self.stopped()
        if stop:
            return self.fail(stop)
        if self.past_deadline():
            return self.give_up("the search's time ran out before it was reached")
        return None


class PlanStandoff(ApproachStep):
    """A standoff pose facing the candidate on the map as it is now, written to ``standoff``.

    Each pose not reached before asks for ``clearance_step`` more room round the robot and another
    place (:func:`standoff_goal`). No pose: the candidate is given up (``unreached``).
    """

    class Params(ApproachStep.Params):
        robot_radius: float = Field(
            0.17, gt=0, description="Footprint radius for standoff poses and paths (m).")
        clearance_step: float = Field(
            0.1, ge=0, description="After a standoff pose was not reached, the next asks for this much more "
            "room around the robot (m), and another place.")
        view: Literal["lower_quarter", "centre"] = Field(
            "lower_quarter", description="What the camera must see from the pose: the candidate's lower "
            "quarter (a detection placed it), or its centre `z` (a scene graph's object).")
        standoff: Annotated[str, Output("the standoff pose to drive to: x, y, yaw, attempt", type="dict")] = (
            "standoff")

    params: Params

    def __init__(self, name: str, params: BaseModel | None = None) -> None:
        super().__init__(name, params)
        self.job: Background | bool | None = None  # True: the candidate's own goal, no search

    def initialise(self) -> None:
        """Take the candidate; the job starts at the first tick with a pose."""
        super().initialise()
        self.job = None

    def update(self) -> Status:
        """Start the search for a pose, then wait for it."""
        early = self.early_exit()
        if early is not None:
            return early
        assert self.cand is not None
        if self.job is None:
            return self._start()
        done, result, error = (True, self._ranked(), "") if self.job is True else self._poll()
        if not done:
            return self.running("finding a standoff pose")
        self.job = None
        if error:
            return self.give_up(f"finding a standoff pose failed: {error}")
        goal, why = result
        tries = self.tries()
        looked = [t for t in tries if t.get("looked")]
        if goal is None and looked:  # looked at and not confirmed, and no other place to look from
            return self.give_up(f"{looked[0]['why']}; no other place to look at it from", kind="wrong")
        if goal is None:
            last = next((t["why"] for t in reversed(tries) if t.get("why")), "")
            return self.give_up(f"cannot be approached: {why}" + (f" ({last})" if last else ""))
        attempt = self.drives() + 1
        self.write("standoff", {"x": goal.x, "y": goal.y, "yaw": goal.yaw, "attempt": attempt})
        self.emit("approach_step", mode="standoff", attempt=attempt, object=self.cand["id"],
                  x=round(goal.x, 3), y=round(goal.y, 3), yaw=round(goal.yaw, 3),
                  object_x=self.cand["x"], object_y=self.cand["y"])
        self.context.mark("goal", goal.x, goal.y, str(self.cand["id"]))
        return self.succeed(f"a standoff pose facing {self.cand['id']} (attempt {attempt})")

    def _start(self) -> Status:
        assert self.cand is not None
        robot = self.context.robot
        stamped = robot.pose()
        if stamped is None:
            return self.running("waiting for a pose")
        c = self.cand
        failed = [Pose2D(t["x"], t["y"], t["yaw"]) for t in self.tries()
                  if not t.get("reached", True) and not t.get("looked")]
        looked = tuple(Pose2D(t["x"], t["y"], t["yaw"]) for t in self.tries() if t.get("looked"))
        if isinstance(c.get("goal"), dict) and not self.tries():
            self.job = True  # ranked with the other candidates: its pose is planned already
            return self.update()
        z = view_height(c) if self.params.view == "lower_quarter" else float(c.get("z", 0.0) or 0.0)
        obj = GraphObject(str(c["id"]), str(c["label"]), xy=(c["x"], c["y"]), z=z)
        radius = self.params.robot_radius + self.params.clearance_step * len(failed)
        self.job = Background(standoff_goal, obj, robot.occupancy(), stamped.pose, radius,
                              camera_view(robot.rgbd()), failed, looked, wait=waits(self.context))
        return self.update()

    def _poll(self) -> tuple[bool, Any, str]:
        assert isinstance(self.job, Background)
        return self.job.poll()

    def _ranked(self) -> tuple[Pose2D, str]:
        """The candidate's own ``goal`` (planned when the candidates were ranked)."""
        assert self.cand is not None
        goal = self.cand["goal"]
        return Pose2D(float(goal["x"]), float(goal["y"]), float(goal["yaw"])), ""

    def terminate(self, new_status: Status) -> None:
        """Drop a search in flight."""
        if isinstance(self.job, Background):
            self.job.cancel()
        self.job = None


class DriveToStandoff(ApproachStep, GoalLeaf):
    """Drive to the ``standoff`` pose; not reached: recorded in ``tries``, given up after the last attempt.

    SUCCEEDED, or ABORTED within :data:`NEAR_ENOUGH` of the pose and within ``reach`` of the object,
    counts as reached.
    """

    class Params(ApproachStep.Params):
        xy_tolerance: float = Field(0.15, gt=0, description="Distance to the goal that counts as there (m).")
        yaw_tolerance: float = Field(0.3, gt=0, description="Heading error accepted at the goal (rad).")
        reach: float = Field(
            1.0, gt=0, description="A goal the stack aborted just short of counts as reached only when the "
            "robot stands within this distance of the candidate (m).")
        goal_timeout: float = Field(120.0, gt=0, description="Give up a goal not reached in this many s.")
        standoff: Annotated[str, Input("the standoff pose to drive to", type="dict")] = "standoff"

    params: Params

    def initialise(self) -> None:
        """Send the goal."""
        super().initialise()
        self.handle = None
        pose = self.read("standoff")
        self.goal = Pose2D(pose["x"], pose["y"], pose["yaw"]) if isinstance(pose, dict) else None
        if self.goal is None or self.cand is None or self.stopped():
            return
        tolerance = Tolerance(self.params.xy_tolerance, self.params.yaw_tolerance)
        self.send_goal(self.goal, tolerance)
        c, goal = self.cand, self.goal
        said = {k: c[k] for k in ("command", "path_length", "straight_line") if k in c}
        self.emit("goal_sent", object=c["id"], label=c.get("label"), x=round(goal.x, 3), y=round(goal.y, 3),
                  yaw=round(goal.yaw, 3), object_x=c["x"], object_y=c["y"], xy_tolerance=tolerance.xy,
                  yaw_tolerance=tolerance.yaw, **said)

    def update(self) -> Status:
        """Poll the goal."""
        early = self.early_exit()
        if early is not None:
            return early
        if self.handle is None or self.goal is None:
            return self.fail("no standoff pose to drive to (run PlanStandoff first)")
        robot = self.context.robot
        status = self.handle.status()
        if not status.done:
            if self.overdue(self.params.goal_timeout):
                return self._ended(False, f"not reached within {self.params.goal_timeout:g} s")
            feedback = self.handle.feedback()
            left = f"{feedback.distance_remaining:.1f} m to go" if feedback is not None else status.value
            return self.running(f"approaching: {left}")
        result = self.handle.result()
        self.handle = None
        stamped = robot.pose()
        off = stamped.pose.distance_to(self.goal) if stamped is not None else math.inf
        ok = status is ActionStatus.SUCCEEDED or (off <= NEAR_ENOUGH and self.within_reach(stamped))
        reason = result.reason if result is not None and result.reason else "no reason given"
        self.emit("goal_result", status=status.value, reason=reason, x=self.goal.x, y=self.goal.y,
                  object=self.cand["id"] if self.cand is not None else None)
        return self._ended(ok, f"{status.value}: {reason}")

    def within_reach(self, stamped: PoseStamped | None) -> bool:
        """Whether the robot stands within ``reach`` of the candidate (never without a pose)."""
        if self.cand is None or stamped is None:
            return False
        away = math.hypot(stamped.pose.x - self.cand["x"], stamped.pose.y - self.cand["y"])
        return bool(away <= self.params.reach)

    def _ended(self, ok: bool, why: str) -> Status:
        assert self.goal is not None
        tries = self.tries()
        entry = {"x": self.goal.x, "y": self.goal.y, "yaw": self.goal.yaw, "reached": ok,
                 "why": "" if ok else why}
        self.write("tries", [*tries, entry])
        if ok:
            return self.succeed(f"at the standoff pose ({self.goal.x:.2f}, {self.goal.y:.2f})")
        attempts = self.drives()
        if attempts >= self.params.max_attempts:
            return self.give_up(f"not reached in {attempts} attempts ({why})")
        return self.fail(f"standoff pose not reached ({why}); trying another with more room")

    def _cancel(self) -> None:
        if self.handle is not None:
            self.handle.cancel()
            self.handle = None

    def terminate(self, new_status: Status) -> None:
        """Cancel the goal in flight."""
        self._cancel()


class FaceTarget(Leaf):
    """Turn in place until the object is straight ahead (the navigation stack may stop short of facing it).

    Succeeds facing it, or after ``timeout`` facing as near as it got (the look that follows decides).
    """

    class Params(BaseModel):
        facing: float = Field(0.1, gt=0, description="Heading error that counts as facing (rad).")
        timeout: float = Field(10.0, gt=0, description="Time allowed to turn (s).")
        target: Annotated[str, Input("the object to face: id, x, y", type="dict")] = "search_candidate"

    params: Params

    def __init__(self, name: str, params: BaseModel | None = None) -> None:
        super().__init__(name, params)
        self.started = 0.0
        self.turning = False

    def initialise(self) -> None:
        """Start the clock."""
        self.started = self.context.robot.now()
        self.turning = False

    def update(self) -> Status:
        """Turn toward the object, proportionally to the heading error."""
        target = self.read("target")
        if not isinstance(target, dict) or "x" not in target:
            return self.fail("no object to face")
        robot = self.context.robot
        stamped = robot.pose()
        error = stamped.pose.bearing_to(target["x"], target["y"]) if stamped is not None else 0.0
        if abs(error) > self.params.facing and robot.now() - self.started < self.params.timeout:
            robot.drive(0.0, max(-1.0, min(1.0, 2.0 * error)))
            self.turning = True
            return self.running(f"turning to face {target.get('id', 'it')} ({math.degrees(error):.0f} deg)")
        robot.stop()
        self.turning = False
        return self.succeed(f"facing {target.get('id', 'it')} ({math.degrees(error):.0f} deg off)")

    def terminate(self, new_status: Status) -> None:
        """Stop turning when halted."""
        if self.turning and self.ctx is not None:
            self.ctx.robot.stop()
        self.turning = False
