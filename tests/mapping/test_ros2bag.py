"""The ROS 2 bag reader on a bag recorded from `missiontree sim-ros` (office, unknown map), no ROS needed."""

from __future__ import annotations

import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

pytest.importorskip("mcap_ros2", reason="mcap-ros2-support missing: pip install 'missiontree[realdata]'")

from mcap.reader import make_reader  # noqa: E402
from mcap_ros2.writer import Writer as Ros2Writer  # noqa: E402

from missiontree.mapping import ros2bag  # noqa: E402
from missiontree.mapping.ros2bag import (  # noqa: E402
    BagError,
    BagTopics,
    color_from_image,
    depth_from_image,
    read_bag,
)

pytestmark = pytest.mark.realdata

BAG = Path(__file__).resolve().parents[1] / "data" / "ros2bag" / "sim_office.mcap"


@pytest.fixture(scope="module")
def bag():
    """The committed bag, read once."""
    return read_bag(BAG)


def test_the_bag_is_laid_out_as_rosbag2_writes_mcap() -> None:
    """ros2 profile, cdr channels with offered QoS, ros2msg schemas holding the complete definitions."""
    with BAG.open("rb") as stream:
        reader = make_reader(stream)
        assert reader.get_header().profile == "ros2"
        summary = reader.get_summary()
    assert summary is not None
    for channel in summary.channels.values():
        schema = summary.schemas[channel.schema_id]
        assert channel.message_encoding == "cdr" and schema.encoding == "ros2msg"
        assert "offered_qos_profiles" in channel.metadata
    scan = next(s for s in summary.schemas.values() if s.name == "sensor_msgs/msg/LaserScan")
    text = scan.data.decode()
    assert "MSG: std_msgs/msg/Header" in text and "MSG: builtin_interfaces/msg/Time" in text


def test_it_is_small_and_holds_every_turtlebot4_topic(bag) -> None:
    """Under 1 MB, with scans, odometry, tf, the camera's three topics and a map."""
    assert BAG.stat().st_size < 1_000_000
    names = BagTopics()
    for topic in (names.scan, names.odom, names.tf, names.tf_static, names.map, names.color, names.color_info,
                  names.depth):
        assert bag.topics.get(topic, 0) > 0, topic


def test_scans_carry_the_lidar_mount_from_tf_static(bag) -> None:
    """360 beams from index 0 at -pi, mount yaw pi/2 (index 0 looks right), stamps increasing."""
    scan = bag.scans[0]
    assert len(scan.ranges) == 360 and scan.frame_id == "rplidar_link"
    assert scan.mount_yaw == pytest.approx(math.pi / 2)
    assert bag.lidar_offset == pytest.approx((0.0, 0.0))
    stamps = [s.stamp for s in bag.scans]
    assert all(b > a for a, b in zip(stamps, stamps[1:], strict=False))
    assert 8 <= 1 / np.median(np.diff(stamps)) <= 12  # the 10 Hz lidar


def test_poses_come_from_tf_and_follow_the_drive_through_the_door(bag) -> None:
    """Poses are map -> odom -> base_link: the robot goes east through the door (x = 5, y 3.0 to 4.2)."""
    assert bag.pose_source == "tf (map)"
    first, last = bag.poses[0], bag.poses[-1]
    assert first.x < 4.0 and last.x > 5.5
    crossing = min(bag.poses, key=lambda p: abs(p.x - 5.0))
    assert 3.0 < crossing.y < 4.2
    middle = 0.5 * (bag.pose_stamps[0] + bag.pose_stamps[-1])
    assert bag.pose_at(middle) is not None and bag.pose_at(bag.pose_stamps[-1] + 1.0) is None


def test_frames_pair_colour_with_depth_in_metres_and_the_camera_mount(bag) -> None:
    """Each frame: RGB, depth in metres (16UC1 millimetres), K from camera_info, mount 6 cm ahead 40 cm up."""
    assert len(bag.frames) >= 5
    frame = bag.frames[0]
    assert frame.color.shape == (240, 320, 3) and frame.depth.shape == (240, 320)
    assert frame.depth.dtype == np.float32 and 0.3 < np.nanmin(frame.depth) and np.nanmax(frame.depth) < 12.0
    assert frame.intrinsics.cx == pytest.approx(159.5) and frame.intrinsics.fx > 100
    assert (frame.mount.x, frame.mount.y, frame.height) == pytest.approx((0.06, 0.0, 0.4))
    pose = bag.pose_at(frame.stamp)
    rgbd = frame.to_frame(pose)
    assert rgbd.camera_pose.distance_to(pose) == pytest.approx(0.06, abs=1e-6)


def test_the_learned_map_grows_over_the_run(bag) -> None:
    """/map (learned by sim-ros from its lidar) knows more cells at the end than at the start."""
    known = [int((g.data >= 0).sum()) for g in bag.maps]
    assert len(known) >= 5 and known[-1] > known[0]
    assert bag.maps[-1].resolution == pytest.approx(0.05)


def test_a_file_that_is_not_a_bag_is_refused_naming_it(tmp_path: Path) -> None:
    """A text file, or a missing one, raises BagError with the path."""
    junk = tmp_path / "junk.mcap"
    junk.write_text("not a bag")
    with pytest.raises(BagError, match="junk.mcap"):
        read_bag(junk)
    short = tmp_path / "short.mcap"
    short.write_bytes(b"abc")
    with pytest.raises(BagError, match="short.mcap"):
        read_bag(short)
    with pytest.raises(BagError, match="no such bag"):
        read_bag(tmp_path / "absent.mcap")


def _schemas() -> dict[str, str]:
    with BAG.open("rb") as stream:
        summary = make_reader(stream).get_summary()
    assert summary is not None
    return {s.name: s.data.decode() for s in summary.schemas.values()}


def _odom_scan_bag(path: Path, prefix: str = "") -> Path:
    """Five /odom and /scan messages 1 s apart (x = 0..4 m, yaw 0.2 rad a second), no /tf."""
    texts = _schemas()
    with path.open("wb") as stream:
        writer = Ros2Writer(stream)
        odom = writer.register_msgdef("nav_msgs/msg/Odometry", texts["nav_msgs/msg/Odometry"])
        scan = writer.register_msgdef("sensor_msgs/msg/LaserScan", texts["sensor_msgs/msg/LaserScan"])
        for i in range(5):
            stamp = {"sec": 100 + i, "nanosec": 0}
            half = 0.1 * i
            writer.write_message(prefix + "/odom", odom, {
                "header": {"stamp": stamp, "frame_id": "odom"}, "child_frame_id": "base_link",
                "pose": {"pose": {"position": {"x": float(i), "y": 0.0, "z": 0.0},
                                  "orientation": {"x": 0.0, "y": 0.0, "z": math.sin(half),
                                                  "w": math.cos(half)}},
                         "covariance": [0.0] * 36},
                "twist": {"twist": {"linear": {"x": 0.0, "y": 0.0, "z": 0.0},
                                    "angular": {"x": 0.0, "y": 0.0, "z": 0.0}}, "covariance": [0.0] * 36}},
                log_time=(100 + i) * 10**9)
            writer.write_message(prefix + "/scan", scan, {
                "header": {"stamp": stamp, "frame_id": "laser"}, "angle_min": -1.0, "angle_max": 1.0,
                "angle_increment": 0.5, "time_increment": 0.0, "scan_time": 0.1, "range_min": 0.1,
                "range_max": 10.0, "ranges": [2.0] * 5, "intensities": []}, log_time=(100 + i) * 10**9 + 1)
        writer.finish()
    return path


def test_without_tf_the_poses_come_from_odometry(tmp_path: Path) -> None:
    """A bag with /odom and /scan only (no /tf): poses from the odometry, scans with no mount."""
    got = read_bag(_odom_scan_bag(tmp_path / "odom_only.mcap"))
    assert got.pose_source == "odometry" and len(got.scans) == 5
    assert got.pose_at(102.0).x == pytest.approx(2.0) and got.pose_at(102.0).yaw == pytest.approx(0.4)
    assert got.scans[0].mount_yaw == 0.0 and not got.frames and not got.maps


def _image(encoding: str, pixels: np.ndarray) -> SimpleNamespace:
    channels = pixels.shape[2] if pixels.ndim == 3 else 1
    return SimpleNamespace(encoding=encoding, is_bigendian=0, height=pixels.shape[0], width=pixels.shape[1],
                           step=pixels.shape[1] * pixels.itemsize * channels,
                           data=pixels.tobytes(), header=SimpleNamespace(frame_id="cam"))


def test_depth_encodings_decode_to_metres_with_holes_as_nan() -> None:
    """16UC1 is millimetres (0 = no reading), 32FC1 is metres as stored."""
    mm = np.array([[0, 1500], [2500, 65535]], np.uint16)
    depth = depth_from_image(_image("16UC1", mm))
    assert np.isnan(depth[0, 0]) and depth[0, 1] == pytest.approx(1.5)
    assert depth[1, 1] == pytest.approx(65.535)
    metres = np.array([[1.25, np.nan]], np.float32)
    assert depth_from_image(_image("32FC1", metres))[0, 0] == pytest.approx(1.25)
    with pytest.raises(BagError, match="not a depth encoding"):
        depth_from_image(_image("mono8", np.zeros((2, 2), np.uint8)))


def test_colour_encodings_decode_to_rgb() -> None:
    """bgr8 is swapped to RGB, mono8 repeated to three channels."""
    bgr = np.zeros((1, 2, 3), np.uint8)
    bgr[0, 0] = (255, 0, 0)  # blue in BGR
    assert tuple(color_from_image(_image("bgr8", bgr))[0, 0]) == (0, 0, 255)
    grey = np.array([[7, 9]], np.uint8)
    assert color_from_image(_image("mono8", grey)).shape == (1, 2, 3)


def test_frames_and_maps_are_thinned_by_stamp(bag) -> None:
    """At 0.5 frames a second one frame per 2 s slot is kept; maps 3 s apart keep the latest one."""
    thin = read_bag(BAG, frame_rate=0.5, map_period=3.0)
    slots = [int(f.stamp * 0.5) for f in thin.frames]
    assert len(slots) == len(set(slots)) and 5 <= len(thin.frames) < len(bag.frames)
    stamps = [g.stamp for g in thin.maps]
    assert all(b - a >= 3.0 - 1e-6 for a, b in zip(stamps[:-2], stamps[1:-1], strict=True))
    assert stamps[-1] == bag.maps[-1].stamp and len(thin.maps) < len(bag.maps)
    everything = read_bag(BAG, frame_rate=None, map_period=0.0)
    assert len(everything.frames) == len(bag.frames) == 13  # the bag holds 1 frame a second


def test_a_namespaced_robots_topics_read_with_its_namespace(tmp_path: Path) -> None:
    """/robot1/scan and /robot1/odom are read with the namespace /robot1, and not without it."""
    path = _odom_scan_bag(tmp_path / "ns.mcap", "/robot1")
    assert BagTopics().namespaced("robot1/").scan == "/robot1/scan"
    assert len(read_bag(path, BagTopics().namespaced("/robot1")).scans) == 5
    assert not read_bag(path).scans


def test_a_topic_over_the_message_limit_is_refused_before_decoding(monkeypatch: pytest.MonkeyPatch) -> None:
    """More scans than the per-topic limit (counted from the summary) is a BagError naming the topic."""
    monkeypatch.setattr(ros2bag, "MAX_TOPIC_MESSAGES", 100)
    monkeypatch.setattr(ros2bag, "_collect", lambda *a, **k: pytest.fail("decoded before the count check"))
    with pytest.raises(BagError, match=r"/scan holds 119 messages, over the limit of 100"):
        read_bag(BAG)


def test_a_scan_with_too_many_beams_is_refused(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A scan longer than the beam limit is a BagError, not a scan kept."""
    monkeypatch.setattr(ros2bag, "MAX_BEAMS", 4)
    with pytest.raises(BagError, match="has 5 beams; expected at most 4"):
        read_bag(_odom_scan_bag(tmp_path / "long.mcap"))


def test_grid_from_msg_rows_the_cells_and_names_a_short_map() -> None:
    """A map message's cells become rows (row 0 = lowest y); too few cells raise the given error."""
    header = SimpleNamespace(frame_id="map", stamp=SimpleNamespace(sec=2, nanosec=500_000_000))
    origin = SimpleNamespace(position=SimpleNamespace(x=1.0, y=-1.0),
                             orientation=SimpleNamespace(x=0.0, y=0.0, z=0.0, w=1.0))
    info = SimpleNamespace(width=3, height=2, resolution=0.05, origin=origin)
    grid = ros2bag.grid_from_msg(SimpleNamespace(header=header, info=info, data=[0, 100, -1, 0, 0, 50]))
    assert grid.data.tolist() == [[0, 100, -1], [0, 0, 50]] and grid.stamp == 2.5
    assert (grid.origin.x, grid.origin.y, grid.resolution) == (1.0, -1.0, 0.05)
    with pytest.raises(KeyError, match="5 cells for 3 x 2"):
        ros2bag.grid_from_msg(SimpleNamespace(header=header, info=info, data=[0] * 5), KeyError)
