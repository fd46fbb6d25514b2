"""``missiontree world show WORLD --out world.png``: draw a simulator world from above, with a metre grid.

The world is loaded and checked as a run would load it (a shipped name such as ``office``, a path
to a world file, or ``generated:<seed>``), so a broken world prints its problems as
``file:line:col`` and exits 2. The picture is the run pictures' top-down drawing at the start of a
run: walls and map cells, rooms, objects with their ids, people's routes, the robot at its start
pose, and a grid line every metre numbered in metres along the top (x) and left (y) edges, so goals
and waypoints can be read off the picture. ``--waypoints FILE`` adds a waypoint file's poses as goals, to
see whether a route was written for this world.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import numpy as np

EXIT_OK = 0


def register(subparsers: Any) -> None:
    """Add the ``world`` subcommand (with ``world show``)."""
    parser = subparsers.add_parser(
        "world", help="look at simulator worlds",
        description="Look at simulator worlds: `missiontree world show WORLD --out world.png` draws one.",
    )
    actions = parser.add_subparsers(dest="world_command", metavar="ACTION", required=True)
    show = actions.add_parser(
        "show", help="draw a world from above with a metre grid and coordinates",
        description="Load and check a world (a shipped name, a path to a world file, or generated:<seed>) "
        "and draw it from above with a grid line every metre, numbered in metres (x along the top, y on "
        "the left).",
    )
    show.add_argument("world", help="a shipped world name (office), a world file, or generated:<seed>")
    show.add_argument("--out", type=Path, help="the PNG to write (default: <world name>.png)")
    show.add_argument("--waypoints", help="also draw this waypoint file's poses (a path or a shipped name)")
    show.add_argument("--route", help="the route to draw when the waypoint file holds several")
    show.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Load the world and draw it."""
    from missiontree.backends.sim import load_robot_profile, load_world
    from missiontree.backends.sim.render import Scene, SceneObject, ScenePerson, SceneRoom, draw_topdown

    world = load_world(args.world)
    profile = load_robot_profile(world.profile_name)
    goals = []
    if args.waypoints:
        from missiontree.behaviours.waypoints import load_waypoints

        goals = [w.pose for w in load_waypoints(args.waypoints, args.route)]
    people = []
    for person in world.crowd.people:
        route = np.array(person.spec.route, float).reshape(-1, 2)
        state = person.state_at(0.0)
        people.append(ScenePerson(person.id, route, (state.x, state.y) if state.present else None))
    scene = Scene(
        name=world.name, bounds=world.bounds(), grid=world.grid, now=0.0, seed=0, bumps=0,
        robot_pose=world.start, robot_radius=profile.body.radius,
        rooms=[SceneRoom(r.name, r.type, r.polygon) for r in world.rooms],
        walls=[tuple(float(v) for v in s) for s in world.wall_segments],  # type: ignore[misc]  # x1 y1 x2 y2
        objects=[SceneObject(o.id, tuple(int(c) for c in o.rgb), o.footprint(),  # type: ignore[arg-type]
                             (o.pose.x, o.pose.y - o.size[1] / 2 - 0.12)) for o in world.objects],
        people=people, goals=goals,
    )
    out = args.out if args.out is not None else Path(f"{world.name}.png")
    if out.parent != Path("."):
        out.parent.mkdir(parents=True, exist_ok=True)
    draw_topdown(scene, [], out, metre_grid=True)
    xmin, ymin, xmax, ymax = world.bounds()
    print(f"{world.name}: {xmax - xmin:.1f} x {ymax - ymin:.1f} m, {len(world.rooms)} rooms, "
          f"{len(world.objects)} objects, {len(world.crowd.people)} people; drawn to {out}")
    return EXIT_OK
