"""The ROS 2 backend's profile: topic names, frames, QoS depth, navigation interface, mounts.

Profiles live in ``config/backends/<name>.yaml`` (``turtlebot4`` by default, ``realsense`` for a
NAIS-like RealSense rig). Every key has a TurtleBot 4 default, so a profile only names what
differs; options given to ``create_robot`` override the file key by key. Pure: no rclpy.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, ValidationError, model_validator

from missiontree.errors import ConfigError, ProblemsError
from missiontree.paths import find_config
from missiontree.yamlio import load_yaml, short_repr, validation_problems

DEFAULT_PROFILE = "turtlebot4"
#: The profile that lists every key (named in problems' hints).
_DOCS = "config/backends/turtlebot4.yaml"
_DOCS_HINT = f"write `key: value` lines ({_DOCS} lists every key)"


class _Section(BaseModel):
    model_config = ConfigDict(extra="forbid")


class Topics(_Section):
    """Topic names; relative names are resolved in the robot's namespace."""

    scan: str = "/scan"
    odom: str = "/odom"
    color: str = "/oakd/rgb/preview/image_raw"
    color_info: str = "/oakd/rgb/preview/camera_info"
    depth: str = "/oakd/stereo/image_raw"
    map: str = "/map"
    amcl_pose: str = "/amcl_pose"
    tf: str = "/tf"
    tf_static: str = "/tf_static"
    cmd_vel: str = "/cmd_vel"
    goal_pose: str = "/goal_pose"
    markers: str = "/missiontree/detections"
    scene_graph: str = "/scene_graph"
    alarms: str = "/missiontree/alarms"
    command: str = "/command"


class Frames(_Section):
    """Frame names of the TF tree ``map → odom → base``."""

    map: str = "map"
    odom: str = "odom"
    base: str = "base_link"


class Navigation(_Section):
    """How goals reach Nav2.

    Attributes:
        action: Name of the NavigateToPose action server.
        interface: ``action`` (needs nav2_msgs), ``topic`` (/goal_pose + the action's status topic +
            its cancel service) or ``auto`` (the action when nav2_msgs imports).
        server_timeout: Seconds to wait for the server (or for a status of a topic goal) before the
            goal is aborted with a reason.
        behavior_tree: Behaviour tree XML Nav2 should use; empty for its default.
    """

    action: str = "/navigate_to_pose"
    interface: Literal["auto", "action", "topic"] = "auto"
    server_timeout: float = 5.0
    behavior_tree: str = ""


class Camera(_Section):
    """Camera mount, used when TF has no transform from the base to ``frame``."""

    frame: str = "oakd_rgb_camera_frame"
    height: float = 0.40
    mount_x: float = 0.06
    mount_y: float = 0.0
    mount_yaw_deg: float = 0.0
    max_depth_lag: float = 0.2  # s between a colour image and the depth image paired with it


class Lidar(_Section):
    """Lidar mount yaw, used when TF has no transform from the base to the scan's frame."""

    mount_yaw_deg: float = 90.0


class Ros2Profile(_Section):
    """A ROS 2 robot as missiontree sees it.

    Attributes:
        name: Robot name shown in logs.
        namespace: Prefix for relative topic names (``/robot1`` for a namespaced TurtleBot 4).
        pose_source: ``tf`` (map → base from /tf and /tf_static) or ``amcl`` (/amcl_pose advanced
            by /odom between updates).
        cmd_vel_stamped: Publish ``TwistStamped`` (TurtleBot 4 on Jazzy) instead of ``Twist``.
        sensor_qos_depth: Queue depth of the best-effort sensor subscriptions.
        history_horizon: Seconds of pose and scan history kept for ``pose_at``/``scan_at``.
        domain_id: ROS_DOMAIN_ID for this robot's context; None takes the environment's.
        use_sim_time: Take ROS time from /clock (a simulator such as ``missiontree sim-ros --sim-time``
            or Gazebo); ``now()`` and ``spin_until`` then follow the simulated clock.
        startup_timeout: Seconds ``create_robot`` waits for a pose, a scan and the navigation server
            before handing the robot over (it is handed over anyway: missing data shows as None).
        shutdown_timeout: Seconds ``close`` waits for the goal's cancel to be answered and the zero
            velocity to be acknowledged by its subscribers before leaving the ROS graph.
    """

    # Unknown top-level keys are ignored: a --config file may hold the profile and other run options
    # side by side. Sections stay strict, so a misspelt topic name is still an error.
    model_config = ConfigDict(extra="ignore")

    name: str = "turtlebot4"
    namespace: str = ""
    pose_source: Literal["tf", "amcl"] = "tf"
    cmd_vel_stamped: bool = True
    sensor_qos_depth: int = 5
    history_horizon: float = 10.0
    domain_id: int | None = None
    use_sim_time: bool = False
    startup_timeout: float = 5.0
    shutdown_timeout: float = 3.0
    topics: Topics = Topics()
    frames: Frames = Frames()
    navigation: Navigation = Navigation()
    camera: Camera = Camera()
    lidar: Lidar = Lidar()

    @model_validator(mode="after")
    def _in_namespace(self) -> Ros2Profile:
        """With a namespace, every topic and the action resolve inside it, as a namespaced TurtleBot 4.

        ``namespace: /robot1`` alone gives ``/robot1/scan``, ``/robot1/tf`` (per-namespace TF, frame
        names unchanged, as Nav2's multi-robot bringup and TurtleBot 4 do) and
        ``/robot1/navigate_to_pose``: absolute names are made relative. ``/clock`` stays global.
        """
        name = self.namespace.strip().strip("/")
        self.namespace = f"/{name}" if name else ""
        if name:
            names = self.topics.model_dump()
            self.topics = Topics(**{key: value.lstrip("/") for key, value in names.items()})
            self.navigation = self.navigation.model_copy(
                update={"action": self.navigation.action.lstrip("/")})
        return self

    def in_namespace(self, topic: str) -> str:
        """A topic name as this robot uses it: inside its namespace when it has one (``/x`` → ``x``).

        For names that do not come from the profile (a plugin sensor's topic, such as
        ``/battery_state``), so that they follow the same rule as the profile's own.
        """
        return topic.lstrip("/") if self.namespace else topic

    @property
    def nav_status_topic(self) -> str:
        """The NavigateToPose action's status topic."""
        return f"{self.navigation.action}/_action/status"

    @property
    def nav_cancel_service(self) -> str:
        """The NavigateToPose action's cancel service."""
        return f"{self.navigation.action}/_action/cancel_goal"


def _merge(base: dict[str, Any], override: dict[str, Any]) -> dict[str, Any]:
    """``base`` with ``override`` merged in, nested mappings key by key."""
    out = dict(base)
    for key, value in override.items():
        if isinstance(value, dict) and isinstance(out.get(key), dict):
            out[key] = _merge(out[key], value)
        else:
            out[key] = value
    return out


def load_profile(name: str | Path = DEFAULT_PROFILE, overrides: dict[str, Any] | None = None) -> Ros2Profile:
    """Read a profile by shipped name or path, with ``overrides`` merged over it.

    The file is read through :mod:`missiontree.yamlio` and checked on its own first, so a problem in
    it is reported at its ``file:line:col``; the ``overrides`` (options given to ``create_robot``, a
    run config's ``ros2:`` mapping) are checked after merging and named by key.

    Raises:
        ProblemsError: The file is missing, not YAML, or has an unknown key or a value of the wrong
            type (every problem located).
        ConfigError: An override has an unknown key or a value of the wrong type.
    """
    path = find_config("backends", name)
    doc = load_yaml(path, error=ProblemsError)
    data = doc.data if doc.data is not None else {}
    if not isinstance(data, dict):
        raise ProblemsError([doc.problem_at((), f"expected a mapping of profile keys, found "
                                            f"{type(data).__name__}", _DOCS_HINT, where="")])
    try:
        profile = Ros2Profile.model_validate(data)
    except ValidationError as exc:
        raise ProblemsError(validation_problems(exc, doc, Ros2Profile, docs=_DOCS)) from None
    if not overrides:
        return profile
    try:
        return Ros2Profile.model_validate(_merge(data, overrides))
    except ValidationError as exc:
        problems = "; ".join(
            f"{'.'.join(str(p) for p in err['loc'])}: {err['msg']} (found {short_repr(err.get('input'))})"
            for err in exc.errors()
        )
        raise ConfigError(f"the options given over {path} make an invalid ROS 2 profile: {problems} "
                          f"({_DOCS} lists every key)") from None
