"""``missiontree view RUN``: the run as one self-contained HTML page, or served live with ``--follow``.

``view RUN [--out report.html]`` writes a page that opens from ``file://`` with no network: the
tree as declared, coloured by status at the selected tick, a timeline with event marks, the node's
feedback and the blackboard, and the map with the robot's path. ``view --follow RUN`` serves the
same page on 127.0.0.1 and updates it as the tick log grows (Ctrl-C stops it).
"""

from __future__ import annotations

import argparse
import sys
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any, cast

from missiontree.errors import ConfigError


def register(subparsers: Any) -> None:
    """Add the ``view`` subcommand."""
    parser = subparsers.add_parser(
        "view",
        help="see a run: an HTML replay of its tick log",
        description="Write a self-contained HTML replay of a run (tree coloured by status per tick, "
        "timeline, blackboard, map with the robot's path), or serve it live with --follow.",
    )
    parser.add_argument("run_path", metavar="RUN", type=Path, help="a run directory or its ticks.jsonl")
    parser.add_argument("--out", type=Path, help="where to write the page (default: RUN/report.html)")
    parser.add_argument(
        "--mission", type=Path, help="the mission file, for runs that did not record their tree"
    )
    parser.add_argument(
        "--follow",
        action="store_true",
        help="serve the page on 127.0.0.1 and update it as the run writes its log",
    )
    parser.add_argument(
        "--port", type=int, default=8765, help="port for --follow (default 8765; 0 picks one)"
    )
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Write the page, or serve it until interrupted."""
    if args.follow:
        from missiontree.runlog.follow import make_server

        run_dir = args.run_path if args.run_path.suffix != ".jsonl" else args.run_path.parent
        if not run_dir.is_dir():
            raise ConfigError(
                f"run directory {str(run_dir)!r} does not exist; --follow watches a run directory "
                f"(it may be empty until the run starts writing)"
            )
        try:
            server = make_server(run_dir, args.port, args.mission)
        except OSError as error:
            raise ConfigError(
                f"cannot serve on 127.0.0.1:{args.port}: {error.strerror}; pick another --port"
            ) from error
        host, port = cast(tuple[str, int], server.server_address[:2])  # an AF_INET server's address
        print(f"viewing {run_dir} live at http://{host}:{port}/ (Ctrl-C stops)", flush=True)
        try:
            server.serve_forever()
        except KeyboardInterrupt:
            pass
        finally:
            server.server_close()
        return 0
    from missiontree.runlog.html import write_page

    if args.out is not None and args.out.is_dir():
        raise ConfigError(f"--out {args.out} is a directory; give a file name such as report.html")
    path = write_page(args.run_path, args.out, args.mission)
    size = path.stat().st_size
    print(f"wrote {path} ({size / 1e6:.2f} MB); open it in a browser", file=sys.stdout)
    return 0


#: Port of the live viewer ``run --view`` starts (0 in tests: any free port).
RUN_VIEW_PORT = 8765


def run_with_viewer(
    args: argparse.Namespace, request: Any, run_mission: Callable[[Any], Any], describe: Callable[[Any], str]
) -> int:
    """``run --view``: serve the live viewer of the run directory while ``run_mission(request)`` runs.

    The robot's pose is sampled every tick into ``poses.jsonl`` (the request's ``on_tick``), so the
    live map shows the path as it grows.

    When the run ends the page is also written as ``report.html`` in the run directory; on a
    terminal the viewer stays up until Ctrl-C, otherwise it stops with the run.
    """
    from missiontree.runlog.follow import serve_in_background
    from missiontree.runlog.html import write_page
    from missiontree.runlog.record import PoseTrail

    run_dir = args.out if args.out is not None else Path("runs") / args.tree.stem
    run_dir.mkdir(parents=True, exist_ok=True)
    port = int(getattr(args, "view_port", RUN_VIEW_PORT))
    try:
        server = serve_in_background(run_dir, port)
    except OSError as error:
        raise ConfigError(f"cannot serve the viewer on 127.0.0.1:{port}: {error.strerror}; "
                          f"another viewer may be running (or run `missiontree view --follow`)") from error
    host, bound = cast(tuple[str, int], server.server_address[:2])  # an AF_INET server's address
    print(f"live viewer at http://{host}:{bound}/", file=sys.stderr, flush=True)
    try:
        trail = PoseTrail(run_dir)
        previous = request.on_tick

        def on_tick(session: Any) -> None:
            trail(session)
            if previous is not None:
                previous(session)

        request.on_tick = on_tick
        try:
            result = run_mission(request)
        finally:
            trail.close()
        print(describe(result))
        if (run_dir / "ticks.jsonl").is_file():
            print(f"replay written to {write_page(run_dir)}")
        if sys.stdin.isatty():
            print(f"viewer still at http://{host}:{bound}/ (Ctrl-C stops)", file=sys.stderr, flush=True)
            try:
                threading.Event().wait()
            except KeyboardInterrupt:
                pass
        return int(result.exit_code)
    finally:
        server.shutdown()
        server.server_close()
