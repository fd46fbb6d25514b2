"""Patrol routes: waypoint lists written in a mission, a config file, or a Nav2-style waypoint YAML.

Accepted shapes, for a list given inline in a tree or read from a file:

- a list of ``[x, y]`` or ``[x, y, yaw]`` (the patrol-robot thesis's Listing 4.8);
- a list of mappings ``{x, y, yaw?, name?}``;
- a list of geometry_msgs-like poses ``{pose: {position: {x, y}, orientation: {z, w}}}``
  (a PoseStamped dump; yaw from the quaternion);
- the Nav2 RViz panel's saved file: ``waypoints: {waypoint0: {pose: [x, y, z],
  orientation: [x, y, z, w]}, ...}``.

A file holds one of these at its top, under ``waypoints:`` (with an optional ``order:`` list of
names giving the loop, names may repeat), or under ``routes: {name: ...}`` (several named routes,
picked with ``route``). Files are found by path or by name under
``config/waypoints/`` (:func:`missiontree.paths.find_config`). Bad input raises a ConfigError
saying where, what was expected and what was found.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pydantic import BaseModel, Field, model_validator

from missiontree.errors import ConfigError, ProblemsError
from missiontree.mapping.occupancy import BLOCKED_FROM
from missiontree.paths import find_config
from missiontree.types import OccupancyGrid, Pose2D
from missiontree.yamlio import YamlLimits, load_yaml

#: A waypoint file is a list of poses: a few hundred at most, never megabytes.
WAYPOINT_LIMITS = YamlLimits(max_bytes=256 * 1024, max_depth=16, max_nodes=50_000)


@dataclass(frozen=True)
class Waypoint:
    """A named patrol pose in the map frame."""

    name: str
    pose: Pose2D


_FORMS = ("[x, y, yaw], {x, y, yaw}, {pose: {position: {x, y}, orientation: {z, w}}} "
          "or the Nav2 panel's {pose: [x, y, z], orientation: [x, y, z, w]}")


class RouteSource(BaseModel):
    """A leaf's route parameters: inline waypoints or a waypoint file (and a route in it), exactly one."""

    waypoints: list[Any] | None = Field(
        None, description="The route: [[x, y, yaw], ...] or [{x, y, yaw, name}, ...].")
    waypoints_file: str | None = Field(
        None, description="A waypoint file: a path or a name under config/waypoints/ (Nav2 format too).")
    route: str | None = Field(None, description="Route name when the file holds several under `routes:`.")

    @model_validator(mode="after")
    def _one_source(self) -> RouteSource:
        if (self.waypoints is None) == (self.waypoints_file is None):
            raise ValueError("give exactly one of `waypoints` (inline) or `waypoints_file`")
        if self.waypoints is not None:
            parse_waypoints(self.waypoints, "waypoints")
        return self

    def load_route(self, where: str) -> list[Waypoint]:
        """The route: the inline waypoints (``where`` names them in errors) or the file's route."""
        if self.waypoints is not None:
            return parse_waypoints(self.waypoints, where)
        assert self.waypoints_file is not None
        return load_waypoints(self.waypoints_file, self.route)


def parse_waypoints(raw: Any, where: str = "waypoints") -> list[Waypoint]:
    """Read waypoints in any accepted shape.

    Args:
        raw: The list (or Nav2 panel mapping) as loaded from YAML.
        where: Where it came from, for messages (a file name or a node path).

    Raises:
        ConfigError: The value is empty or an entry has another shape.
    """
    order = None
    if isinstance(raw, Mapping) and "waypoints" in raw:
        order = raw.get("order")
        raw = raw["waypoints"]
    if isinstance(raw, Mapping):  # Nav2 panel: {waypoint0: {...}, waypoint1: {...}}
        items = [(str(k), v) for k, v in sorted(raw.items(), key=lambda kv: _natural_key(str(kv[0])))]
    elif isinstance(raw, Sequence) and not isinstance(raw, str):
        items = [(f"P{i + 1}", v) for i, v in enumerate(raw)]
    else:
        raise ConfigError(f"{where}: expected a list of waypoints ({_FORMS}), found {type(raw).__name__}")
    if not items:
        raise ConfigError(f"{where}: expected at least one waypoint, found an empty list")
    waypoints = [_one(name, value, f"{where}[{i}]") for i, (name, value) in enumerate(items)]
    return waypoints if order is None else _ordered(waypoints, order, where)


def _ordered(waypoints: list[Waypoint], order: Any, where: str) -> list[Waypoint]:
    """The patrol loop named by ``order`` (names may repeat: out and back along a corridor)."""
    by_name = {w.name: w for w in waypoints}
    if not isinstance(order, Sequence) or isinstance(order, str) or not order:
        raise ConfigError(f"{where}: expected `order:` to be a list of waypoint names, found {order!r}")
    unknown = [str(n) for n in order if str(n) not in by_name]
    if unknown:
        raise ConfigError(f"{where}: `order:` names unknown waypoints {', '.join(unknown)}; "
                          f"known: {', '.join(by_name)}")
    return [by_name[str(n)] for n in order]


@dataclass(frozen=True)
class WaypointFile:
    """A waypoint file as read: its route and the world it says it was written for.

    Attributes:
        path: The file read.
        waypoints: The route picked (``route``, or the only one).
        world: The file's ``world:`` (a world name), or None when it names none.
    """

    path: Path
    waypoints: list[Waypoint]
    world: str | None


def resolve_waypoints_file(name_or_path: str | os.PathLike[str], base: Path | None = None) -> Path:
    """The waypoint file a name means: beside ``base`` (the mission's folder) first, then config/.

    Raises:
        ConfigError: Nothing found; the message lists the shipped names.
    """
    if base is not None:
        beside = (base / name_or_path)
        if beside.is_file():
            return beside.resolve()
    return find_config("waypoints", name_or_path)


def read_waypoint_file(name_or_path: str | os.PathLike[str], route: str | None = None,
                       base: Path | None = None) -> WaypointFile:
    """Read a waypoint file whole: the route and the world it was written for.

    Raises:
        ConfigError: Missing file, unknown route, or malformed waypoints (a ProblemsError with
            file:line:col when the YAML itself is broken).
    """
    path = resolve_waypoints_file(name_or_path, base)
    data = load_yaml(path, limits=WAYPOINT_LIMITS, error=ProblemsError).data
    where = str(path)
    world = data.get("world") if isinstance(data, Mapping) else None
    if world is not None and not isinstance(world, str):
        raise ConfigError(f"{where}: expected `world:` to name a world, found {type(world).__name__}")
    if isinstance(data, Mapping) and "routes" in data:
        routes = data["routes"]
        if not isinstance(routes, Mapping) or not routes:
            raise ConfigError(f"{where}: expected `routes:` to map route names to waypoint lists")
        if route is None:
            if len(routes) > 1:
                raise ConfigError(
                    f"{where}: holds several routes ({', '.join(map(str, routes))}); "
                    "name one with the patrol's `route` parameter")
            route = str(next(iter(routes)))
        if route not in routes:
            raise ConfigError(
                f"{where}: no route {route!r}; known: {', '.join(map(str, routes))}")
        return WaypointFile(path, parse_waypoints(routes[route], f"{where}: routes.{route}"), world)
    if route is not None:
        raise ConfigError(f"{where}: has no `routes:` section, so route {route!r} cannot be picked")
    return WaypointFile(path, parse_waypoints(data, where), world)


def load_waypoints(name_or_path: str, route: str | None = None, base: Path | None = None) -> list[Waypoint]:
    """Read a waypoint file (a path, or a name under ``config/waypoints/``).

    Args:
        name_or_path: ``combined`` or ``config/waypoints/combined.yaml``.
        route: The route to use when the file holds several under ``routes:``.
        base: A folder searched first (the mission file's), as subtree includes are.

    Raises:
        ConfigError: Missing file, unknown route, or malformed waypoints.
    """
    return read_waypoint_file(name_or_path, route, base).waypoints


def misfits(waypoints: Sequence[Waypoint], grid: OccupancyGrid) -> list[str]:
    """Why waypoints cannot belong to the world of ``grid``: outside its map, or inside an obstacle.

    A waypoint merely close to an obstacle is not a misfit: the patrol skips it with the planner's
    reason at run time (the patrol-robot thesis §4.5.8). Returns one sentence per misfit, empty when all fit.
    """
    rows, cols = grid.data.shape
    x0, y0 = grid.origin.x, grid.origin.y
    x1, y1 = x0 + cols * grid.resolution, y0 + rows * grid.resolution
    found: list[str] = []
    for w in waypoints:
        x, y = w.pose.x, w.pose.y
        row, col = grid.world_to_cell(x, y) if abs(x) < 1e9 and abs(y) < 1e9 else (-1, -1)
        at = f"{w.name} ({x:g}, {y:g})"
        if not (0 <= row < rows and 0 <= col < cols):
            found.append(f"{at} lies outside the map ({x0:.1f}..{x1:.1f}, {y0:.1f}..{y1:.1f})")
        elif grid.data[row, col] >= BLOCKED_FROM:
            found.append(f"{at} lies inside an obstacle")
        elif grid.data[row, col] < 0:
            found.append(f"{at} lies in unknown space")
    return found


def _natural_key(text: str) -> tuple[str, int]:
    digits = "".join(ch for ch in text if ch.isdigit())
    return text.rstrip("0123456789"), int(digits) if digits else -1


def _number(value: Any, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise ConfigError(f"{where}: expected a finite number, found {value!r}")
    return float(value)


def _yaw_of_quaternion(q: Sequence[float] | Mapping[str, Any], where: str) -> float:
    if isinstance(q, Mapping):
        x, y, z, w = (_number(q.get(k, 0.0 if k != "w" else 1.0), f"{where}.{k}") for k in "xyzw")
    else:
        if len(q) != 4:
            raise ConfigError(f"{where}: expected a quaternion [x, y, z, w], found {list(q)!r}")
        x, y, z, w = (_number(v, where) for v in q)
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def _one(name: str, value: Any, where: str) -> Waypoint:
    if isinstance(value, Sequence) and not isinstance(value, str):
        if len(value) not in (2, 3):
            raise ConfigError(f"{where}: expected [x, y] or [x, y, yaw], found {list(value)!r}")
        nums = [_number(v, where) for v in value]
        return Waypoint(name, Pose2D(nums[0], nums[1], nums[2] if len(nums) == 3 else 0.0))
    if not isinstance(value, Mapping):
        raise ConfigError(f"{where}: expected a waypoint ({_FORMS}), found {value!r}")
    name = str(value.get("name", name))
    if "x" in value and "y" in value:
        return Waypoint(name, Pose2D(_number(value["x"], f"{where}.x"), _number(value["y"], f"{where}.y"),
                                     _number(value.get("yaw", 0.0), f"{where}.yaw")))
    pose = value.get("pose")
    if isinstance(pose, Sequence) and not isinstance(pose, str) and len(pose) >= 2:  # Nav2 panel
        yaw = _yaw_of_quaternion(value["orientation"], f"{where}.orientation") \
            if "orientation" in value else 0.0
        x, y = _number(pose[0], f"{where}.pose[0]"), _number(pose[1], f"{where}.pose[1]")
        return Waypoint(name, Pose2D(x, y, yaw))
    if isinstance(pose, Mapping) and "pose" in pose:  # a PoseStamped dump: {header, pose: {...}}
        pose = pose["pose"]
    if isinstance(pose, Mapping) and isinstance(pose.get("position"), Mapping):
        position = pose["position"]
        yaw = _yaw_of_quaternion(pose["orientation"], f"{where}.pose.orientation") \
            if "orientation" in pose else 0.0
        return Waypoint(name, Pose2D(_number(position.get("x"), f"{where}.pose.position.x"),
                                     _number(position.get("y"), f"{where}.pose.position.y"), yaw))
    raise ConfigError(f"{where}: expected a waypoint ({_FORMS}), found keys {sorted(map(str, value))}")
