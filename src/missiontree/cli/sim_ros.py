"""``missiontree sim-ros --world W``: the simulator served as a ROS 2 robot until SIGINT/SIGTERM.

Publishes the TurtleBot 4 topics (/scan, /odom, the OAK-D images, /tf, /tf_static, /map) and
serves NavigateToPose with the simulator's navigation, paced in real time, so that
``missiontree run TREE --backend ros2``, RViz and other ROS 2 tools run against it; the installed
plugins' sensors are simulated and published on their topics (``--no-plugins``: none). Needs the
``ros2`` extra (see docs/ros2.md). With ``--unknown-map`` the robot starts knowing nothing and
/map is the map it learns from its lidar, republished as it grows. Exit code 0 after a signal or
``--duration``, 2 on bad input or when ROS 2 support is not installed.
"""

from __future__ import annotations

import argparse
import os
import signal
import sys
import threading
from types import FrameType
from typing import Any

from missiontree.cli import add_plugin_flag, plugins_from_args

DEFAULT_WORLD = "office"


def register(subparsers: Any) -> None:
    """Add the ``sim-ros`` subcommand."""
    parser = subparsers.add_parser(
        "sim-ros", help="serve the simulator as a ROS 2 robot (topics, TF, /map, NavigateToPose)",
        description="Serve a simulated TurtleBot 4 over ROS 2 in real time until interrupted: the same "
        "topics, TF, /map and NavigateToPose action server as the robot with Nav2.",
    )
    parser.add_argument("--world", default=DEFAULT_WORLD,
                        help=f"simulator world: a shipped name or a path (default {DEFAULT_WORLD})")
    parser.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    parser.add_argument("--robot", help="simulated robot profile (default: the world's, normally turtlebot4)")
    parser.add_argument("--profile", default="turtlebot4",
                        help="ROS 2 profile naming the topics and frames to serve (config/backends; "
                        "default turtlebot4)")
    parser.add_argument("--rate", type=float, default=1.0,
                        help="simulated seconds per wall second (default 1.0: real time; without --sim-time "
                        "other rates make stamps drift from ROS time)")
    parser.add_argument("--sim-time", action="store_true",
                        help="stamp with simulated time and publish /clock, as Gazebo with use_sim_time "
                        "(clients set use_sim_time: true in their profile); any --rate then stays consistent")
    parser.add_argument("--paused", action="store_true",
                        help="hold the clock at 0 until the first goal or velocity command (or a 'resume' "
                        "on /missiontree/sim/control), so a mission starts with the world's clock")
    parser.add_argument("--unknown-map", action="store_true",
                        help="start knowing nothing: /map is the map the robot learns from its lidar, "
                        "republished as it grows (as slam_toolbox does), and NavigateToPose plans on it")
    parser.add_argument("--robots", type=int, default=1, metavar="N",
                        help="serve N robots in one world, each under its own namespace (/robot1/scan, "
                        "/robot1/tf, /robot1/navigate_to_pose, ...); default 1: one robot, no namespace")
    parser.add_argument("--kill-robot", action="append", default=[], metavar="NAME@S",
                        help="with --robots: robot NAME's NavigateToPose server vanishes at S simulated "
                        "seconds, as when its Nav2 crashes (it stops where it stands; its sensors and TF go "
                        "on); repeatable")
    parser.add_argument("--duration", type=float, metavar="S", help="stop after S wall seconds")
    parser.add_argument("--domain-id", type=int, metavar="N",
                        help="ROS_DOMAIN_ID to serve on (default: the environment's)")
    add_plugin_flag(parser)  # plugin sensors are simulated and published on their topics
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Serve the simulator over ROS 2 until SIGINT/SIGTERM (or ``--duration``)."""
    from missiontree.errors import ConfigError
    from missiontree.session.fleet import parse_kill, robot_count
    from missiontree.session.worlds import sim_ros_bridge

    if args.rate <= 0:
        raise ConfigError(f"--rate must be positive, found {args.rate}")
    robots = robot_count(args.robots, None, None)
    kills = [(kill.robot, kill.at) for kill in map(parse_kill, args.kill_robot)]
    options = {"world": args.world, "seed": args.seed, "robot": args.robot, "unknown_map": args.unknown_map,
               "sensors": list(plugins_from_args(args).sensors.values())}
    bridge, profile = sim_ros_bridge(options, {"profile": args.profile, "domain_id": args.domain_id},
                                     rate=args.rate, sim_time=args.sim_time, paused=args.paused,
                                     robots=robots, kills=kills)
    stop_signal: list[int] = []

    def on_signal(signum: int, frame: FrameType | None) -> None:
        stop_signal.append(signum)
        bridge.shutdown()

    previous = {}
    if threading.current_thread() is threading.main_thread():
        for sig in (signal.SIGINT, signal.SIGTERM):
            previous[sig] = signal.signal(sig, on_signal)
    domain = profile.domain_id if profile.domain_id is not None else os.environ.get("ROS_DOMAIN_ID", "0")
    mapping = "; learning /map from the lidar (unknown map)" if args.unknown_map else ""
    first = profile.namespace
    served = (f"{robots} robots under /robot1 ... /robot{robots} (scan {first}/{profile.topics.scan}, "
              f"action {first}/{profile.navigation.action})" if robots > 1 else
              f"scan {profile.topics.scan}, action {profile.navigation.action}")
    print(f"missiontree sim-ros: serving world {args.world!r} (seed {args.seed}){mapping} as {profile.name} "
          f"on ROS_DOMAIN_ID={domain}; {served}; Ctrl-C to stop", flush=True)
    try:
        bridge.run(duration=args.duration)
    finally:
        bridge.close()
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    why = signal.Signals(stop_signal[0]).name if stop_signal else "duration reached"
    print(f"missiontree sim-ros: stopped ({why}) after {bridge.sim.now():.1f} s simulated, "
          f"{sum(b.goals_served for b in [bridge, *bridge.peers])} goals served, {bridge.resets} resets",
          file=sys.stderr, flush=True)
    return 0
