"""``missiontree bag record|info``: record a ROS 2 bag from a running robot, or say what one holds.

``bag record --out FILE.mcap --duration S`` subscribes over DDS (the ``ros2`` extra) to the
TurtleBot 4 topics (or ``--topics``) and writes them as rosbag2's MCAP storage does, so
``ros2 bag info``/``play`` and Foxglove read the file and ``missiontree run ... --backend recorded
--world FILE.mcap`` plays it. ``--max-rate TOPIC=HZ`` thins a topic by its header stamps (the
camera's three topics together when given the same rate). ``bag info FILE.mcap`` needs no ROS
(the ``realdata`` extra): topics and counts, and what the recorded backend reads from them.
Bad input prints one line and exits 2; ROS 2 support missing also exits 2 with how to install it.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from missiontree.errors import ConfigError

EXIT_OK = 0


def register(subparsers: Any) -> None:
    """Add the ``bag`` subcommand (with ``bag record`` and ``bag info``)."""
    parser = subparsers.add_parser(
        "bag", help="record a ROS 2 bag (MCAP) from a robot, or show what one holds",
        description="Record a ROS 2 bag in rosbag2's MCAP layout from a running robot (e.g. `missiontree "
        "sim-ros`), or summarise one; `missiontree run ... --backend recorded --world FILE.mcap` plays it.",
    )
    actions = parser.add_subparsers(dest="bag_command", metavar="ACTION", required=True)
    record = actions.add_parser(
        "record", help="record topics over DDS into an .mcap file",
        description="Subscribe to the topics (default: the TurtleBot 4's scan, odom, tf, tf_static, map and "
        "the OAK-D colour, camera_info and depth) and write them for S seconds into FILE, as rosbag2's MCAP "
        "storage plugin does.")
    record.add_argument("--out", type=Path, required=True, help="the .mcap file to write")
    record.add_argument("--duration", type=float, required=True, metavar="S", help="wall seconds to record")
    record.add_argument("--topics", nargs="+", metavar="TOPIC",
                        help="topics to record (default: TurtleBot 4's)")
    record.add_argument("--namespace", default="",
                        help="the robot's namespace, put before the default topics (e.g. /robot1)")
    record.add_argument("--max-rate", action="append", default=[], metavar="TOPIC=HZ",
                        help="keep at most HZ messages a second of TOPIC, by header stamp (repeatable)")
    record.add_argument("--domain-id", type=int, metavar="N",
                        help="ROS_DOMAIN_ID (default: the environment's)")
    record.add_argument("--discovery-timeout", type=float, default=10.0, metavar="S",
                        help="seconds to wait for the topics' publishers (default 10)")
    record.add_argument("--compression", default="zstd", choices=("zstd", "lz4", "none"),
                        help="chunk compression (default zstd)")
    record.set_defaults(func=run_record)
    info = actions.add_parser("info",
                              help="topics, counts and what the recorded backend reads (no ROS needed)")
    info.add_argument("bag", type=Path, help="the .mcap file")
    info.add_argument("--namespace", default="", help="the robot's namespace in the bag (e.g. /robot1)")
    info.set_defaults(func=run_info)


def _rates(items: list[str]) -> dict[str, float]:
    rates = {}
    for item in items:
        topic, sep, value = item.rpartition("=")
        try:
            rates[topic] = float(value)
        except ValueError:
            topic = ""
        if not sep or not topic:
            raise ConfigError(f"--max-rate: expected TOPIC=HZ, found {item!r}")
    return rates


def run_record(args: argparse.Namespace) -> int:
    """Record a bag and print what was written."""
    from missiontree.session.ros2bag import default_topics, record_bag

    if not str(args.out).endswith(".mcap"):
        raise ConfigError(f"--out: expected an .mcap file name, found {args.out}")
    prefix = "/" + args.namespace.strip("/") if args.namespace.strip("/") else ""
    topics = args.topics or [prefix + t for t in default_topics()]
    summary = record_bag(args.out, args.duration, topics, domain_id=args.domain_id,
                         max_rate=_rates(args.max_rate), discovery_timeout=args.discovery_timeout,
                         compression=args.compression)
    size = summary.path.stat().st_size / 1e6
    print(f"recorded {summary.seconds:.1f} s into {summary.path} ({size:.2f} MB)")
    for topic in sorted(summary.counts):
        dropped = summary.dropped.get(topic, 0)
        thinned = f", {dropped} thinned out" if dropped else ""
        print(f"  {topic}: {summary.counts[topic]} x {summary.types[topic]}{thinned}")
    for topic in summary.missing:
        print(f"  {topic}: no publisher found; not recorded")
    return EXIT_OK


def run_info(args: argparse.Namespace) -> int:
    """Print a bag's topics and what the recorded backend reads from it."""
    from missiontree.errors import BackendUnavailableError
    from missiontree.mapping.ros2bag import BagError, BagTopics, read_bag

    try:
        bag = read_bag(args.bag, BagTopics().namespaced(args.namespace))
    except (BagError, BackendUnavailableError) as error:
        raise ConfigError(str(error)) from None
    for topic, count in sorted(bag.topics.items()):
        print(f"{topic}: {count}")
    span = (bag.scans[-1].stamp - bag.scans[0].stamp) if bag.scans else 0.0
    print(f"scans: {len(bag.scans)} over {span:.1f} s; poses: {len(bag.poses)} from "
          f"{bag.pose_source or 'nothing'}; RGB-D frames: {len(bag.frames)}; maps: {len(bag.maps)}")
    return EXIT_OK
