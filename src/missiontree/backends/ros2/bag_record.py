"""Record a ROS 2 bag (MCAP, as rosbag2 writes it) from a running robot over DDS.

:func:`record_bag` subscribes to topics with rclpy *raw* subscriptions (the serialized CDR is
written as it came, nothing is decoded) and writes them into one ``.mcap`` file laid out as
rosbag2's MCAP storage plugin lays it out, so ``ros2 bag info``, ``ros2 bag play`` and Foxglove
read it: the ``ros2`` profile; one schema per message type named ``pkg/msg/Type`` with encoding
``ros2msg`` and the complete message definition (the type's ``.msg`` text followed by every type
it uses, each after a line of 80 ``=`` and ``MSG: pkg/msg/Type``); one channel per topic with
message encoding ``cdr`` and the publishers' ``offered_qos_profiles`` (and ``topic_type_hash``)
in its metadata; log time
= the time of receipt. The subscription's QoS follows the publishers' (reliable and transient
local only where every publisher offers it), as rosbag2 does, so a latched /map and /tf_static
arrive. Chunks are zstd-compressed (``compression``), which rosbag2 and Foxglove also read.

``max_rate`` thins topics by their messages' header stamps (all header-first types): a message
is kept when its stamp falls in a new 1/rate-second slot, so a colour image, its camera_info
and its depth image (same stamp) are kept or dropped together. That keeps a bag small without
changing any message.
"""

from __future__ import annotations

import importlib
import math
import os
import struct
import sys
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from missiontree.errors import BackendError, ConfigError

#: The TurtleBot 4 topics recorded by default (the ``turtlebot4`` profile's names).
DEFAULT_TOPICS = ("/scan", "/odom", "/tf", "/tf_static", "/map", "/oakd/rgb/preview/image_raw",
                  "/oakd/rgb/preview/camera_info", "/oakd/stereo/image_raw")
#: The line between definitions in a ``ros2msg`` schema.
SEPARATOR = "=" * 80
_PRIMITIVES = {"bool", "byte", "char", "float32", "float64", "int8", "uint8", "int16", "uint16", "int32",
               "uint32", "int64", "uint64", "string", "wstring"}


@dataclass
class BagSummary:
    """What :func:`record_bag` wrote.

    Attributes:
        path: The ``.mcap`` file.
        seconds: Wall seconds recorded.
        counts: Messages written per topic (0 for a topic found but silent).
        types: Message type per topic recorded.
        missing: Topics asked for that no publisher offered within the discovery time.
        dropped: Messages left out by ``max_rate`` per topic.
    """

    path: Path
    seconds: float
    counts: dict[str, int] = field(default_factory=dict)
    types: dict[str, str] = field(default_factory=dict)
    missing: list[str] = field(default_factory=list)
    dropped: dict[str, int] = field(default_factory=dict)


def _msg_file(package: str, name: str) -> Path:
    """The ``.msg`` file of ``package/msg/name`` in the ament index (AMENT_PREFIX_PATH, then the venv)."""
    prefixes = [p for p in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p] + [sys.prefix]
    for prefix in prefixes:
        path = Path(prefix) / "share" / package / "msg" / f"{name}.msg"
        if path.is_file():
            return path
    raise BackendError(f"no definition of {package}/msg/{name} under {prefixes} (share/{package}/msg/"
                       f"{name}.msg); is the interface package installed?")


def msg_dependencies(text: str, package: str) -> list[str]:
    """The ``pkg/msg/Type`` names of the non-primitive fields of a ``.msg`` text, in order."""
    found: list[str] = []
    for line in text.splitlines():
        words = line.split("#", 1)[0].split()
        if len(words) < 2:
            continue
        base = words[0].split("[", 1)[0].split("<=", 1)[0]
        constant = "=" in words[1] or (len(words) > 2 and words[2].startswith("="))
        if base in _PRIMITIVES or constant:
            continue
        pkg, _, name = base.rpartition("/")
        if base == "Header" and not pkg:
            pkg = "std_msgs"
        full = f"{pkg or package}/msg/{name}"
        if full not in found:
            found.append(full)
    return found


def message_definition(type_name: str) -> str:
    """The complete ``ros2msg`` definition of ``pkg/msg/Type``, as rosbag2 writes it in a schema.

    Raises:
        BackendError: A definition (the type's or one it uses) is not installed.
    """
    def text_of(full: str) -> str:
        package, _, name = full.split("/")
        return _msg_file(package, name).read_text(encoding="utf-8")

    root = text_of(type_name)
    parts, seen = [root], {type_name}
    queue = msg_dependencies(root, type_name.split("/")[0])
    while queue:
        dep = queue.pop(0)
        if dep in seen:
            continue
        seen.add(dep)
        text = text_of(dep)
        parts.append(f"{SEPARATOR}\nMSG: {dep}\n{text}")
        queue.extend(msg_dependencies(text, dep.split("/")[0]))
    return "\n".join(parts)


def header_stamp(data: bytes) -> float:
    """The header stamp of a serialized header-first message (after CDR's 4-byte encapsulation)."""
    if len(data) < 12:
        return math.nan
    little = data[1] == 1  # CDR_LE
    sec, nsec = struct.unpack_from("<iI" if little else ">iI", data, 4)
    return sec + nsec * 1e-9


def _qos_yaml(infos: Sequence[Any]) -> str:
    """The publishers' offered QoS profiles as rosbag2's ``offered_qos_profiles`` YAML."""
    rows = []
    for info in infos:
        q = info.qos_profile
        never = "\n    sec: 2147483647\n    nsec: 4294967295\n"  # rosbag2's "infinite" duration
        rows.append(f"- history: {int(q.history)}\n  depth: {int(q.depth)}\n"
                    f"  reliability: {int(q.reliability)}\n  durability: {int(q.durability)}\n"
                    f"  deadline:{never}  lifespan:{never}  liveliness: {int(q.liveliness)}\n"
                    f"  liveliness_lease_duration:{never}  avoid_ros_namespace_conventions: false")
    return "\n".join(rows) if rows else "[]"


def type_hash(info: Any) -> str:
    """A publisher's type hash as ROS writes it (``RIHS01_<hex>``); empty when it has none."""
    found = getattr(info, "topic_type_hash", None)
    version = getattr(found, "version", -1)
    if found is None or version < 1:
        return ""
    return f"RIHS{version:02d}_{bytes(found.value).hex()}"


def _subscription_qos(infos: Sequence[Any]) -> Any:
    """Reliable / transient local only where every publisher offers it (what rosbag2 does)."""
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

    reliable = bool(infos) and all(i.qos_profile.reliability == ReliabilityPolicy.RELIABLE for i in infos)
    latched = bool(infos) and all(i.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL for i in infos)
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=100,
                      reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
                      durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE)


def _message_class(type_name: str) -> Any:
    package, _, name = type_name.split("/")
    try:
        return getattr(importlib.import_module(f"{package}.msg"), name)
    except (ImportError, AttributeError) as error:
        raise BackendError(f"cannot record a {type_name} topic: its Python interface does not import "
                           f"({error})") from None


class StampThrottle:
    """Keeps a message when its header stamp enters a new 1/rate slot (see the module docstring)."""

    def __init__(self, rate: float) -> None:
        self.rate = rate
        self.slot: int | None = None

    def keep(self, data: bytes) -> bool:
        """Whether to write this serialized message (a message without a stamp is always kept)."""
        stamp = header_stamp(data)
        if not math.isfinite(stamp):
            return True
        slot = math.floor(stamp * self.rate)
        if slot == self.slot:
            return False
        self.slot = slot
        return True


def record_bag(out: str | Path, duration: float, topics: Sequence[str] | None = None, *,
               domain_id: int | None = None, max_rate: Mapping[str, float] | None = None,
               discovery_timeout: float = 10.0, compression: str = "zstd") -> BagSummary:
    """Record ``topics`` (default :data:`DEFAULT_TOPICS`) for ``duration`` wall seconds into ``out``.

    Waits up to ``discovery_timeout`` seconds for every topic to have a publisher; topics still
    without one are left out and listed in the summary's ``missing`` (an error when none is found).

    Raises:
        ConfigError: A non-positive duration or rate.
        BackendError: No topic found, or a type whose definition is not installed.
    """
    import rclpy
    from mcap.writer import CompressionType, Writer
    from rclpy.signals import SignalHandlerOptions

    if duration <= 0:
        raise ConfigError(f"the recording's duration must be positive, found {duration}")
    if compression.upper() not in CompressionType.__members__:
        raise ConfigError(f"unknown compression {compression!r}; expected zstd, lz4 or none")
    rates = dict(max_rate or {})
    if any(r <= 0 for r in rates.values()):
        raise ConfigError(f"max rates must be positive, found {rates}")
    wanted = list(topics or DEFAULT_TOPICS)
    context = rclpy.Context()
    rclpy.init(context=context, domain_id=domain_id, signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node("missiontree_bag_recorder", context=context)
    executor = rclpy.executors.SingleThreadedExecutor(context=context)
    executor.add_node(node)
    path = Path(out)
    try:
        found = _discover(node, executor, wanted, discovery_timeout)
        if not found:
            domain = domain_id if domain_id is not None else "from the environment"
            raise BackendError(f"no publisher of any of {wanted} within {discovery_timeout:g} s "
                               f"(ROS_DOMAIN_ID {domain})")
        path.parent.mkdir(parents=True, exist_ok=True)
        summary = BagSummary(path, 0.0, types=dict(found), missing=[t for t in wanted if t not in found])
        with path.open("wb") as stream:
            writer = Writer(stream, compression=CompressionType[compression.upper()])
            writer.start(profile="ros2", library="missiontree bag record (rosbag2 MCAP layout)")
            started = time.monotonic()
            try:  # a Ctrl-C still leaves a complete file (summary and index written)
                _subscribe(node, writer, found, rates, summary)
                while time.monotonic() - started < duration and context.ok():
                    executor.spin_once(timeout_sec=0.05)
            finally:
                summary.seconds = time.monotonic() - started
                writer.finish()
        return summary
    finally:
        executor.shutdown(timeout_sec=1.0)
        node.destroy_node()
        context.try_shutdown()


def _discover(node: Any, executor: Any, wanted: list[str], timeout: float) -> dict[str, str]:
    """Topic -> type of the wanted topics that have a publisher, waiting up to ``timeout`` for all."""
    deadline = time.monotonic() + timeout
    found: dict[str, str] = {}
    while True:
        names = dict(node.get_topic_names_and_types())
        found = {t: names[t][0] for t in wanted if names.get(t) and node.get_publishers_info_by_topic(t)}
        if len(found) == len(wanted) or time.monotonic() >= deadline:
            return found
        executor.spin_once(timeout_sec=0.1)


def _subscribe(node: Any, writer: Any, found: dict[str, str], rates: dict[str, float],
               summary: BagSummary) -> None:
    """One schema per type, one channel and one raw subscription per topic."""
    schemas: dict[str, int] = {}
    for topic, type_name in sorted(found.items()):
        if type_name not in schemas:
            schemas[type_name] = writer.register_schema(
                name=type_name, encoding="ros2msg", data=message_definition(type_name).encode("utf-8"))
        infos = node.get_publishers_info_by_topic(topic)
        metadata = {"offered_qos_profiles": _qos_yaml(infos)}
        hashes = {type_hash(i) for i in infos} - {""}
        if len(hashes) == 1:  # as rosbag2 on Jazzy: the type's RIHS01 hash
            metadata["topic_type_hash"] = hashes.pop()
        channel = writer.register_channel(topic=topic, message_encoding="cdr", schema_id=schemas[type_name],
                                          metadata=metadata)
        summary.counts[topic] = 0
        throttle = StampThrottle(rates[topic]) if topic in rates else None

        def on_message(data: bytes, topic: str = topic, channel: int = channel,
                       throttle: StampThrottle | None = throttle) -> None:
            if throttle is not None and not throttle.keep(data):
                summary.dropped[topic] = summary.dropped.get(topic, 0) + 1
                return
            now = time.time_ns()
            writer.add_message(channel_id=channel, log_time=now, publish_time=now, data=bytes(data),
                               sequence=summary.counts[topic])
            summary.counts[topic] += 1

        node.create_subscription(_message_class(type_name), topic, on_message, _subscription_qos(infos),
                                 raw=True)
