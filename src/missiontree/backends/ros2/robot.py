"""Ros2Robot: the Robot protocol over rclpy (Jazzy) and Nav2, for a TurtleBot 4 or any ROS 2 robot.

One node in its own rclpy context, spun by an executor on a background thread: callbacks store
the latest message of every topic (sensor data best effort, the map transient local) and keep a
short history of poses and scans; getters convert on demand and return at once. Time is ROS
time; ``spin_until`` waits in wall time while the executor spins. Navigation goes through the
NavigateToPose action (or /goal_pose when nav2_msgs is absent, see :mod:`.navigation`). ``stop``
always publishes zero velocity, also at ``close``, at interpreter exit and on SIGINT.
"""

from __future__ import annotations

import atexit
import math
import signal
import threading
import time
import weakref
from collections import deque
from collections.abc import Callable
from types import FrameType
from typing import Any

import cv2
import numpy as np
import rclpy
from action_msgs.msg import GoalStatusArray
from action_msgs.srv import CancelGoal
from geometry_msgs.msg import PoseStamped as PoseStampedMsg
from geometry_msgs.msg import PoseWithCovarianceStamped, Twist, TwistStamped
from nav_msgs.msg import OccupancyGrid as OccupancyGridMsg
from nav_msgs.msg import Odometry
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.signals import SignalHandlerOptions
from sensor_msgs.msg import CameraInfo, Image
from sensor_msgs.msg import LaserScan as LaserScanMsg

from missiontree.backends.ros2 import conversions as conv
from missiontree.backends.ros2.commands import TopicCommands
from missiontree.backends.ros2.navigation import ActionGoal, NavGoal, ServerWatch, TopicGoal
from missiontree.backends.ros2.profile import Ros2Profile
from missiontree.backends.ros2.publish import WorldPublisher
from missiontree.backends.ros2.qos import latched_qos, qos_named, reliable_qos, sensor_qos
from missiontree.backends.ros2.spin import spin_until, stop_spinning
from missiontree.backends.ros2.tf_buffer import TransformBuffer, compose, history_at, invert
from missiontree.robot.actions import ActionHandle
from missiontree.robot.commands import Command
from missiontree.robot.history import StampedHistory
from missiontree.robot.sensors import SensorKind, SensorReading, SensorStore
from missiontree.types import LaserScan, OccupancyGrid, Pose2D, PoseStamped, RGBDFrame, Tolerance

try:  # built locally by scripts/setup-ros2.sh, or from /opt/ros on a robot
    from nav2_msgs.action import NavigateToPose
except ImportError:  # pragma: no cover - exercised by the topic-interface tests instead
    NavigateToPose = None
try:
    from tf2_msgs.msg import TFMessage
except ImportError:  # pragma: no cover
    TFMessage = None

#: Rate at which a drive() command is repeated until stop(), navigate_to() or another drive().
DRIVE_REPEAT_HZ = 10.0
#: Longest sleep (wall s) between looks at a simulated clock in spin_until.
SIM_CLOCK_POLL = 0.002
#: Largest gap (s) between a requested stamp and the scan ``scan_at`` returns.
SCAN_MATCH_GAP = 0.5


#: The QoS helpers live in .qos; imported here as before.
__all__ = ["Ros2Robot", "latched_qos", "qos_named", "reliable_qos", "sensor_qos"]


class Ros2Robot:
    """A ROS 2 robot behind the :class:`~missiontree.robot.interface.Robot` protocol.

    Args:
        profile: Topic names, frames and navigation settings (config/backends/*.yaml).
        node_name: Name of this process's node.
        install_signal_stop: On SIGINT, publish zero velocity before the previous handler runs.
        sensors: Plugin sensor kinds to subscribe to (those with a ``ros2`` source).
    """

    simulated = False

    def __init__(self, profile: Ros2Profile, node_name: str = "missiontree",
                 install_signal_stop: bool = True, sensors: list[SensorKind] | None = None) -> None:
        self.profile = profile
        self.name = profile.name
        self._lock = threading.RLock()
        self._closed = False
        self._context = rclpy.Context()
        rclpy.init(context=self._context, domain_id=profile.domain_id,
                   signal_handler_options=SignalHandlerOptions.NO)
        overrides = [Parameter("use_sim_time", Parameter.Type.BOOL, True)] if profile.use_sim_time else []
        self.node = Node(node_name, context=self._context, namespace=profile.namespace or None,
                         parameter_overrides=overrides)
        self._tf = TransformBuffer(horizon=profile.history_horizon)
        self._poses: StampedHistory[Pose2D] = StampedHistory(horizon=profile.history_horizon)
        self._odom: StampedHistory[Pose2D] = StampedHistory(horizon=profile.history_horizon)
        self._scans: StampedHistory[LaserScan] = StampedHistory(horizon=profile.history_horizon)
        self._scan: LaserScan | None = None
        self._amcl: PoseStamped | None = None
        self._map_msg: OccupancyGridMsg | None = None
        self._map: OccupancyGrid | None = None
        self._color: Image | None = None
        self._color_info: CameraInfo | None = None
        self._depths: deque[Image] = deque(maxlen=8)
        self._rgbd: RGBDFrame | None = None
        self._mount_yaws: dict[str, float] = {}
        self._goal: NavGoal | None = None
        self._drive_command: tuple[float, float] | None = None
        # Held while the drive command changes and while it is published: the timer's repeat of an
        # old command must never go out after stop()'s zero velocity (the base would keep driving).
        self._drive_lock = threading.RLock()
        self._nav_goal_ids: set[bytes] = set()  # goals seen on the NavigateToPose status topic
        self._sensors = SensorStore(sensors or [])
        self._sensor_errors: set[str] = set()
        try:
            self._subscribe()
            self._advertise()
            self._commands = TopicCommands(self.node, self.now, profile.topics.command)
        except BaseException:
            self.node.destroy_node()
            self._context.try_shutdown()
            raise
        self.world = WorldPublisher(self.node, profile.topics)
        self._spin_stop = threading.Event()
        self._executor = SingleThreadedExecutor(context=self._context)
        self._executor.add_node(self.node)
        self._spinner = threading.Thread(target=self._spin, name=f"ros2-{node_name}", daemon=True)
        self._spinner.start()
        self._previous_sigint: Any = None
        if install_signal_stop:
            self._install_sigint()
        atexit.register(_close_at_exit, weakref.ref(self))

    # ------------------------------------------------------------------------------ wiring

    def _subscribe(self) -> None:
        p, t, node = self.profile, self.profile.topics, self.node
        sensor = sensor_qos(p.sensor_qos_depth)
        node.create_subscription(LaserScanMsg, t.scan, self._on_scan, sensor)
        node.create_subscription(Odometry, t.odom, self._on_odom, sensor)
        node.create_subscription(Image, t.color, self._on_color, sensor)
        node.create_subscription(CameraInfo, t.color_info, self._on_color_info, sensor)
        node.create_subscription(Image, t.depth, self._on_depth, sensor)
        node.create_subscription(OccupancyGridMsg, t.map, self._on_map, latched_qos())
        if TFMessage is not None:
            node.create_subscription(TFMessage, t.tf, lambda m: self._on_tf(m, False), reliable_qos(100))
            node.create_subscription(TFMessage, t.tf_static, lambda m: self._on_tf(m, True), latched_qos(100))
        if p.pose_source == "amcl" or TFMessage is None:
            node.create_subscription(PoseWithCovarianceStamped, t.amcl_pose, self._on_amcl, latched_qos())
        for kind in self._sensors.kinds.values():
            if kind.ros2 is not None:
                # mypy cannot infer a lambda with a default argument (binding this loop's kind)
                node.create_subscription(kind.ros2.message_type(), p.in_namespace(kind.ros2.topic),
                                         lambda m, k=kind: self._on_sensor(k, m),  # type: ignore[misc]
                                         qos_named(kind.ros2.qos, p))

    def _advertise(self) -> None:
        p, t, node = self.profile, self.profile.topics, self.node
        self._cmd_vel = node.create_publisher(TwistStamped if p.cmd_vel_stamped else Twist, t.cmd_vel,
                                              reliable_qos())
        self.nav_interface = p.navigation.interface
        self._server_watch: ServerWatch | None = None
        if self.nav_interface == "auto":
            self.nav_interface = "action" if NavigateToPose is not None else "topic"
        if self.nav_interface == "action":
            if NavigateToPose is None:
                from missiontree.errors import BackendUnavailableError

                raise BackendUnavailableError(
                    "navigation.interface is 'action' but nav2_msgs does not import; run "
                    "scripts/setup-ros2.sh (or source /opt/ros/jazzy/setup.bash on a robot), "
                    "or set navigation.interface: topic")
            from rclpy.action import ActionClient

            self._nav_client = ActionClient(node, NavigateToPose, p.navigation.action)
            self._server_watch = ServerWatch(self._nav_client)
        else:
            self._goal_pub = node.create_publisher(PoseStampedMsg, t.goal_pose, reliable_qos())
            self._cancel_client = node.create_client(CancelGoal, p.nav_cancel_service)
            node.create_subscription(GoalStatusArray, p.nav_status_topic, self._on_nav_status, latched_qos())
        node.create_timer(1.0 / DRIVE_REPEAT_HZ, self._on_timer)

    def _spin(self) -> None:
        spin_until(self._context, self._executor, self._spin_stop)

    # ------------------------------------------------------------------------------ callbacks

    def _on_scan(self, msg: LaserScanMsg) -> None:
        scan = conv.scan_from_msg(msg, self._mount_yaw(msg.header.frame_id))
        with self._lock:
            self._scan = scan
            latest = self._scans.latest()
            if latest is None or scan.stamp >= latest[0]:
                self._scans.push(scan.stamp, scan)

    def _mount_yaw(self, frame: str) -> float:
        """Yaw of a sensor frame on the base, from TF once known, else the profile's lidar mount."""
        yaw = self._mount_yaws.get(frame)
        if yaw is None:
            found = self._tf.lookup(self.profile.frames.base, frame)
            if found is None:
                return math.radians(self.profile.lidar.mount_yaw_deg)
            yaw = self._mount_yaws[frame] = found[1].yaw
        return yaw

    def _on_tf(self, msg: Any, static: bool) -> None:
        for transform in msg.transforms:
            parent, child, stamp, pose = conv.transform_from_msg(transform)
            self._tf.set_transform(parent, child, stamp, pose, static=static)
        if self.profile.pose_source == "tf":
            found = self._tf.lookup(self.profile.frames.map, self.profile.frames.base)
            if found is not None:
                self._push_pose(*found)

    def _on_odom(self, msg: Odometry) -> None:
        odom = conv.odometry_to_pose(msg)
        with self._lock:
            latest = self._odom.latest()
            if latest is None or odom.stamp >= latest[0]:
                self._odom.push(odom.stamp, odom.pose)
        if self.profile.pose_source == "amcl" or TFMessage is None:
            pose = self._amcl_pose()
            if pose is not None:
                self._push_pose(pose.stamp, pose.pose)

    def _on_amcl(self, msg: PoseWithCovarianceStamped) -> None:
        self._amcl = conv.pose_stamped_from_msg(msg)

    def _push_pose(self, stamp: float, pose: Pose2D) -> None:
        with self._lock:
            latest = self._poses.latest()
            if latest is None or stamp > latest[0]:
                self._poses.push(stamp, pose)

    def _on_map(self, msg: OccupancyGridMsg) -> None:
        with self._lock:
            self._map_msg, self._map = msg, None

    def _on_sensor(self, kind: SensorKind, msg: Any) -> None:
        """A plugin sensor's message: convert with its pure function, stamp from the header (else now)."""
        source = kind.ros2
        assert source is not None
        try:
            value = source.from_msg(msg)
        except Exception as error:  # noqa: BLE001 - a plugin's conversion bug must not stop the executor
            if kind.name not in self._sensor_errors:
                self._sensor_errors.add(kind.name)
                self.node.get_logger().error(f"sensor {kind.name!r}: its conversion failed on a message "
                                             f"from {source.topic}: {type(error).__name__}: {error}")
            return
        stamp = 0.0
        header = getattr(msg, "header", None) if source.stamp_from_header else None
        if header is not None:
            stamp = conv.time_to_sec(header.stamp)
        self._sensors.put(kind.name, stamp if stamp > 0.0 else self.now(), value)

    def _on_color(self, msg: Image) -> None:
        self._color = msg

    def _on_color_info(self, msg: CameraInfo) -> None:
        self._color_info = msg

    def _on_depth(self, msg: Image) -> None:
        self._depths.append(msg)

    def _on_nav_status(self, msg: GoalStatusArray) -> None:
        self._nav_goal_ids = {bytes(s.goal_info.goal_id.uuid) for s in msg.status_list}
        goal = self._goal
        if isinstance(goal, TopicGoal):
            goal.on_status(msg)

    def _on_timer(self) -> None:
        with self._drive_lock:
            command = self._drive_command
            if command is not None:  # bases stop when commands stop coming (Create 3's cmd_vel timeout)
                self._publish_velocity(*command)
        if self._server_watch is not None:
            self._server_watch.ready()  # the server's presence followed between goals too
        goal = self._goal
        if goal is not None:
            goal.advance()
            self._check_tolerance(goal)

    def wait_until_ready(self, timeout: float) -> list[str]:
        """Wait up to ``timeout`` s for a pose, a scan and the navigation server; return what is missing."""
        deadline = time.monotonic() + timeout
        while True:
            missing = self.missing()
            if not missing or time.monotonic() >= deadline:
                return missing
            time.sleep(0.05)

    def missing(self) -> list[str]:
        """What the robot has not heard of yet: ``pose``, ``scan``, ``navigation server``."""
        missing = []
        if self.pose() is None:
            missing.append("pose")
        if self._scan is None:
            missing.append(f"scan on {self.profile.topics.scan}")
        if self.nav_interface == "action" and not self._nav_client.server_is_ready():
            missing.append(f"NavigateToPose server on {self.profile.navigation.action}")
        return missing

    # ------------------------------------------------------------------------------ Robot: state

    def now(self) -> float:
        """ROS time in seconds."""
        return self.node.get_clock().now().nanoseconds * 1e-9

    def spin_until(self, t: float) -> None:
        """Wait until ROS time reaches ``t`` (in wall time, or on /clock with use_sim_time).

        The executor thread keeps spinning meanwhile. A simulated clock may run at any rate, so it is
        polled in short sleeps.
        """
        longest = SIM_CLOCK_POLL if self.profile.use_sim_time else 0.05
        while not self._closed:
            remaining = t - self.now()
            if remaining <= 0.0:
                return
            time.sleep(min(remaining, longest))

    def pose(self) -> PoseStamped | None:
        """Latest map pose: map → base from TF, or /amcl_pose advanced by odometry."""
        if self.profile.pose_source == "tf" and TFMessage is not None:
            found = self._tf.lookup(self.profile.frames.map, self.profile.frames.base)
            return None if found is None else PoseStamped(found[0], found[1])
        return self._amcl_pose()

    def _amcl_pose(self) -> PoseStamped | None:
        amcl = self._amcl
        if amcl is None:
            return None
        with self._lock:
            latest = self._odom.latest()
            then = history_at(self._odom, amcl.stamp)
        if latest is None or then is None or latest[0] <= amcl.stamp:
            return amcl
        moved = compose(invert(then), latest[1])  # odometry since AMCL's estimate, in the body frame
        return PoseStamped(latest[0], compose(amcl.pose, moved))

    def scan(self) -> LaserScan | None:
        """Latest scan (its stamp shows when the lidar went quiet)."""
        return self._scan

    def rgbd(self) -> RGBDFrame | None:
        """Latest colour image with the depth image nearest in time and the camera's map pose.

        Colour and depth come on separate topics; while the newest colour image still waits for its
        depth, the last complete frame is returned (its stamp shows its age), None before the first.
        """
        color, info = self._color, self._color_info
        cached = self._rgbd
        if color is None or info is None or not self._depths:
            return cached
        stamp = conv.time_to_sec(color.header.stamp)
        if cached is not None and cached.stamp == stamp:
            return cached
        depth_msg = min(self._depths, key=lambda m: abs(conv.time_to_sec(m.header.stamp) - stamp))
        if abs(conv.time_to_sec(depth_msg.header.stamp) - stamp) > self.profile.camera.max_depth_lag:
            return cached
        rgb = conv.color_from_msg(color)
        depth = conv.depth_from_msg(depth_msg)
        if depth.shape != rgb.shape[:2]:  # OAK-D stereo depth is not registered to the preview image
            depth = cv2.resize(depth, (rgb.shape[1], rgb.shape[0]), interpolation=cv2.INTER_NEAREST)
        base = self.pose_at(stamp)
        if base is None:
            current = self.pose()
            base = current.pose if current is not None else Pose2D(math.nan, math.nan, math.nan)
        frame = RGBDFrame(stamp=stamp, color=rgb, depth=depth.astype(np.float32, copy=False),
                          intrinsics=conv.intrinsics_from_msg(info),
                          camera_pose=compose(base, self._camera_mount()),
                          camera_height=self.profile.camera.height)
        self._rgbd = frame
        return frame

    def _camera_mount(self) -> Pose2D:
        cam = self.profile.camera
        found = self._tf.lookup(self.profile.frames.base, cam.frame)
        if found is not None:
            return found[1]
        return Pose2D(cam.mount_x, cam.mount_y, math.radians(cam.mount_yaw_deg))

    def sensor(self, name: str) -> SensorReading | None:
        """The latest reading of a plugin sensor (a quiet one keeps its old stamp), None before the first."""
        return self._sensors.get(name)

    def sensor_names(self) -> list[str]:
        """The plugin sensors this robot subscribes to."""
        return self._sensors.names()

    def sensor_kind(self, name: str) -> SensorKind:
        """What plugin sensor ``name`` is (UnknownSensorError naming the robot's sensors otherwise)."""
        return self._sensors.kind(name)

    def commands(self) -> list[Command]:
        """User commands received on the command topic (std_msgs/String) since the last call."""
        return self._commands.poll(self.now())

    def commands_closed(self) -> bool:
        """A topic never closes: False."""
        return False

    def occupancy(self) -> OccupancyGrid | None:
        """The latest map received on the map topic."""
        with self._lock:
            if self._map is None and self._map_msg is not None:
                self._map = conv.occupancy_from_msg(self._map_msg)
            return self._map

    def pose_at(self, stamp: float) -> Pose2D | None:
        """Map pose at ``stamp``, interpolated in the recent history."""
        with self._lock:
            return history_at(self._poses, stamp)

    def scan_at(self, stamp: float) -> LaserScan | None:
        """The scan nearest to ``stamp`` (within half a second) from the recent history."""
        with self._lock:
            return self._scans.nearest(stamp, max_gap=SCAN_MATCH_GAP)

    # ------------------------------------------------------------------------------ Robot: motion

    def navigate_to(self, goal: Pose2D, tolerance: Tolerance | None = None) -> ActionHandle:
        """Send a NavigateToPose goal; the previous goal is cancelled (preempted), a drive() ends."""
        nav = self.profile.navigation
        with self._drive_lock:
            self._drive_command = None
        previous = self._goal
        if previous is not None and not previous.done:
            if isinstance(previous, TopicGoal):
                previous.preempted()  # Nav2 preempts it when the new /goal_pose arrives
            else:
                previous.cancel()
        stamp = self.now()
        pose_now = self._pose_only
        if self.nav_interface == "action":
            msg = NavigateToPose.Goal()
            msg.pose = conv.pose_stamped_to_msg(goal, stamp, self.profile.frames.map)
            msg.behavior_tree = nav.behavior_tree
            handle: NavGoal = ActionGoal(self._nav_client, msg, goal, nav.server_timeout, pose_now,
                                         nav.action, in_executor=self._in_executor, watch=self._server_watch)
        else:
            goal_msg = conv.pose_stamped_to_msg(goal, stamp, self.profile.frames.map)
            handle = TopicGoal(lambda: self._goal_pub.publish(goal_msg),
                               lambda: self._goal_pub.get_subscription_count() > 0,
                               self._cancel_client, goal, nav.server_timeout, pose_now, self.now,
                               self._goal_pub.topic_name, known_goals=set(self._nav_goal_ids),
                               in_executor=self._in_executor)
        handle.tolerance = tolerance
        self._goal = handle
        handle.advance()
        return handle

    def _in_executor(self, fn: Callable[[], None]) -> None:
        """Run ``fn`` on the executor thread (where rclpy requests must be issued, see .navigation)."""
        if threading.current_thread() is self._spinner:
            fn()
        else:
            self._executor.create_task(fn)

    def _pose_only(self) -> Pose2D | None:
        current = self.pose()
        return None if current is None else current.pose

    def _check_tolerance(self, goal: NavGoal) -> None:
        """Succeed a goal once within an explicitly looser tolerance than Nav2's goal checker."""
        tol = getattr(goal, "tolerance", None)
        if tol is None or goal.done or goal.status().value not in ("accepted", "running"):
            return
        pose = self._pose_only()
        if pose is None:
            return
        dyaw = abs(math.atan2(math.sin(pose.yaw - goal.goal.yaw), math.cos(pose.yaw - goal.goal.yaw)))
        if pose.distance_to(goal.goal) <= tol.xy and (tol.yaw >= math.pi or dyaw <= tol.yaw):
            goal.cancel()
            goal.within_tolerance()

    def drive(self, v: float, w: float) -> None:
        """Command body velocity on cmd_vel, repeated at 10 Hz until stopped, sent a goal or changed.

        A running goal is cancelled: with Nav2 the controller would fight the command.
        """
        goal = self._goal
        if goal is not None and not goal.done and (v != 0.0 or w != 0.0):
            goal.cancel()
        with self._drive_lock:
            self._drive_command = (float(v), float(w))
            self._publish_velocity(v, w)

    def _publish_velocity(self, v: float, w: float) -> None:
        if not self._context.ok():
            return
        if self.profile.cmd_vel_stamped:
            self._cmd_vel.publish(conv.twist_stamped_to_msg(v, w, self.now(), self.profile.frames.base))
        else:
            self._cmd_vel.publish(conv.twist_to_msg(v, w))

    def stop(self) -> None:
        """Cancel navigation and publish zero velocity; always safe, idempotent."""
        goal = self._goal
        if goal is not None and not goal.done:
            goal.cancel()
        with self._drive_lock:
            self._drive_command = None
            self._publish_velocity(0.0, 0.0)

    def close(self) -> None:
        """Stop, wait briefly for the cancel and the zero velocity to go out, then leave the ROS graph."""
        if self._closed:
            return
        try:
            if self._context.ok():
                self.stop()
                self._flush(self.profile.shutdown_timeout)
        finally:
            self._closed = True
            self._restore_sigint()
            stop_spinning(self._spin_stop, self._spinner, self._executor)
            self.node.destroy_node()
            if self._context.ok():
                self._context.try_shutdown()

    def _flush(self, timeout: float) -> None:
        deadline = time.monotonic() + timeout
        goal = self._goal
        while goal is not None and not goal.cancel_settled() and time.monotonic() < deadline:
            time.sleep(0.01)
        from rclpy.duration import Duration

        remaining = max(0.0, deadline - time.monotonic())
        self._cmd_vel.wait_for_all_acked(Duration(nanoseconds=int(remaining * 1e9)))

    # ------------------------------------------------------------------------------ signals

    def _install_sigint(self) -> None:
        if threading.current_thread() is not threading.main_thread():
            return
        self._previous_sigint = signal.getsignal(signal.SIGINT)
        signal.signal(signal.SIGINT, self._on_sigint)

    def _on_sigint(self, signum: int, frame: FrameType | None) -> None:
        try:
            self.stop()
        finally:
            previous = self._previous_sigint
            if callable(previous):
                previous(signum, frame)
            elif previous != signal.SIG_IGN:
                raise KeyboardInterrupt

    def _restore_sigint(self) -> None:
        if self._previous_sigint is None or threading.current_thread() is not threading.main_thread():
            return
        if signal.getsignal(signal.SIGINT) == self._on_sigint:
            signal.signal(signal.SIGINT, self._previous_sigint)
        self._previous_sigint = None


def _close_at_exit(ref: weakref.ref[Ros2Robot]) -> None:
    robot = ref()
    if robot is not None:
        robot.close()
