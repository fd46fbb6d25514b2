"""`missiontree bag record` over DDS from `missiontree sim-ros`, played back through the recorded backend."""

from __future__ import annotations

import math
import threading
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytest.importorskip("rclpy", reason="ROS 2 extra not installed: pip install -e .[ros2]; setup-ros2.sh")
pytest.importorskip("nav2_msgs.action", reason="nav2_msgs not built: run scripts/setup-ros2.sh")
pytest.importorskip("mcap_ros2", reason="mcap-ros2-support missing: pip install 'missiontree[realdata]'")
pytestmark = [pytest.mark.ros2, pytest.mark.slow]

from mcap.reader import make_reader  # noqa: E402
from rclpy.serialization import deserialize_message  # noqa: E402
from sensor_msgs.msg import LaserScan  # noqa: E402

from missiontree.backends.recorded import create_robot  # noqa: E402
from missiontree.backends.ros2.bag_record import BagSummary, message_definition, record_bag  # noqa: E402
from missiontree.mapping.ros2bag import read_bag  # noqa: E402
from missiontree.types import Pose2D, Tolerance  # noqa: E402

SIM_ROS_FLAGS = ["--unknown-map"]
CAMERA = ("/oakd/rgb/preview/image_raw", "/oakd/rgb/preview/camera_info", "/oakd/stereo/image_raw")


@pytest.fixture(scope="module")
def recording(sim_ros: Any, tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, BagSummary]:
    """Six seconds of sim-ros recorded while a robot drives east through the door."""
    from missiontree.backends.ros2.profile import load_profile
    from missiontree.backends.ros2.robot import Ros2Robot

    robot = Ros2Robot(load_profile("turtlebot4", {"domain_id": sim_ros.domain_id, "shutdown_timeout": 0.3}),
                      node_name="bag_test_driver", install_signal_stop=False)
    try:
        for _ in range(400):
            if robot.pose() and robot.scan():
                break
            threading.Event().wait(0.05)
        out = tmp_path_factory.mktemp("bag") / "run.mcap"
        result: dict[str, BagSummary] = {}
        recorder = threading.Thread(target=lambda: result.update(summary=record_bag(
            out, 6.0, domain_id=sim_ros.domain_id, max_rate={t: 2.0 for t in CAMERA})))
        recorder.start()
        robot.navigate_to(Pose2D(7.5, 3.6, 0.0), Tolerance(xy=0.25, yaw=2 * math.pi))
        recorder.join(timeout=60)
        assert "summary" in result, f"the recorder did not finish; sim-ros said: {sim_ros.output()}"
        return out, result["summary"]
    finally:
        robot.close()


def test_every_turtlebot4_topic_is_recorded(recording: tuple[Path, BagSummary]) -> None:
    """Scans, odometry, tf (and the latched tf_static and map), the camera's three topics: none missing."""
    _, summary = recording
    assert not summary.missing
    counts = summary.counts
    assert counts["/scan"] >= 10 and counts["/tf_static"] >= 1 and counts["/map"] >= 1
    colour, depth = counts["/oakd/rgb/preview/image_raw"], counts["/oakd/stereo/image_raw"]
    assert colour >= 2 and abs(colour - depth) <= 1  # thinned by stamp: the same frames kept


def test_the_stored_definitions_decode_as_rclpy_does(recording: tuple[Path, BagSummary]) -> None:
    """The reader (no ROS, from the bag's schemas) and rclpy agree on every scan; the type hash is kept."""
    path, _ = recording
    with path.open("rb") as stream:
        reader = make_reader(stream)
        raw = [deserialize_message(m.data, LaserScan) for _, _, m in reader.iter_messages(topics=["/scan"])]
        summary = reader.get_summary()
    assert summary is not None
    scan_channel = next(c for c in summary.channels.values() if c.topic == "/scan")
    assert scan_channel.metadata["topic_type_hash"].startswith("RIHS01_")
    scans = read_bag(path).scans
    assert len(scans) == len(raw)
    by_stamp = {s.stamp: s for s in scans}
    for msg in raw:
        stamp = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
        assert np.array_equal(by_stamp[stamp].ranges, np.asarray(msg.ranges, np.float32))


def test_the_schema_is_the_complete_definition() -> None:
    """A LaserScan schema holds its own text, then Header and Time after rosbag2's delimiter."""
    text = message_definition("sensor_msgs/msg/LaserScan")
    assert text.startswith("# Single scan from a planar laser range-finder")
    assert f"{'=' * 80}\nMSG: std_msgs/msg/Header\n" in text and "MSG: builtin_interfaces/msg/Time" in text


def test_the_recording_plays_through_the_recorded_backend(recording: tuple[Path, BagSummary]) -> None:
    """Played back: the robot moves as it drove, frames carry the camera mount, /map is served."""
    path, _ = recording
    bag = read_bag(path)
    robot = create_robot({"world": str(path)})
    robot.spin_until(robot.now() + 0.5)  # the first record may be a camera frame
    start = robot.pose()
    assert start is not None and robot.scan() is not None
    while not robot.finished():
        robot.spin_until(robot.now() + 0.5)
    end = robot.pose()
    assert end is not None and end.pose.x - start.pose.x > 0.1  # it drove east (how far depends on the load)
    assert end.pose.distance_to(bag.pose_at(end.stamp)) < 1e-9
    frame = robot.rgbd()
    assert frame is not None and frame.depth.shape == (240, 320) and np.isfinite(frame.depth).any()
    assert frame.camera_height == pytest.approx(0.4)
    grid = robot.occupancy()
    assert grid is not None and grid.data.max() == 100
