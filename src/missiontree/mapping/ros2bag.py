"""ROS 2 bags (MCAP, as rosbag2 writes them) read without a ROS install: scans, poses, RGB-D, map.

A rosbag2 MCAP file stores each message as CDR with its type's complete ``ros2msg`` definition
in the schema, so it decodes with the pure-Python ``mcap-ros2-support`` library (the
``realdata`` extra): no rclpy, no generated message classes. :func:`read_bag` reads the
TurtleBot 4 topics (:class:`BagTopics`, the names ``missiontree sim-ros`` and a TurtleBot 4
with Nav2 use) into a :class:`BagRecording`:

- **scans**: ``sensor_msgs/LaserScan`` as :class:`~missiontree.types.LaserScan`, with the
  lidar's mount yaw and x/y offset on the robot from /tf_static (``base_link`` → scan frame);
- **poses**: the robot's map pose from /tf (``map`` → ``odom`` → ``base_link``; ``odom`` →
  ``base_link`` alone when there is no ``map`` frame), or from ``nav_msgs/Odometry`` on /odom
  when /tf has no ``base_link``;
- **frames**: every colour image with the depth image nearest in stamp (within 0.2 s) and the
  latest camera_info, as :class:`BagFrame` (16UC1 depth is millimetres, 0 = no reading → NaN;
  32FC1 is metres); the camera's planar mount and height come from /tf_static, following the
  image's frame up to ``base_link`` (the optical frame's rotation is not planar and is skipped);
- **maps**: the ``nav_msgs/OccupancyGrid`` messages on /map (a SLAM map grows over the run).

A real camera's 30 frames a second, decoded, fill memory within minutes, and a SLAM map
republished every second can be megabytes each: by default images are thinned to 5 a second (by
header stamp, as the recorder's ``max_rate``) and maps to one a second (the latest always kept).

Times are the messages' header stamps (the sensors' times), not the recorder's receipt times.
"""

from __future__ import annotations

import bisect
import math
import struct
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from missiontree.errors import BackendUnavailableError
from missiontree.types import CameraIntrinsics, LaserScan, OccupancyGrid, Pose2D, RGBDFrame

#: Largest depth-to-colour stamp gap paired into one frame (s).
MAX_DEPTH_LAG = 0.2
#: Images kept a second at most by default (the TurtleBot 4 simulation's camera rate).
FRAME_RATE = 5.0
#: Least time (s) between two maps kept by default.
MAP_PERIOD = 1.0
#: Largest image side read (pixels).
MAX_SIDE = 8192
#: Most messages read from one topic (counted from the bag's summary before any is decoded): 55 hours
#: of scans at 10 Hz. Images and maps are thinned as they are read, so this bounds what is kept.
MAX_TOPIC_MESSAGES = 2_000_000
#: Most beams in one laser scan.
MAX_BEAMS = 100_000
#: The extra that brings the decoder.
INSTALL_HINT = "pip install 'missiontree[realdata]' (mcap and mcap-ros2-support)"

__all__ = ["BagError", "BagFrame", "BagRecording", "BagTopics", "color_from_image", "depth_from_image",
           "grid_from_msg", "image_pixels", "read_bag"]


class BagError(ValueError):
    """A bag that cannot be read: not MCAP, not rosbag2's CDR layout, or inconsistent messages."""


@dataclass(frozen=True)
class BagTopics:
    """Topic and frame names to read (defaults: the TurtleBot 4's)."""

    scan: str = "/scan"
    odom: str = "/odom"
    tf: str = "/tf"
    tf_static: str = "/tf_static"
    map: str = "/map"
    color: str = "/oakd/rgb/preview/image_raw"
    color_info: str = "/oakd/rgb/preview/camera_info"
    depth: str = "/oakd/stereo/image_raw"
    map_frame: str = "map"
    odom_frame: str = "odom"
    base_frame: str = "base_link"

    def namespaced(self, namespace: str) -> BagTopics:
        """The same names under a robot's namespace (``/robot1``: ``/robot1/scan``, ``/robot1/tf``...)."""
        prefix = "/" + namespace.strip("/") if namespace.strip("/") else ""
        topics = ("scan", "odom", "tf", "tf_static", "map", "color", "color_info", "depth")
        return replace(self, **{name: prefix + getattr(self, name) for name in topics})


@dataclass(frozen=True)
class BagFrame:
    """One colour image with its depth image, as recorded.

    Attributes:
        stamp: The colour image's stamp.
        color: HxWx3 uint8 RGB.
        depth: HxW float32 metres, NaN where there is no reading (resized to the colour image).
        intrinsics: The colour camera's pinhole intrinsics (camera_info's K).
        mount: The camera's planar pose on the robot (from /tf_static).
        height: The camera's height above the robot's base frame (m).
    """

    stamp: float
    color: np.ndarray
    depth: np.ndarray
    intrinsics: CameraIntrinsics
    mount: Pose2D = Pose2D(0.0, 0.0, 0.0)
    height: float = 0.0

    def to_frame(self, camera_pose: Pose2D | None = None) -> RGBDFrame:
        """The frame as an :class:`RGBDFrame`; ``camera_pose`` is the robot's pose (the mount is added)."""
        robot = camera_pose or Pose2D(0.0, 0.0, 0.0)
        return RGBDFrame(self.stamp, self.color, self.depth, self.intrinsics, compose(robot, self.mount),
                         self.height)


@dataclass
class BagRecording:
    """What :func:`read_bag` found.

    Attributes:
        source: The file read.
        topics: Message count per topic in the file (every topic, read or not).
        scans: The laser scans in stamp order.
        lidar_offset: The lidar's x/y on the robot (m).
        pose_stamps: Stamps of the pose track, increasing.
        poses: The robot's pose at each of ``pose_stamps``.
        pose_source: ``tf (map)``, ``tf (odom)`` or ``odometry``: where the poses came from.
        frames: RGB-D frames in stamp order.
        maps: The maps on /map in stamp order.
    """

    source: str
    topics: dict[str, int] = field(default_factory=dict)
    scans: list[LaserScan] = field(default_factory=list)
    lidar_offset: tuple[float, float] = (0.0, 0.0)
    pose_stamps: list[float] = field(default_factory=list)
    poses: list[Pose2D] = field(default_factory=list)
    pose_source: str = ""
    frames: list[BagFrame] = field(default_factory=list)
    maps: list[OccupancyGrid] = field(default_factory=list)

    def pose_at(self, stamp: float) -> Pose2D | None:
        """The pose at ``stamp`` interpolated along the track; None outside it."""
        return interpolate_track(self.pose_stamps, self.poses, stamp)


# ------------------------------------------------------------------------------------- geometry


def compose(a: Pose2D, b: Pose2D) -> Pose2D:
    """The pose ``b`` (given in frame ``a``) expressed in ``a``'s parent frame."""
    x, y = a.transform(b.x, b.y)
    yaw = a.yaw + b.yaw
    return Pose2D(x, y, math.atan2(math.sin(yaw), math.cos(yaw)))


def interpolate_track(stamps: list[float], poses: list[Pose2D], stamp: float) -> Pose2D | None:
    """The pose at ``stamp`` between the track's poses around it (heading on the shorter arc)."""
    if not stamps or stamp < stamps[0] or stamp > stamps[-1]:
        return None
    i = bisect.bisect_left(stamps, stamp)
    if stamps[i] == stamp or i == 0:
        return poses[i]
    t0, t1 = stamps[i - 1], stamps[i]
    a, b = poses[i - 1], poses[i]
    k = (stamp - t0) / (t1 - t0)
    turn = math.atan2(math.sin(b.yaw - a.yaw), math.cos(b.yaw - a.yaw))
    yaw = a.yaw + k * turn
    return Pose2D(a.x + k * (b.x - a.x), a.y + k * (b.y - a.y), math.atan2(math.sin(yaw), math.cos(yaw)))


def _yaw(q: Any) -> float:
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


def _planar(q: Any) -> bool:
    """Whether a quaternion is a rotation about z only."""
    return abs(q.x) < 1e-3 and abs(q.y) < 1e-3


def _stamp(header: Any) -> float:
    return float(header.stamp.sec) + float(header.stamp.nanosec) * 1e-9


def _pose_msg(pose: Any) -> Pose2D:
    return Pose2D(float(pose.position.x), float(pose.position.y), _yaw(pose.orientation))


# ------------------------------------------------------------------------------------- messages


def _decoded(path: Path, topics: set[str]) -> Iterator[tuple[str, Any]]:
    """(topic, decoded message) of the wanted topics, in log-time order."""
    try:
        from mcap.exceptions import McapError
        from mcap.reader import make_reader
        from mcap_ros2.decoder import DecoderFactory
    except ImportError as error:
        raise BackendUnavailableError(f"reading a ROS 2 bag needs mcap-ros2-support ({error}); "
                                      f"{INSTALL_HINT}") from None
    with path.open("rb") as stream:
        try:
            reader = make_reader(stream, decoder_factories=[DecoderFactory()])
            for _schema, channel, _message, decoded in reader.iter_decoded_messages(topics=sorted(topics)):
                yield channel.topic, decoded
        except (McapError, ValueError, KeyError, IndexError, struct.error, EOFError) as error:
            raise _bag_error(path, error) from None


def _bag_error(path: Path, error: Exception) -> BagError:
    """A :class:`BagError` naming the file and what went wrong."""
    return BagError(f"{path}: not a readable ROS 2 MCAP bag ({type(error).__name__}: {error})")


def _topic_counts(path: Path) -> dict[str, int]:
    from mcap.exceptions import McapError
    from mcap.reader import make_reader

    try:
        with path.open("rb") as stream:
            summary = make_reader(stream).get_summary()
    except (McapError, ValueError, struct.error, EOFError) as error:
        raise _bag_error(path, error) from None
    if summary is None:
        raise BagError(f"{path}: the MCAP file has no summary (was the recording cut off?)")
    stats = summary.statistics.channel_message_counts if summary.statistics else {}
    schemas = summary.schemas
    for channel in summary.channels.values():
        schema = schemas.get(channel.schema_id)
        if channel.message_encoding != "cdr" or schema is None or schema.encoding != "ros2msg":
            raise BagError(f"{path}: topic {channel.topic} is {channel.message_encoding!r} with a "
                           f"{schema.encoding if schema else 'missing'!r} schema; expected rosbag2's cdr "
                           "messages with ros2msg schemas")
    return {c.topic: int(stats.get(c.id, 0)) for c in summary.channels.values()}


#: The ``sensor_msgs/Image`` encodings read: (element type, channels).
IMAGE_ENCODINGS: dict[str, tuple[type, int]] = {
    "rgb8": (np.uint8, 3), "bgr8": (np.uint8, 3), "rgba8": (np.uint8, 4), "bgra8": (np.uint8, 4),
    "mono8": (np.uint8, 1), "8UC1": (np.uint8, 1), "8UC3": (np.uint8, 3), "16UC1": (np.uint16, 1),
    "mono16": (np.uint16, 1), "32FC1": (np.float32, 1)}

#: What raises a decoding problem: the bag reader's BagError, the live robot's BackendError.
ErrorMaker = Callable[[str], Exception]


def image_pixels(msg: Any, error: ErrorMaker = BagError) -> np.ndarray:
    """The pixels of a ``sensor_msgs/Image`` (decoded from a bag or received live), HxW or HxWxC.

    Row padding is dropped and the result is a native-endian copy. Raises ``error`` naming the frame
    for an unknown encoding, a size out of range or a message shorter than its header says.
    """
    if msg.encoding not in IMAGE_ENCODINGS:
        raise error(f"image on frame {msg.header.frame_id!r}: unsupported encoding {msg.encoding!r}; "
                    f"expected one of {', '.join(IMAGE_ENCODINGS)} (set the camera driver's output encoding)")
    if not (0 < msg.height <= MAX_SIDE and 0 < msg.width <= MAX_SIDE):
        raise error(f"image on frame {msg.header.frame_id!r}: {msg.width} x {msg.height} is out of range")
    kind, channels = IMAGE_ENCODINGS[msg.encoding]
    dtype = np.dtype(kind).newbyteorder(">" if msg.is_bigendian else "<")
    row = msg.step // dtype.itemsize
    raw = np.frombuffer(bytes(msg.data), dtype=dtype)
    if raw.size < msg.height * row or row < msg.width * channels:
        raise error(f"image on frame {msg.header.frame_id!r}: {raw.size} values for {msg.height} x "
                    f"{msg.width} x {channels} with step {msg.step}; the message is truncated")
    rows = raw[: msg.height * row].reshape(msg.height, row)[:, : msg.width * channels]
    shape = (msg.height, msg.width) if channels == 1 else (msg.height, msg.width, channels)
    return rows.reshape(shape).astype(dtype.newbyteorder("="))


def color_from_image(msg: Any, error: ErrorMaker = BagError) -> np.ndarray:
    """An HxWx3 uint8 RGB image from an 8-bit colour or mono ``sensor_msgs/Image``."""
    pixels = image_pixels(msg, error)
    if pixels.ndim == 2:
        return np.repeat(pixels[:, :, None].astype(np.uint8), 3, axis=2)
    if msg.encoding in ("bgr8", "bgra8"):
        return np.ascontiguousarray(pixels[:, :, 2::-1])
    return np.ascontiguousarray(pixels[:, :, :3].astype(np.uint8))


def depth_from_image(msg: Any, error: ErrorMaker = BagError) -> np.ndarray:
    """HxW float32 metres from a depth image: 16UC1 millimetres (0 = no reading → NaN), 32FC1."""
    pixels = image_pixels(msg, error)
    if msg.encoding in ("16UC1", "mono16"):
        depth = pixels.astype(np.float32) / 1000.0
        depth[pixels == 0] = np.nan
        return depth
    if msg.encoding == "32FC1":
        return pixels.astype(np.float32)
    raise error(f"depth image on frame {msg.header.frame_id!r}: {msg.encoding!r} is not a depth encoding "
                "(expected 16UC1 millimetres or 32FC1 metres)")


def grid_from_msg(msg: Any, error: ErrorMaker = BagError) -> OccupancyGrid:
    """An :class:`OccupancyGrid` (row 0 = lowest y, as in ROS) from a ``nav_msgs/OccupancyGrid``.

    Decoded from a bag or received live; raises ``error`` naming the frame when the cells do not
    fill width x height.
    """
    info = msg.info
    data = np.asarray(msg.data, dtype=np.int8)
    if data.size != info.width * info.height:
        raise error(f"map on frame {msg.header.frame_id!r}: {data.size} cells for "
                    f"{info.width} x {info.height}")
    return OccupancyGrid(_stamp(msg.header), float(info.resolution), _pose_msg(info.origin),
                         data.reshape(info.height, info.width).copy())


# ------------------------------------------------------------------------------------- the bag


@dataclass
class _Collected:
    """The wanted messages of a bag, grouped as read."""

    scans: list[Any] = field(default_factory=list)
    dynamic: dict[tuple[str, str], list[tuple[float, Pose2D]]] = field(default_factory=dict)
    static: dict[str, tuple[str, Pose2D, float, bool]] = field(default_factory=dict)
    odom: list[tuple[float, Pose2D]] = field(default_factory=list)
    colors: list[tuple[float, str, np.ndarray]] = field(default_factory=list)
    depths: list[tuple[float, np.ndarray]] = field(default_factory=list)
    info: CameraIntrinsics | None = None
    infos: list[tuple[float, CameraIntrinsics]] = field(default_factory=list)
    maps: list[OccupancyGrid] = field(default_factory=list)


class _Slots:
    """Keeps a stamp when it enters a new 1/rate-second slot (all stamps without a rate)."""

    def __init__(self, rate: float | None) -> None:
        self.rate = rate
        self.last: int | None = None

    def keep(self, stamp: float) -> bool:
        if self.rate is None:
            return True
        slot = math.floor(stamp * self.rate)
        if slot == self.last:
            return False
        self.last = slot
        return True


def _add_map(maps: list[OccupancyGrid], grid: OccupancyGrid, period: float) -> None:
    """Append a map, or replace the latest when it is under ``period`` newer than the one before it."""
    if len(maps) >= 2 and maps[-1].stamp - maps[-2].stamp < period:
        maps[-1] = grid
    else:
        maps.append(grid)


def _collect(path: Path, names: BagTopics, frame_rate: float | None, map_period: float) -> _Collected:
    got = _Collected()
    colours, depths = _Slots(frame_rate), _Slots(frame_rate)
    for topic, msg in _decoded(path, {names.scan, names.odom, names.tf, names.tf_static, names.map,
                                      names.color, names.color_info, names.depth}):
        if topic == names.scan:
            if len(msg.ranges) > MAX_BEAMS:
                raise BagError(f"{path}: a scan on {topic} has {len(msg.ranges):,} beams; expected at most "
                               f"{MAX_BEAMS:,}")
            got.scans.append(msg)
        elif topic in (names.tf, names.tf_static):
            for t in msg.transforms:
                parent, child = t.header.frame_id.lstrip("/"), t.child_frame_id.lstrip("/")
                tr, q = t.transform.translation, t.transform.rotation
                pose = Pose2D(float(tr.x), float(tr.y), _yaw(q))
                if topic == names.tf_static:
                    got.static[child] = (parent, pose, float(tr.z), _planar(q))
                else:
                    got.dynamic.setdefault((parent, child), []).append((_stamp(t.header), pose))
        elif topic == names.odom:
            got.odom.append((_stamp(msg.header), _pose_msg(msg.pose.pose)))
        elif topic == names.color and colours.keep(_stamp(msg.header)):
            got.colors.append((_stamp(msg.header), msg.header.frame_id.lstrip("/"), color_from_image(msg)))
        elif topic == names.depth and depths.keep(_stamp(msg.header)):
            got.depths.append((_stamp(msg.header), depth_from_image(msg)))
        elif topic == names.color_info:
            k = msg.k
            intrinsics = CameraIntrinsics(int(msg.width), int(msg.height), float(k[0]), float(k[4]),
                                          float(k[2]), float(k[5]))
            got.infos.append((_stamp(msg.header), intrinsics))
        elif topic == names.map:
            _add_map(got.maps, grid_from_msg(msg), map_period)
    return got


def _track(got: _Collected, names: BagTopics) -> tuple[list[float], list[Pose2D], str]:
    """The robot's pose track: map → odom → base from /tf, else odom → base, else /odom."""
    base = sorted(got.dynamic.get((names.odom_frame, names.base_frame), []), key=lambda p: p[0])
    if base:
        drift = sorted(got.dynamic.get((names.map_frame, names.odom_frame), []), key=lambda p: p[0])
        if not drift:
            return [t for t, _ in base], [p for _, p in base], "tf (odom)"
        stamps, poses = [t for t, _ in drift], [p for _, p in drift]
        track = []
        for t, p in base:  # map -> odom at t: interpolated, or the nearest end outside the track
            correction = interpolate_track(stamps, poses, min(max(t, stamps[0]), stamps[-1]))
            track.append((t, compose(correction or poses[0], p)))
        return [t for t, _ in track], [p for _, p in track], "tf (map)"
    odom = sorted(got.odom, key=lambda p: p[0])
    return [t for t, _ in odom], [p for _, p in odom], "odometry" if odom else ""


def _mount(got: _Collected, frame: str, base: str) -> tuple[Pose2D, float] | None:
    """The planar pose and height of ``frame`` on the robot, following /tf_static up to ``base``."""
    pose, z = Pose2D(0.0, 0.0, 0.0), 0.0
    for _ in range(32):
        if frame == base:
            return pose, z
        link = got.static.get(frame)
        if link is None:
            return None
        parent, step, dz, planar = link
        pose = compose(step, pose) if planar else Pose2D(step.x + pose.x, step.y + pose.y, pose.yaw)
        z += dz
        frame = parent
    return None


def _frames(got: _Collected, names: BagTopics) -> list[BagFrame]:
    """Each colour image with the nearest depth (within MAX_DEPTH_LAG) and the camera_info before it."""
    depth_stamps = [t for t, _ in sorted(got.depths, key=lambda d: d[0])]
    depths = [d for _, d in sorted(got.depths, key=lambda d: d[0])]
    infos = sorted(got.infos, key=lambda i: i[0])
    frames = []
    for stamp, frame_id, color in sorted(got.colors, key=lambda c: c[0]):
        i = bisect.bisect_left(depth_stamps, stamp)
        near = [j for j in (i - 1, i) if 0 <= j < len(depths)]
        k = bisect.bisect_right([t for t, _ in infos], stamp + 1e-6) - 1
        if not near or not infos:
            continue
        j = min(near, key=lambda j: abs(depth_stamps[j] - stamp))
        if abs(depth_stamps[j] - stamp) > MAX_DEPTH_LAG:
            continue
        depth = depths[j]
        if depth.shape != color.shape[:2]:  # OAK-D stereo depth is not registered to the preview image
            import cv2

            depth = cv2.resize(depth, (color.shape[1], color.shape[0]), interpolation=cv2.INTER_NEAREST)
        mount = _mount(got, frame_id, names.base_frame) or (Pose2D(0.0, 0.0, 0.0), 0.0)
        frames.append(BagFrame(stamp, color, depth, infos[max(k, 0)][1], mount[0], mount[1]))
    return frames


def read_bag(path: str | Path, names: BagTopics | None = None, *, frame_rate: float | None = FRAME_RATE,
             map_period: float = MAP_PERIOD) -> BagRecording:
    """Read a rosbag2 MCAP file's scans, poses, RGB-D frames and maps (see the module docstring).

    Args:
        path: The ``.mcap`` file.
        names: Topic and frame names (default: the TurtleBot 4's).
        frame_rate: Images kept a second at most, by header stamp (None: every one): a real
            camera's 30 frames a second would fill memory within minutes.
        map_period: Maps kept at least this many seconds apart, the latest always kept (a SLAM
            map republished every second can be megabytes each).

    Raises:
        BagError: The file is not a rosbag2 MCAP bag, or a message is inconsistent.
        BackendUnavailableError: ``mcap-ros2-support`` is not installed.
    """
    names = names or BagTopics()
    path = Path(path)
    if not path.is_file():
        raise BagError(f"{path}: no such bag file")
    counts = _topic_counts(path)
    if frame_rate is not None and frame_rate <= 0:
        raise BagError(f"frame_rate must be positive or None, found {frame_rate}")
    for topic in (names.scan, names.odom, names.tf, names.tf_static, names.color_info):
        if counts.get(topic, 0) > MAX_TOPIC_MESSAGES:
            raise BagError(f"{path}: {topic} holds {counts[topic]:,} messages, over the limit of "
                           f"{MAX_TOPIC_MESSAGES:,} a topic read whole (split the bag)")
    got = _collect(path, names, frame_rate, map_period)
    stamps, poses, source = _track(got, names)
    scans = []
    mount_yaw, offset = 0.0, (0.0, 0.0)
    if got.scans:
        mount = _mount(got, got.scans[0].header.frame_id.lstrip("/"), names.base_frame)
        if mount is not None:
            mount_yaw, offset = mount[0].yaw, (mount[0].x, mount[0].y)
    for msg in sorted(got.scans, key=lambda m: _stamp(m.header)):
        scans.append(LaserScan(stamp=_stamp(msg.header), angle_min=float(msg.angle_min),
                               angle_increment=float(msg.angle_increment), range_min=float(msg.range_min),
                               range_max=float(msg.range_max), ranges=np.asarray(msg.ranges, np.float32),
                               mount_yaw=mount_yaw, frame_id=msg.header.frame_id))
    return BagRecording(str(path), counts, scans, offset, stamps, poses, source, _frames(got, names),
                        sorted(got.maps, key=lambda g: g.stamp))
