"""ROS 2 backend profiles: the shipped files, overrides, clear errors (runs without ROS)."""

from __future__ import annotations

from pathlib import Path

import pytest

from missiontree.backends.ros2 import profile_from_options
from missiontree.backends.ros2.profile import load_profile
from missiontree.errors import ConfigError, ProblemsError


def test_turtlebot4_profile_names_the_turtlebot4_topics() -> None:
    """The default profile subscribes to the TurtleBot 4's topics and sends TwistStamped (Jazzy)."""
    p = load_profile()
    assert (p.topics.scan, p.topics.odom, p.topics.cmd_vel) == ("/scan", "/odom", "/cmd_vel")
    assert p.topics.color == "/oakd/rgb/preview/image_raw"
    assert p.cmd_vel_stamped is True
    assert p.nav_status_topic == "/navigate_to_pose/_action/status"
    assert p.nav_cancel_service == "/navigate_to_pose/_action/cancel_goal"


def test_realsense_profile_uses_aligned_depth_and_plain_twist() -> None:
    """NAIS's RealSense rig: aligned depth, /camera/color topics, Twist; the rest stays TurtleBot 4."""
    p = load_profile("realsense")
    assert p.topics.depth == "/camera/aligned_depth_to_color/image_raw"
    assert p.topics.color_info == "/camera/color/camera_info"
    assert p.cmd_vel_stamped is False
    assert p.topics.scan == "/scan"


def test_run_config_ros2_section_overrides_key_by_key() -> None:
    """A ``ros2:`` mapping in the run config changes only the keys it names."""
    p = profile_from_options({"config": {"ros2": {"topics": {"scan": "/robot1/scan"},
                                                   "navigation": {"server_timeout": 1.5}}},
                              "domain_id": 42})
    assert p.topics.scan == "/robot1/scan" and p.topics.odom == "/odom"
    assert p.navigation.server_timeout == 1.5 and p.navigation.action == "/navigate_to_pose"
    assert p.domain_id == 42


def test_misspelt_key_is_reported_with_file_and_key(tmp_path: Path) -> None:
    """An unknown key names the file and line, the key path, the keys allowed and the nearest one."""
    bad = tmp_path / "bad.yaml"
    bad.write_text("topics:\n  scann: /scan\n")
    wording = r"bad\.yaml:2:3: topics\.scann: .*expected one of: scan, .*did you mean 'scan'"
    with pytest.raises(ConfigError, match=wording):
        load_profile(bad)


def test_wrong_type_is_reported(tmp_path: Path) -> None:
    """A value of the wrong type names the key and what was found."""
    bad = tmp_path / "bad.yaml"
    bad.write_text("navigation:\n  interface: carrier-pigeon\n")
    with pytest.raises(ConfigError, match=r"navigation\.interface.*carrier-pigeon"):
        load_profile(bad)


def test_unknown_profile_name_lists_the_known_ones() -> None:
    """A profile name that does not exist lists the shipped ones."""
    with pytest.raises(ConfigError, match="turtlebot4"):
        load_profile("no-such-robot")


def test_profile_problems_have_file_line_and_col(tmp_path: Path) -> None:
    """Every problem of a profile file is reported at once, each at its file:line:col."""
    bad = tmp_path / "bad.yaml"
    bad.write_text("topics:\n  scann: /scan\nnavigation:\n  interface: carrier-pigeon\n")
    with pytest.raises(ProblemsError) as caught:
        load_profile(bad)
    shown = [str(problem) for problem in caught.value.problems]
    assert shown[0].startswith(f"{bad}:2:3: topics.scann:")
    assert shown[1].startswith(f"{bad}:4:14: navigation.interface:") and "carrier-pigeon" in shown[1]


def test_a_profile_that_is_not_yaml_is_located(tmp_path: Path) -> None:
    """A YAML syntax error in a profile names the file and line (the shared YAML reader's message)."""
    bad = tmp_path / "bad.yaml"
    bad.write_text("topics: [1\n")
    with pytest.raises(ProblemsError, match=r"bad\.yaml:2:1: YAML syntax error"):
        load_profile(bad)


def test_a_bad_override_names_the_key() -> None:
    """An option given over the file with an unknown key is a ConfigError naming the key."""
    with pytest.raises(ConfigError, match=r"topics\.scann"):
        load_profile("turtlebot4", {"topics": {"scann": "/x"}})


def test_a_namespace_puts_every_topic_and_the_action_inside_it() -> None:
    """``namespace: robot1`` alone resolves every topic (TF too) and the action under /robot1."""
    p = load_profile("turtlebot4", {"namespace": "robot1/"})
    assert p.namespace == "/robot1"
    topics = p.topics
    assert (topics.scan, topics.tf, topics.tf_static, topics.map) == ("scan", "tf", "tf_static", "map")
    assert p.topics.color == "oakd/rgb/preview/image_raw"
    assert p.navigation.action == "navigate_to_pose"
    assert (p.frames.map, p.frames.odom, p.frames.base) == ("map", "odom", "base_link")  # per-namespace TF


def test_without_a_namespace_the_names_stay_absolute() -> None:
    """An empty namespace leaves the TurtleBot 4's absolute names as they are."""
    p = load_profile("turtlebot4", {"namespace": " "})
    assert (p.namespace, p.topics.scan, p.navigation.action) == ("", "/scan", "/navigate_to_pose")


def test_a_plugin_topic_follows_the_namespace_rule() -> None:
    """A plugin's /battery_state resolves under a namespace (/robot1/battery_state), as is without one."""
    namespaced = load_profile("turtlebot4", {"namespace": "/robot1"})
    assert namespaced.in_namespace("/battery_state") == "battery_state"
    assert load_profile("turtlebot4").in_namespace("/battery_state") == "/battery_state"
