"""The file formats of the simulator: world files and robot profiles, as pydantic models.

Every model forbids unknown keys, so a misspelt key is an error with its line rather than a
silently ignored setting. :mod:`missiontree.backends.sim.world` turns validation errors into
``file:line`` problems; docs/worlds.md describes the format for users.
"""

from __future__ import annotations

import math
from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from missiontree.backends.sim.patterns import PATTERNS

#: Largest world a file may describe: every coordinate within this many metres of the origin, and
#: (checked when the grid is made) at most ``mapimage.MAX_MAP_CELLS`` grid cells.
COORD_LIMIT = 10_000.0
#: Largest side of a world or map, in metres.
MAX_EXTENT = 500.0
#: A coordinate in metres: finite (every model refuses NaN and infinity) and within COORD_LIMIT.
Coord = Annotated[float, Field(ge=-COORD_LIMIT, le=COORD_LIMIT)]
#: A length in metres (sizes, heights): positive and at most MAX_EXTENT.
Length = Annotated[float, Field(gt=0, le=MAX_EXTENT)]
#: An angle in radians, bounded so a typo (1e9) is caught.
Angle = Annotated[float, Field(ge=-1000.0, le=1000.0)]
Point = tuple[Coord, Coord]
#: A surface pattern's name (see :mod:`missiontree.backends.sim.patterns`).
PatternName = Literal[tuple(PATTERNS)]  # type: ignore[valid-type]
RGB = tuple[Annotated[int, Field(ge=0, le=255)], Annotated[int, Field(ge=0, le=255)],
            Annotated[int, Field(ge=0, le=255)]]

#: Colour names accepted for ``color`` when ``rgb`` is not given.
COLOR_NAMES: dict[str, tuple[int, int, int]] = {
    "black": (30, 30, 30), "white": (235, 235, 235), "grey": (128, 128, 128), "gray": (128, 128, 128),
    "red": (200, 30, 35), "green": (40, 160, 60), "blue": (35, 70, 200), "yellow": (230, 200, 40),
    "orange": (235, 130, 30), "pink": (240, 120, 180), "purple": (130, 50, 160), "brown": (120, 80, 45),
    "beige": (215, 195, 160), "silver": (190, 190, 195), "cyan": (40, 190, 200), "navy": (25, 35, 90),
    "dark grey": (70, 70, 72), "light grey": (190, 190, 190), "wood": (160, 115, 70),
}


class _Strict(BaseModel):
    # allow_inf_nan=False: NaN and infinity are refused in every number of every file format
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


class PoseSpec(_Strict):
    """A planar pose; ``yaw`` in radians, or ``yaw_deg`` in degrees."""

    x: Coord
    y: Coord
    yaw: Angle = 0.0
    yaw_deg: Annotated[float, Field(ge=-36000.0, le=36000.0)] | None = None

    @property
    def heading(self) -> float:
        """Heading in radians, whichever way it was given."""
        return math.radians(self.yaw_deg) if self.yaw_deg is not None else self.yaw


class WallGroup(_Strict):
    """Walls as segments and polylines (closed polylines are polygons)."""

    height: float = Field(2.5, gt=0, le=100)
    thickness: float = Field(0.1, gt=0, le=10, description="drawn into the occupancy grid")
    rgb: RGB = (214, 210, 200)
    segments: list[tuple[Point, Point]] = []
    polylines: list[list[Point]] = []
    polygons: list[list[Point]] = []

    @field_validator("polylines", "polygons")
    @classmethod
    def _two_points(cls, value: list[list[Point]]) -> list[list[Point]]:
        for line in value:
            if len(line) < 2:
                raise ValueError(f"expected at least 2 points, found {len(line)}")
        return value


class MapSpec(_Strict):
    """A Nav2 map_server map: ``yaml`` names the map yaml (relative to the world file)."""

    yaml: str = Field(max_length=1024)
    height: float = Field(2.5, gt=0, le=100, description="height given to occupied cells")
    rgb: RGB = (214, 210, 200)


class NavMapYaml(BaseModel):
    """The keys of a Nav2 map_server yaml that the simulator reads."""

    model_config = ConfigDict(extra="allow", allow_inf_nan=False)

    image: str = Field(max_length=1024)
    resolution: float = Field(gt=0.001, le=10)
    origin: tuple[Coord, Coord, Angle]
    negate: int = Field(0, ge=0, le=1)
    occupied_thresh: float = Field(0.65, ge=0, le=1)
    free_thresh: float = Field(0.25, ge=0, le=1)
    mode: Literal["trinary", "scale", "raw"] = "trinary"


class RoomSpec(_Strict):
    """A named room: a polygon with a type (kitchen, office, corridor, ...)."""

    name: str
    type: str
    polygon: list[Point] = Field(min_length=3)
    floor_rgb: RGB | None = None


class ObjectSpec(_Strict):
    """A thing in the world, drawn as a box or an upright cylinder."""

    id: str | None = None
    label: str
    color: str | None = None
    rgb: RGB | None = None
    attributes: list[str] = []
    description: str = ""
    shape: Literal["box", "cylinder"] = "box"
    size: tuple[Length, Length, Length] = Field(
        description="x, y, z extent in metres; cylinder: x = diameter")
    pose: PoseSpec
    elevation: float = Field(0.0, ge=0, le=100)
    movable: bool = True
    obstacle: bool | None = Field(None, description="blocks the robot; default: if it reaches below 0.3 m")
    pattern: PatternName | None = Field(  # type: ignore[valid-type]  # a Literal built from PATTERNS
        None, description="what the camera paints on the side faces; default: what the label suggests")

    @field_validator("size")
    @classmethod
    def _positive(cls, value: tuple[float, float, float]) -> tuple[float, float, float]:
        if min(value) <= 0:
            raise ValueError(f"expected three positive sizes, found {list(value)}")
        return value

    @model_validator(mode="after")
    def _colour_known(self) -> ObjectSpec:
        if self.rgb is None and self.color is not None and self.color.lower() not in COLOR_NAMES:
            known = ", ".join(sorted(COLOR_NAMES))
            raise ValueError(f"unknown colour {self.color!r} without rgb; known: {known} (or give rgb)")
        return self

    @property
    def rgb_value(self) -> tuple[int, int, int]:
        """The colour drawn: ``rgb``, else the named colour, else grey."""
        if self.rgb is not None:
            return tuple(self.rgb)  # type: ignore[return-value]
        return COLOR_NAMES.get((self.color or "grey").lower(), COLOR_NAMES["grey"])


class PersonSpec(_Strict):
    """A person walking a route at a speed, from a start time, looping or not."""

    id: str
    route: list[Point] = Field(min_length=1)
    speed: float = Field(1.0, ge=0, le=10, description="walking speed (m/s)")
    start_time: float = Field(0.0, ge=0, le=1e6)
    loop: bool = True
    pause: float = Field(0.0, ge=0, le=1e6, description="seconds standing at each route point")
    vanish_at_end: bool = False
    shirt_rgb: RGB = (60, 90, 160)
    trousers_rgb: RGB = (40, 40, 50)
    skin_rgb: RGB = (205, 160, 130)


class RobotPlacement(_Strict):
    """Which robot profile starts where."""

    profile: str = "turtlebot4"
    start: PoseSpec


class WorldSpec(_Strict):
    """A whole world file."""

    name: str
    description: str = ""
    robot: RobotPlacement
    walls: WallGroup | None = None
    map: MapSpec | None = None
    resolution: float = Field(0.05, gt=0, le=0.5, description="occupancy grid cell size")
    rooms: list[RoomSpec] = []
    objects: list[ObjectSpec] = []
    people: list[PersonSpec] = []
    plugins: dict[str, dict[str, object]] = Field(
        {}, description="sections for plugin sensor models (e.g. `battery: {dock: {x, y}}`), each read "
        "by the plugin that registered it (missiontree.robot.sensors.SimSource)")

    @model_validator(mode="after")
    def _walls_or_map(self) -> WorldSpec:
        if self.walls is None and self.map is None:
            raise ValueError("expected `walls:` or `map:` (a Nav2 map_server yaml), found neither")
        return self


# -- robot profiles --------------------------------------------------------------------------------


class MountSpec(_Strict):
    """Where a sensor sits on the robot base frame."""

    x: float = 0.0
    y: float = 0.0
    z: float = 0.2
    yaw_deg: float = 0.0


class LidarSpec(_Strict):
    """A 2D lidar; ``angle_min_deg`` is the sensor-frame angle of index 0."""

    mount: MountSpec = MountSpec()
    beams: int = Field(360, ge=4, le=4096)
    angle_min_deg: float = -180.0
    range_min: float = Field(0.15, ge=0)
    range_max: float = Field(12.0, gt=0, le=100)
    rate: float = Field(10.0, gt=0, le=1000)
    noise: float = Field(0.01, ge=0, description="range standard deviation in metres")
    frame_id: str = "rplidar_link"


class CameraSpec(_Strict):
    """A pinhole RGB-D camera looking along the mount's yaw, optical axis level."""

    mount: MountSpec = MountSpec(x=0.06, z=0.4)
    width: int = Field(320, ge=8, le=4096)
    height: int = Field(240, ge=8, le=4096)
    hfov_deg: float = Field(70.0, gt=1, lt=179)
    rate: float = Field(5.0, gt=0, le=1000)
    depth_min: float = Field(0.2, ge=0)
    depth_max: float = Field(10.0, gt=0, le=100)
    depth_noise: float = Field(0.0, ge=0, description="std of depth noise at 1 m; grows with depth squared")
    color_noise: float = Field(0.0, ge=0, description="std of colour noise in 0-255 units")


class BodySpec(_Strict):
    """The robot's body: a cylinder."""

    radius: float = Field(0.17, gt=0, le=5)
    height: float = Field(0.35, gt=0)
    rgb: RGB = (50, 50, 55)


class LimitsSpec(_Strict):
    """Velocity and acceleration limits."""

    max_v: float = Field(0.31, gt=0, le=20)
    max_w: float = Field(1.9, gt=0, le=50)
    max_acc: float = Field(1.0, gt=0)
    max_alpha: float = Field(4.0, gt=0)


class WheelsSpec(_Strict):
    """Wheel geometry (iRobot Create 3): used to model wheel-level odometry noise."""

    radius: float = Field(0.036, gt=0)
    track: float = Field(0.233, gt=0)


class OdometrySpec(_Strict):
    """Odometry noise: the pose estimate drifts from the truth when these are non-zero."""

    noise_v: float = Field(0.0, ge=0, description="relative std of the travelled distance")
    noise_w: float = Field(0.0, ge=0, description="relative std of the turned angle")


class NavigationSpec(_Strict):
    """The NavigateToPose equivalent: costmap, planner, follower and abort rules."""

    inflation_radius: float = Field(0.45, ge=0, le=10)
    cost_scaling: float = Field(3.0, ge=0, description="how fast inflation cost decays with distance")
    lookahead: float = Field(0.45, gt=0)
    heading_gain: float = Field(2.5, gt=0)
    blocked_timeout: float = Field(10.0, gt=0, description="abort when the path stays blocked this long")
    replan_period: float = Field(2.0, gt=0)
    obstacle_margin: float = Field(0.12, ge=0, description="stop when a scan point is this close ahead")
    default_xy_tolerance: float = Field(0.25, gt=0)
    default_yaw_tolerance: float = Field(0.25, gt=0)


class RobotProfile(_Strict):
    """A robot profile file (config/robots/<name>.yaml) after config overrides."""

    name: str
    body: BodySpec = BodySpec()
    limits: LimitsSpec = LimitsSpec()
    wheels: WheelsSpec = WheelsSpec()
    odometry: OdometrySpec = OdometrySpec()
    lidar: LidarSpec = LidarSpec()
    camera: CameraSpec = CameraSpec()
    navigation: NavigationSpec = NavigationSpec()
    physics_dt: float = Field(0.05, gt=0, le=0.2)
    history_horizon: float = Field(10.0, gt=0, le=600)
    accelerate: bool = Field(True, description="use numba kernels when numba is installed")
    camera_thread: bool = Field(False, description="render camera frames on a worker thread (numba); "
                                "pays off when frames are read less often than they are made")
