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
    from missiontree.session.worlds import draw_world

    drawn = draw_world(args.world, args.out, waypoints=args.waypoints, route=args.route)
    print(f"{drawn.name}: {drawn.width:.1f} x {drawn.height:.1f} m, {drawn.rooms} rooms, "
          f"{drawn.objects} objects, {drawn.people} people; drawn to {drawn.out}")
    return EXIT_OK
