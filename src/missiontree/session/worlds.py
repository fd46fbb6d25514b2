"""The simulator's files as the command line sees them: checked alone, drawn, served over ROS 2.

The CLI imports no backend (ARCHITECTURE §11): ``missiontree validate`` checks a world file, a
robot profile or a waypoint file through :func:`check_world_file`, :func:`check_robot_file` and
:func:`check_waypoint_file`; ``missiontree world show`` draws through :func:`draw_world`;
``missiontree sim-ros`` builds its bridge with :func:`sim_ros_bridge`.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from missiontree.errors import BackendUnavailableError, ConfigError, Problem, ProblemsError, WorldFileError
from missiontree.yamlio import load_yaml


def check_world_file(path: Path) -> None:
    """Load a world file as a run would; raises :class:`~missiontree.errors.ProblemsError` on problems."""
    from missiontree.backends.sim import load_world

    load_world(path)


def check_robot_file(path: Path) -> None:
    """Load a simulated robot profile as a run would; raises on problems."""
    from missiontree.backends.sim import load_robot_profile

    load_robot_profile(path)


def check_waypoint_file(path: Path) -> list[Problem]:
    """A waypoint file alone: valid, and (when it names its world) inside that world's free space."""
    from missiontree.backends.sim import load_world
    from missiontree.behaviours.waypoints import misfits, read_waypoint_file

    found = read_waypoint_file(path)
    if found.world is None:
        return []
    doc = load_yaml(path, error=ProblemsError)
    try:
        world = load_world(found.world)
    except WorldFileError as error:
        return [doc.problem_at(("world",), f"expected a world that loads, found {found.world!r}: "
                               f"{error.problems[0].message}", "fix `world:`")]
    return [doc.problem_at(("waypoints",), f"expected waypoints in the world {world.name!r}, found {reason}",
                           "move the waypoint into free space, or fix `world:`")
            for reason in misfits(found.waypoints, world.grid)]


@dataclass(frozen=True)
class WorldDrawn:
    """What :func:`draw_world` drew: the world's name, size and contents, and the picture's path."""

    name: str
    width: float
    height: float
    rooms: int
    objects: int
    people: int
    out: Path


def draw_world(name: str, out: Path | None = None, *, waypoints: str | None = None,
               route: str | None = None) -> WorldDrawn:
    """Load and check a world and draw it from above at its start, with a metre grid.

    Args:
        name: A shipped world name, a world file, or ``generated:<seed>``.
        out: The PNG to write (default ``<world name>.png``).
        waypoints: A waypoint file whose poses are drawn as goals.
        route: The route to draw when the waypoint file holds several.
    """
    import numpy as np

    from missiontree.backends.sim import load_robot_profile, load_world
    from missiontree.backends.sim.render import Scene, SceneObject, ScenePerson, SceneRoom, draw_topdown

    world = load_world(name)
    profile = load_robot_profile(world.profile_name)
    goals = []
    if waypoints:
        from missiontree.behaviours.waypoints import load_waypoints

        goals = [w.pose for w in load_waypoints(waypoints, route)]
    people = []
    for person in world.crowd.people:
        path = np.array(person.spec.route, float).reshape(-1, 2)
        state = person.state_at(0.0)
        people.append(ScenePerson(person.id, path, (state.x, state.y) if state.present else None))
    scene = Scene(
        name=world.name, bounds=world.bounds(), grid=world.grid, now=0.0, seed=0, bumps=0,
        robot_pose=world.start, robot_radius=profile.body.radius,
        rooms=[SceneRoom(r.name, r.type, r.polygon) for r in world.rooms],
        walls=[tuple(float(v) for v in s) for s in world.wall_segments],  # type: ignore[misc]  # x1 y1 x2 y2
        objects=[SceneObject(o.id, tuple(int(c) for c in o.rgb), o.footprint(),  # type: ignore[arg-type]
                             (o.pose.x, o.pose.y - o.size[1] / 2 - 0.12)) for o in world.objects],
        people=people, goals=goals,
    )
    target = out if out is not None else Path(f"{world.name}.png")
    if target.parent != Path("."):
        target.parent.mkdir(parents=True, exist_ok=True)
    draw_topdown(scene, [], target, metre_grid=True)
    xmin, ymin, xmax, ymax = world.bounds()
    return WorldDrawn(world.name, xmax - xmin, ymax - ymin, len(world.rooms), len(world.objects),
                      len(world.crowd.people), target)


def sim_ros_bridge(options: dict[str, Any], profile_options: dict[str, Any], *, rate: float,
                   sim_time: bool, paused: bool, robots: int = 1,
                   kills: list[tuple[str, float]] | None = None) -> tuple[Any, Any]:
    """The simulator served over ROS 2: (bridge, ROS 2 profile), not yet running.

    Args:
        options: The simulated robot's options (``world``, ``seed``, ``robot``, ``unknown_map``,
            ``sensors``), as for a run.
        profile_options: The ROS 2 profile's options (``profile``, ``domain_id``).
        rate: Simulated seconds per wall second.
        sim_time: Stamp with simulated time and publish /clock.
        paused: Hold the clock until the first goal or command.
        robots: Two or more: a fleet in one world, each robot under ``/robotN`` (the returned bridge
            leads and serves them all; the profile returned is robot 1's).
        kills: In a fleet, ``(robot, simulated seconds)``: that robot's NavigateToPose server vanishes then.

    Raises:
        BackendUnavailableError: rclpy or the NavigateToPose interface package does not import.
        ConfigError: Kills without a fleet, or naming no robot of it.
    """
    from missiontree.backends.ros2 import INSTALL_HINT, profile_from_options, require_rclpy
    from missiontree.backends.sim import create_robot as create_sim

    profile = profile_from_options(profile_options)
    require_rclpy()
    try:  # the bridge also needs the NavigateToPose interface package, tf2_msgs and rosgraph_msgs
        from missiontree.backends.ros2.bridge import SimBridge
    except ImportError as error:
        raise BackendUnavailableError(f"missiontree sim-ros needs the ros2 extra with its NavigateToPose "
                                      f"interface package, which does not import ({error}); "
                                      f"{INSTALL_HINT}") from None
    if robots > 1:
        from missiontree.backends.ros2.fleet_bridge import serve_fleet
        from missiontree.backends.sim.fleet import create_fleet

        fleet = create_fleet(options.get("world") or "office", robots=robots, seed=options.get("seed", 0),
                             robot=options.get("robot"), unknown_map=bool(options.get("unknown_map")),
                             sensors=options.get("sensors"))
        lead = serve_fleet(fleet, profile_options.get("profile") or "turtlebot4",
                           domain_id=profile.domain_id, rate=rate, sim_time=sim_time, paused=paused,
                           kills=kills or [])
        return lead, lead.profile
    if kills:
        raise ConfigError("--kill-robot needs a fleet (--robots 2 or more)")
    bridge = SimBridge(lambda: create_sim(options), profile, rate=rate, sim_time=sim_time, paused=paused)
    return bridge, profile
