"""LookAgain: go back for a second look at what the scene graph could not confirm.

Beside ``BuildSceneGraph``, exploration sees many objects only in passing: too close (the box cut by
the image's border), or 2-3 m off its path, small and oblique, for a few frames while it turns. The
builder keeps such places as doubtful (``context.scene.doubtful``: a label seen a few frames at a
place where no instance of it stands). After exploring, ``LookAgain`` visits each: it stands on a
free cell of its own map about 1.5 m away with a clear line of sight
(:func:`~missiontree.semantics.second_look.look_stand`), faces the place and sweeps a little to
each side, so the camera sees it whole for a few seconds and the fusion confirms it or finds
nothing there. It ends SUCCESS once every place was visited (or could not be), naming how many are
now in the graph. Nothing here reads the simulator's truth.

With ``surfaces`` it also looks at the top of every object of the graph whose measured top lies above
the camera and low enough to put things on (a table, a desk, a counter, a sofa's seat): from close,
a camera below the top sees the object's edge and nothing on it, and the objects standing there
(a cup, a bottle) are above the image's top. The stand is where the top and ``object_height``
above it are inside the vertical field of view (:func:`surface_distance`: the camera's height and
intrinsics from its frames), plus half the object's footprint. The objects are chosen by their
measured size, never by their label.

Use it after exploration, beside the builder::

    Parallel: {policy: success_on_one, children: [
        Sequence: {memory: true, children: [Explore: {...}, LookAgain: {}]},
        BuildSceneGraph: {...}]}
"""

from __future__ import annotations

import math

from pydantic import BaseModel, Field

from missiontree.engine.leaf import Leaf, Status
from missiontree.robot.actions import ActionHandle
from missiontree.semantics.second_look import BEST, FAR, NEAR, look_stand
from missiontree.types import Pose2D, Tolerance

#: A place to look at: (label, x, y, nearest, best, farthest stand distance in metres).
Place = tuple[str, float, float, float, float, float]


def surface_distance(top: float, object_height: float, camera_height: float, tan_half_vfov: float) -> float:
    """Least distance (m) at which a camera sees up to ``object_height`` above a surface ``top`` high.

    The vertical half field of view's tangent bounds what is in the image above the optical axis: a
    point ``h`` above the camera is in view from ``h / tan`` metres on.
    """
    rise = max(top + object_height - camera_height, 0.0)
    return rise / max(tan_half_vfov, 1e-3)


class LookAgain(Leaf):
    """Visit every doubtful place of the live scene for a second look; SUCCESS when all were visited."""

    class Params(BaseModel):
        distance: float = Field(BEST, gt=0, description="Preferred distance to the place (m).")
        min_distance: float = Field(NEAR, gt=0, description="Nearest stand to the place (m).")
        max_distance: float = Field(FAR, gt=0, description="Farthest stand from the place (m).")
        sweep: float = Field(0.5, ge=0, description="Radians swept to each side after facing the place.")
        turn_speed: float = Field(0.5, gt=0, description="Turning speed while looking (rad/s).")
        goal_timeout: float = Field(
            60.0, gt=0, description="Seconds to reach a stand before looking from where it is."
        )
        max_places: int = Field(30, ge=1, description="Most places visited in one run of the leaf.")
        doubtful: bool = Field(True, description="Look at the doubtful places (scene.doubtful).")
        surfaces: bool = Field(
            False, description="Also look at the top of every object whose top is above the camera and "
            "below max_top (objects on tables and desks).",
        )
        object_height: float = Field(
            0.3, gt=0, description="Height above a surface to bring into view (m): a bottle."
        )
        max_top: float = Field(1.3, gt=0, description="Highest surface top looked at (m).")
        min_footprint: float = Field(
            0.5, gt=0, description="Least measured width (m) of an object whose top is looked at."
        )

    params: Params

    def __init__(self, name: str, params: BaseModel | None = None) -> None:
        super().__init__(name, params)
        self.visited: list[Place] = []
        self.place: Place | None = None
        self.handle: ActionHandle | None = None
        self.started = 0.0
        self.turns: list[tuple[float, float]] = []
        self.no_stand = 0

    def initialise(self) -> None:
        """Start with no place chosen; the first update picks the nearest doubtful one."""
        self.visited = []
        self.place = None
        self.handle = None
        self.turns = []
        self.no_stand = 0

    def update(self) -> Status:
        """Drive to the current place's stand, look, then take the next place."""
        robot = self.context.robot
        now = robot.now()
        if self.turns:
            speed, until = self.turns[0]
            if now < until:
                robot.drive(0.0, speed)
                return self.running(self._feedback())
            self.turns.pop(0)
            if self.turns:
                robot.drive(0.0, self.turns[0][0])
                self.turns[0] = (self.turns[0][0], now + self.turns[0][1])
                return self.running(self._feedback())
            robot.stop()
            self.place = None
        if self.handle is not None:
            if not self.handle.status().done and now - self.started < self.params.goal_timeout:
                return self.running(self._feedback())
            if not self.handle.status().done:
                self.handle.cancel()
            self.handle = None
            self._start_look()
            return self.running(self._feedback())
        return self._next()

    def terminate(self, new_status: Status) -> None:
        """Cancel a goal under way and stop turning."""
        if self.handle is not None:
            self.handle.cancel()
            self.handle = None
        if self.turns and self.ctx is not None:
            self.context.robot.stop()
        self.turns = []

    # -- steps ---------------------------------------------------------------------------------

    def _pending(self) -> list[Place]:
        scene = self.context.scene
        p = self.params
        places: list[Place] = [
            (label, x, y, p.min_distance, p.distance, p.max_distance)
            for label, x, y in (list(scene.doubtful) if p.doubtful and scene is not None else [])
        ]
        places += self._surfaces()
        return [
            q
            for q in places
            if not any(q[0] == v[0] and math.hypot(q[1] - v[1], q[2] - v[2]) < 0.5 for v in self.visited)
        ]

    def _surfaces(self) -> list[Place]:
        """Tops to look at (see ``surfaces``): by measured size, from where objects on them are in view."""
        scene = self.context.scene
        frame = self.context.robot.rgbd()
        if not self.params.surfaces or scene is None or frame is None:
            return []
        k, height = frame.intrinsics, frame.camera_height
        tan = (k.cy + 0.5) / k.fy
        out: list[Place] = []
        for inst in scene.map:
            top = inst.position[2] + 0.5 * inst.size[2] if len(inst.position) > 2 else inst.size[2]
            if not height < top <= self.params.max_top:
                continue
            if max(inst.size[0], inst.size[1]) < self.params.min_footprint:
                continue
            near = surface_distance(top, self.params.object_height, height, tan)
            near += 0.5 * max(inst.size[0], inst.size[1])
            out.append((inst.label, inst.position[0], inst.position[1], near, near + 0.4, near + 1.5))
        return out

    def _next(self) -> Status:
        robot = self.context.robot
        pending = self._pending()
        if not pending or len(self.visited) >= self.params.max_places:
            return self._done()
        stamped = robot.pose()
        here = (stamped.pose.x, stamped.pose.y) if stamped is not None else (pending[0][1], pending[0][2])
        place = min(pending, key=lambda p: math.hypot(p[1] - here[0], p[2] - here[1]))
        self.visited.append(place)
        grid = robot.occupancy()
        stand = look_stand(grid, (place[1], place[2]), *place[3:]) if grid is not None else None
        if stand is None:
            self.no_stand += 1
            return self.running(self._feedback())
        self.place = place
        self.started = robot.now()
        self.handle = robot.navigate_to(Pose2D(stand[0], stand[1], 0.0), Tolerance(0.35, 2 * math.pi))
        self.emit("look_again", label=place[0], x=place[1], y=place[2], stand_x=stand[0], stand_y=stand[1])
        return self.running(self._feedback())

    def _start_look(self) -> None:
        """Face the place, then sweep ``sweep`` to each side (each step timed from when it starts)."""
        assert self.place is not None
        robot = self.context.robot
        stamped = robot.pose()
        speed = self.params.turn_speed
        if stamped is None:
            self.place = None
            return
        here = stamped.pose
        error = math.remainder(
            math.atan2(self.place[2] - here.y, self.place[1] - here.x) - here.yaw, 2 * math.pi
        )
        sweep = self.params.sweep / speed
        steps = [
            (math.copysign(speed, error), abs(error) / speed),
            (speed, sweep),
            (-speed, 2 * sweep),
            (speed, sweep),
        ]
        self.turns = [(steps[0][0], robot.now() + steps[0][1]), *steps[1:]]
        robot.drive(0.0, self.turns[0][0])

    def _done(self) -> Status:
        scene = self.context.scene
        confirmed = 0
        if scene is not None:
            confirmed = sum(1 for label, x, y, *_ in self.visited if scene.map.near(x, y, 0.5, label=label))
        return self.succeed(
            f"looked again at {len(self.visited) - self.no_stand} places: {confirmed} now in the scene graph"
            + (f", {self.no_stand} with no stand in sight on the map" if self.no_stand else "")
        )

    def _feedback(self) -> str:
        where = (
            f"{self.place[0]} at ({self.place[1]:.2f}, {self.place[2]:.2f})" if self.place else "next place"
        )
        return f"second look {len(self.visited)}: {where}"
