"""The recorded backend on a ROS 2 bag recorded from `missiontree sim-ros` (office world, unknown map)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("mcap_ros2", reason="mcap-ros2-support missing: pip install 'missiontree[realdata]'")

from scipy.ndimage import binary_dilation  # noqa: E402

from missiontree.backends.recorded import create_robot  # noqa: E402
from missiontree.cli.main import main  # noqa: E402
from missiontree.errors import BackendError, ConfigError  # noqa: E402
from missiontree.mapping.ros2bag import read_bag  # noqa: E402
from missiontree.paths import REPO_ROOT  # noqa: E402
from missiontree.robot.actions import ActionStatus  # noqa: E402
from missiontree.types import Pose2D  # noqa: E402

pytestmark = pytest.mark.realdata

BAG = REPO_ROOT / "tests" / "data" / "ros2bag" / "sim_office.mcap"


@pytest.fixture(scope="module")
def bag():
    """The committed bag, read once."""
    return read_bag(BAG)


def test_scans_and_poses_play_at_their_stamps(bag) -> None:
    """The clock starts at the first record; pose() is the /tf track at the latest scan's stamp."""
    robot = create_robot({"world": str(BAG)})
    scan = robot.scan()
    assert scan is not None and scan.stamp == robot.now() == bag.scans[0].stamp
    robot.spin_until(robot.now() + 3.0)
    pose = robot.pose()
    assert pose is not None and robot.now() - 0.15 < pose.stamp <= robot.now()
    assert pose.pose.distance_to(bag.pose_at(pose.stamp)) < 1e-9
    assert pose.pose.x - bag.poses[0].x > 0.5  # the robot drove east


def test_rgbd_frames_carry_the_camera_mount_from_tf_static(bag) -> None:
    """A played frame sits 6 cm ahead of the robot's pose at its stamp, 40 cm up."""
    robot = create_robot({"world": str(BAG)})
    robot.spin_until(bag.frames[3].stamp)
    frame = robot.rgbd()
    assert frame is not None and frame.stamp == bag.frames[3].stamp
    base = robot.pose_at(frame.stamp)
    assert base is not None
    assert frame.camera_pose.distance_to(base) == pytest.approx(0.06, abs=1e-6)
    assert frame.camera_height == pytest.approx(0.4)


def test_occupancy_is_the_bags_latest_map_played(bag) -> None:
    """The /map messages play like a robot's map topic: the latest one whose stamp the clock reached."""
    robot = create_robot({"world": str(BAG)})
    robot.spin_until(bag.maps[4].stamp - 0.01)
    earlier = robot.occupancy()
    assert earlier is not None and earlier.stamp == bag.maps[3].stamp
    robot.spin_until(bag.maps[4].stamp)
    grid = robot.occupancy()
    assert grid is not None and grid.stamp == bag.maps[4].stamp
    assert np.array_equal(grid.data, bag.maps[4].data)


def test_the_live_map_of_the_scans_matches_the_map_sim_ros_learned(bag) -> None:
    """With live_map, the scans' own map puts >= 90 % of its walls within 2 cells of /map's walls."""
    robot = create_robot({"world": str(BAG), "live_map": True})
    while not robot.finished():
        robot.occupancy()
        robot.spin_until(robot.now() + 0.5)
    live, reference = robot.occupancy(), bag.maps[-1]
    assert live is not None and live is not reference
    walls = binary_dilation(reference.data == 100, iterations=2)
    cells = [reference.world_to_cell(*live.cell_to_world(r, c)) for r, c in np.argwhere(live.data == 100)]
    inside = [walls[r, c] for r, c in cells if 0 <= r < walls.shape[0] and 0 <= c < walls.shape[1]]
    assert len(cells) > 300 and sum(inside) / len(cells) >= 0.9
    assert (live.data == 0).sum() == pytest.approx((reference.data == 0).sum(), rel=0.1)


def test_motion_is_refused_naming_the_bag() -> None:
    """navigate_to comes back REJECTED and drive raises, both naming the recording."""
    robot = create_robot({"world": str(BAG)})
    handle = robot.navigate_to(Pose2D(1.0, 1.0, 0.0))
    assert handle.status() is ActionStatus.REJECTED and "sim_office.mcap" in handle.result().reason
    with pytest.raises(BackendError, match="cannot drive"):
        robot.drive(0.2, 0.0)


def test_rawlog_options_are_refused_for_a_bag() -> None:
    """The rawlog options rgbd and correct given with a bag are a ConfigError saying so."""
    with pytest.raises(ConfigError, match="'correct' applies to a rawlog"):
        create_robot({"world": str(BAG), "correct": True})


@pytest.mark.slow
def test_the_map_recording_mission_maps_the_bag_and_finds_the_sofa(tmp_path: Path) -> None:
    """trees/examples/map_recording.yaml on the bag: SUCCESS, rooms segmented, the brown sofa placed."""
    out = tmp_path / "run"
    code = main(["run", str(REPO_ROOT / "trees" / "examples" / "map_recording.yaml"), "--backend", "recorded",
                 "--world", str(BAG), "--set", "length=11.5", "--out", str(out)])
    summary = json.loads((out / "summary.json").read_text())
    assert code == 0 and summary["status"] == "SUCCESS", summary
    graph = json.loads((out / "scene_graph.json").read_text())
    rooms = [n for n in graph["nodes"] if n["type"] == "room"]
    sofas = [n for n in graph["nodes"] if n["type"] == "object" and n["label"] == "sofa"]
    assert rooms and sofas
    x, y = sofas[0]["coordinates"][:2]  # the world file's brown sofa stands at (8.6, 4.0): scoring only
    assert abs(x - 8.6) < 0.3 and abs(y - 4.0) < 0.3


def test_every_frame_played_has_a_known_camera_pose(bag) -> None:
    """Frames outside the scans' time (no pose known there) are left out; each one kept sits on the track."""
    robot = create_robot({"world": str(BAG)})
    first, last = bag.scans[0].stamp, bag.scans[-1].stamp
    played = [f for f in bag.frames if first <= f.stamp <= last]
    assert played
    for frame in played:
        robot.spin_until(frame.stamp)
        rgbd = robot.rgbd()
        base = robot.pose_at(frame.stamp)
        assert rgbd is not None and rgbd.stamp == frame.stamp and base is not None
        assert rgbd.camera_pose.distance_to(base) == pytest.approx(0.06, abs=1e-6)


def test_frame_rate_thins_the_frames_played(bag) -> None:
    """With frame_rate 0.5 fewer distinct frames come out of rgbd() than the bag holds, each a bag frame."""
    robot = create_robot({"world": str(BAG), "frame_rate": 0.5})
    seen = set()
    for frame in bag.frames:
        robot.spin_until(frame.stamp)
        rgbd = robot.rgbd()
        if rgbd is not None:
            seen.add(rgbd.stamp)
    assert 3 <= len(seen) < len(bag.frames) - 3
    assert seen <= {f.stamp for f in bag.frames}


def test_a_bag_without_scans_on_the_topic_names_the_topics_it_has() -> None:
    """With a namespace the bag does not use, the error names the scan topic sought and the bag's topics."""
    with pytest.raises(ConfigError, match=r"no scans on /robot1/scan; its topics: /map, .*/scan"):
        create_robot({"world": str(BAG), "namespace": "/robot1"})


def test_options_come_from_the_config_files_recorded_mapping(bag) -> None:
    """A --config file's recorded: mapping sets the options; an unknown key there is refused by name."""
    with pytest.raises(ConfigError, match=r"^recorded backend: \S+ has no scans on /robot1/scan"):
        create_robot({"world": str(BAG), "config": {"recorded": {"namespace": "/robot1"}}})
    with pytest.raises(ConfigError, match="unknown options \\['speed'\\]"):
        create_robot({"world": str(BAG), "config": {"recorded": {"speed": 2}}})
    robot = create_robot({"world": str(BAG), "config": {"recorded": {"live_map": True}}})
    robot.spin_until(robot.now() + 1.0)
    grid = robot.occupancy()
    scan = robot.scan()
    assert grid is not None and scan is not None
    assert grid.stamp == scan.stamp and grid.stamp not in {g.stamp for g in bag.maps}  # the scans' own map
