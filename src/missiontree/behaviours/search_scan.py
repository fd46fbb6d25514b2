"""Looking around for the search: a full turn in steps (ScanRotate), the HSV colour mapper (ColourAttention).

The vision-language object-search report's SCANNING state: turn 360 degrees pausing at fixed angles to
look, with an HSV colour mapper that pre-filters each frame (the task's colour present when >= 1 % of the
pixels match, the mask's centroid -> left / centre / right) and can interrupt the turn.

Tick-log events: ``scan_look``, ``colour_attention``.
"""

from __future__ import annotations

import math
from typing import Annotated

from pydantic import BaseModel, Field

from missiontree.behaviours.search_common import fresh_frame
from missiontree.engine.leaf import Leaf, Status
from missiontree.engine.ports import Output
from missiontree.perception.colour import canonical_colour, find_colour
from missiontree.types import wrap_angle


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
            if now - self.pause_started < p.pause or fresh_frame(robot, self.pause_started) is None:
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
        frame = fresh_frame(robot, self.last)
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

