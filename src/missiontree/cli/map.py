"""``missiontree map convert SRC --out DIR``: a map_server ``map.yaml``/``map.pgm`` from another format.

SRC is an MRPT ``.gridmap``/``.gridmap.gz`` (MRPT's own occupancy grids, such as Debian's
mrpt-common datasets), an MRPT ``.rawlog`` of 2-D laser scans and odometry (mapped with the
log-odds grid at the odometry poses corrected by scan matching, or the raw odometry poses with
``--raw-odometry``), an MRPT ``.simplemap(.gz)`` (scans at the poses MRPT's SLAM gave them), or a
map_server ``.yaml``, or a ROS 2 bag (``.mcap``: its ``/scan`` laid at the poses of its ``/tf`` or
``/odom``). The pair written loads in Nav2's map_server and in a
world file (``map: {yaml: DIR/map.yaml}``). Bad input (a file of no known kind, a damaged file, the
scan matcher's extra missing) prints one line and exits 2.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from missiontree.errors import ConfigError

EXIT_OK = 0


def register(subparsers: Any) -> None:
    """Add the ``map`` subcommand (with ``map convert``)."""
    parser = subparsers.add_parser(
        "map", help="convert maps between formats",
        description="Convert maps: `missiontree map convert SRC --out DIR` writes a map_server "
        "map.yaml/map.pgm.",
    )
    actions = parser.add_subparsers(dest="map_command", metavar="ACTION", required=True)
    convert = actions.add_parser(
        "convert",
        help="write a map_server map.yaml/map.pgm from an MRPT gridmap, rawlog or simplemap, a ROS 2 bag "
        "(.mcap) or a map.yaml",
        description="Read SRC (MRPT .gridmap or .gridmap.gz, MRPT .rawlog of 2-D scans and odometry, MRPT "
        ".simplemap or .simplemap.gz, a ROS 2 bag .mcap (/scan at the poses of /tf or /odom), or a "
        "map_server .yaml) and write DIR/NAME.yaml and DIR/NAME.pgm in "
        "map_server's trinary format.",
    )
    convert.add_argument("src", type=Path,
                         help="the map source (.gridmap(.gz), .rawlog, .simplemap(.gz), .mcap, .yaml)")
    convert.add_argument("--out", type=Path, required=True, help="the directory to write into")
    convert.add_argument("--name", default="map", help="base name of the files written (default: map)")
    convert.add_argument("--resolution", type=float, default=0.05,
                         help="cell size (m) of a map built from scans (rawlog, simplemap, bag; "
                         "default: 0.05)")
    convert.add_argument("--max-range", type=float, default=15.0,
                         help="returns beyond this (m) free space and draw no wall (rawlog, simplemap, bag; "
                         "default: 15)")
    convert.add_argument("--raw-odometry", action="store_true",
                         help="map a rawlog at its raw odometry poses (no scan matching, no realdata extra)")
    convert.add_argument("--namespace", default="",
                         help="a bag from a namespaced robot: /robot1 reads /robot1/scan, /robot1/tf, ...")
    convert.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Convert one map source; bad input raises ConfigError (exit 2)."""
    from missiontree.mapping.map_sources import MapSourceError, load_map_source
    from missiontree.mapping.mapfile import write_map

    if not 0.005 <= args.resolution <= 5.0:
        raise ConfigError(f"--resolution: expected 0.005 to 5 m, found {args.resolution}")
    if not args.max_range > 0:
        raise ConfigError(f"--max-range: expected a positive range, found {args.max_range}")
    if not args.name or "/" in args.name or args.name.startswith("."):
        raise ConfigError(f"--name: expected a plain file name, found {args.name!r}")
    try:
        loaded = load_map_source(args.src, correct=not args.raw_odometry, resolution=args.resolution,
                                 max_range=args.max_range, namespace=args.namespace)
    except MapSourceError as exc:
        raise ConfigError(str(exc)) from None
    pgm, meta = write_map(loaded.grid, args.out, args.name)
    grid = loaded.grid
    rows, cols = grid.data.shape
    print(f"{args.src}: {loaded.how}")
    print(f"wrote {meta} and {pgm}: {cols} x {rows} cells of {grid.resolution:g} m, origin "
          f"({grid.origin.x:g}, {grid.origin.y:g})")
    return EXIT_OK
