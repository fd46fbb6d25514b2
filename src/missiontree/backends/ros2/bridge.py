"""The simulator served as a ROS 2 robot: TurtleBot 4 topics, TF, /map and a NavigateToPose server.

:class:`SimBridge` steps a :class:`~missiontree.backends.sim.SimRobot` in real time and publishes
what a TurtleBot 4 running Nav2 would: /scan, /odom, the OAK-D colour and depth images with
camera_info, /tf (map → odom → base_link), /tf_static (lidar and camera mounts), /map (transient
local; in unknown-map runs the map the robot learns, republished every ``MAP_PERIOD`` as a SLAM
node does), /amcl_pose; it drives the simulated base from /cmd_vel and serves NavigateToPose (and
/goal_pose, as bt_navigator does) with the simulator's navigation, and every plugin sensor the
simulator produces on its topic (its ``Ros2Source.to_msg``). Missions, RViz and other ROS
tools then run against it as against the robot.

Threads: the pacing loop (``run``) owns the simulator's stepping; the executor's threads serve
callbacks and the action server. Every simulator call holds ``_sim_lock``.

A fleet (``sim-ros --robots N``, :func:`serve_fleet`) is one bridge per robot, each on a node of its
own under the robot's namespace (``/robot1/scan``, ``/robot1/tf``, ``/robot1/navigate_to_pose``), all
sharing one lock; the first robot's bridge leads: its loop steps the whole fleet (one clock), publishes
every robot's data and /clock, and takes robots' navigation away on schedule (:meth:`SimBridge.vanish`).
"""

from __future__ import annotations

import json
import math
import threading
import time
from collections.abc import Callable
from typing import Any

import rclpy
from geometry_msgs.msg import PoseStamped as PoseStampedMsg
from geometry_msgs.msg import PoseWithCovarianceStamped, TransformStamped, Twist, TwistStamped
from nav2_msgs.action import NavigateToPose
from nav_msgs.msg import OccupancyGrid as OccupancyGridMsg
from nav_msgs.msg import Odometry
from rclpy.action import ActionClient, ActionServer, CancelResponse, GoalResponse
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.executors import MultiThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.signals import SignalHandlerOptions
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import CameraInfo, Image
from sensor_msgs.msg import LaserScan as LaserScanMsg
from std_msgs.msg import String
from tf2_msgs.msg import TFMessage

from missiontree.backends.ros2 import conversions as conv
from missiontree.backends.ros2.pacing import next_stride
from missiontree.backends.ros2.profile import Ros2Profile
from missiontree.backends.ros2.qos import latched_qos, reliable_qos
from missiontree.backends.ros2.spin import spin_until, stop_spinning
from missiontree.robot.actions import ActionStatus
from missiontree.types import Pose2D

#: Nav2's result code for an error it cannot name (nav2_msgs NavigateToPose.Result.UNKNOWN).
NAV2_UNKNOWN = 9000
#: Simulator controls in (std_msgs/String) and the bridge's status out (JSON, transient local).
CONTROL_TOPIC = "/missiontree/sim/control"
STATUS_TOPIC = "/missiontree/sim/status"
#: Wall seconds between republications of the sensor data while paused.
PAUSED_PERIOD = 0.25
#: Simulated seconds between publications of the learned /map in unknown-map runs.
MAP_PERIOD = 1.0
#: A velocity command received this recently (s) survives the cancel of a goal.
CMD_VEL_HOLD = 0.5
#: Optical frame orientation relative to the camera link (z forward, x right, y down).
_OPTICAL = (-0.5, 0.5, -0.5, 0.5)


class SimBridge:
    """Serves a simulated robot over ROS 2 in real time.

    Besides the robot's topics it listens on ``/missiontree/sim/control`` (std_msgs/String) for
    simulator controls, as Gazebo's reset service: ``reset`` (a fresh simulator from the factory,
    robot back at the start; running goals abort), ``silence lidar|camera|<plugin sensor>`` and
    ``resume lidar|camera|<plugin sensor>`` (a sensor stops or restarts publishing); and publishes
    ``/missiontree/sim/status``
    (JSON: resets, controls applied, goals served; transient local) after each.

    With ``sim_time`` it works as Gazebo with ``use_sim_time``: stamps are simulated time and the
    simulated clock goes out on ``/clock``, so clients that set ``use_sim_time`` (a profile's
    ``use_sim_time: true``) stay consistent at any ``rate``, and when the machine cannot keep up.
    ``paused`` holds the clock at 0 (republishing the first sensor data) until the first goal,
    velocity command or ``resume`` control: a mission then starts with the world's clock.

    Args:
        make_sim: Builds the simulated robot (``missiontree.backends.sim.create_robot`` with options).
        profile: Topic and frame names to serve (the same profile a Ros2Robot reads).
        rate: Simulated seconds per wall second (1.0 = real time).
        odom_hz: Rate of /odom and /tf.
        sim_time: Stamp with simulated time and publish /clock.
        paused: Start with the clock held (see above).
    """

    def __init__(self, make_sim: Callable[[], Any], profile: Ros2Profile, rate: float = 1.0,
                 odom_hz: float = 20.0, sim_time: bool = False, paused: bool = False,
                 lock: threading.RLock | None = None) -> None:
        self.make_sim = make_sim
        self.sim_time = sim_time
        self.paused = paused
        self.sim = make_sim()
        self.profile = profile
        self.rate = rate
        self.odom_period = 1.0 / odom_hz
        self._sim_lock = lock or threading.RLock()
        #: In a fleet: the bridge whose loop steps the world (itself when alone), and the others it serves.
        self.lead: SimBridge = self
        self.peers: list[SimBridge] = []
        #: Scheduled kills the lead applies as its clock passes them: (simulated time, robot's bridge).
        self.kills: list[tuple[float, SimBridge]] = []
        #: Why this robot's servers vanished (:meth:`vanish`), "" while they serve.
        self.vanished = ""
        inside = profile.namespace != ""  # a fleet's robot: its controls under its namespace too
        self._control_topic = CONTROL_TOPIC.lstrip("/") if inside else CONTROL_TOPIC
        self._status_topic = STATUS_TOPIC.lstrip("/") if inside else STATUS_TOPIC
        self._stop = threading.Event()  # ends the pacing loop and running goals
        self._spin_stop = threading.Event()  # then ends the executor's spinning
        self._context = rclpy.Context()
        rclpy.init(context=self._context, domain_id=profile.domain_id,
                   signal_handler_options=SignalHandlerOptions.NO)
        overrides = [Parameter("use_sim_time", Parameter.Type.BOOL, True)] if sim_time else []
        self.node = Node("missiontree_sim", context=self._context, namespace=profile.namespace or None,
                         parameter_overrides=overrides)
        # ROS time of simulated time 0: stamps are ROS time, in step with the simulator when paced.
        self._epoch = self._ros_now() - self.sim.now()
        self._wall0, self._sim0 = time.monotonic(), self.sim.now()
        self._forget_published()
        self._last_command: tuple[float, float, float] | None = None  # (v, w, wall time received)
        self._executing = 0  # NavigateToPose goals running: their controller owns the base
        self.resets = 0
        self.controls = 0
        self.goals_served = 0
        self._advertise()
        self._executor = MultiThreadedExecutor(num_threads=4, context=self._context)
        self._executor.add_node(self.node)
        self._spinner = threading.Thread(target=self._spin, name="sim-ros-executor", daemon=True)

    def _forget_published(self) -> None:
        self._last_scan = self._last_frame = -math.inf
        self._last_odom = -math.inf
        self._last_map = -math.inf
        self._last_pose: Pose2D | None = None
        self._last_sensor: dict[str, float] = {}

    # ------------------------------------------------------------------------------ wiring

    def _advertise(self) -> None:
        t, node = self.profile.topics, self.node
        self._scan_pub = node.create_publisher(LaserScanMsg, t.scan, reliable_qos(10))
        self._odom_pub = node.create_publisher(Odometry, t.odom, reliable_qos(10))
        self._tf_pub = node.create_publisher(TFMessage, t.tf, reliable_qos(100))
        self._tf_static_pub = node.create_publisher(TFMessage, t.tf_static, latched_qos(100))
        self._map_pub = node.create_publisher(OccupancyGridMsg, t.map, latched_qos())
        self._amcl_pub = node.create_publisher(PoseWithCovarianceStamped, t.amcl_pose, latched_qos())
        self._color_pub = node.create_publisher(Image, t.color, reliable_qos(5))
        self._info_pub = node.create_publisher(CameraInfo, t.color_info, reliable_qos(5))
        self._depth_pub = node.create_publisher(Image, t.depth, reliable_qos(5))
        twist_type = TwistStamped if self.profile.cmd_vel_stamped else Twist
        node.create_subscription(twist_type, t.cmd_vel, self._on_cmd_vel, reliable_qos())
        group = ReentrantCallbackGroup()
        self._server = ActionServer(
            node, NavigateToPose, self.profile.navigation.action, execute_callback=self._execute,
            goal_callback=lambda _goal: GoalResponse.ACCEPT, cancel_callback=lambda _h: CancelResponse.ACCEPT,
            handle_accepted_callback=self._on_accepted, callback_group=group)
        # bt_navigator turns /goal_pose into a goal of its own action server; so does the bridge.
        self._self_client = ActionClient(node, NavigateToPose, self.profile.navigation.action,
                                         callback_group=group)
        node.create_subscription(PoseStampedMsg, t.goal_pose, self._on_goal_pose, reliable_qos(),
                                 callback_group=group)
        node.create_subscription(String, self._control_topic, self._on_control, reliable_qos())
        self._status_pub = node.create_publisher(String, self._status_topic, latched_qos())
        self._clock_pub = node.create_publisher(Clock, "/clock", reliable_qos(10))
        # plugin sensors the simulator produces and can publish (missiontree.robot.sensors)
        self._sensor_pubs: dict[str, tuple[Any, Any]] = {}
        for name in self.sim.sensor_names():
            kind = self.sim.plugin_sensors.store.kinds[name]
            if kind.ros2 is None or kind.ros2.to_msg is None or kind.sim is None:
                continue
            qos = latched_qos() if kind.ros2.qos == "latched" else reliable_qos(10)
            topic = self.profile.in_namespace(kind.ros2.topic)
            self._sensor_pubs[name] = (node.create_publisher(kind.ros2.message_type(), topic, qos),
                                       kind.ros2.to_msg)

    def _spin(self) -> None:
        spin_until(self._context, self._executor, self._spin_stop)

    def _ros_now(self) -> float:
        return self.node.get_clock().now().nanoseconds * 1e-9

    def stamp(self, sim_time: float) -> float:
        """ROS time of a simulated time (the simulated time itself in sim-time mode)."""
        return sim_time if self.sim_time else self._epoch + sim_time

    def resume(self) -> None:
        """Let a paused clock run (from now on, in step with wall time at the bridge's rate)."""
        if self.lead is not self:  # a fleet has one clock: its lead's
            self.lead.resume()
            return
        with self._sim_lock:
            if self.paused:
                self.paused = False
                self._anchor()

    def _anchor(self) -> None:
        """Pace from here: wall time and simulated time start together, wall-clock stamps from now."""
        self._wall0, self._sim0 = time.monotonic(), self.sim.now()
        if not self.sim_time:
            self._epoch = max(self._epoch, self._ros_now() - self.sim.now())  # stamps never go back

    # ------------------------------------------------------------------------------ commands in

    def _on_cmd_vel(self, msg: Twist | TwistStamped) -> None:
        v, w = conv.twist_from_msg(msg)
        with self._sim_lock:
            self._last_command = (v, w, time.monotonic())
            if self._executing and not self.vanished:
                # As with Nav2, the goal's controller owns the base while a goal runs: a stray command
                # (a client's last repeat crossing its new goal on the wire) must not stall the goal.
                # Clients that mean to take over cancel the goal first (Ros2Robot.drive does).
                return
            self.sim.drive(v, w)
        if v or w:
            self.resume()

    def _on_control(self, msg: String) -> None:
        words = msg.data.split()
        with self._sim_lock:
            if words == ["reset"] and self.lead is self and not self.peers:
                self.reset()
            elif words == ["kill"] and (self.peers or self.lead is not self):
                self.vanish("killed by a 'kill' control")
            elif words == ["resume"]:
                self.resume()
            elif len(words) == 2 and words[0] in ("silence", "resume") and (
                    words[1] in ("lidar", "camera") or words[1] in self.sim.sensor_names()):
                self.sim.silence(words[1], quiet=words[0] == "silence")
            else:
                self.node.get_logger().warning(
                    f"unknown simulator control {msg.data!r}; expected 'reset' (one robot only), "
                    "'kill' (a fleet's robot), 'resume', 'silence lidar|camera' or 'resume lidar|camera'")
                return
            self.controls += 1
        self._publish_status()

    def reset(self) -> None:
        """Replace the simulator by a fresh one (robot at the start); running goals end aborted."""
        with self._sim_lock:
            old = self.sim
            self.sim = self.make_sim()
            old.close()
            self.resets += 1
            self._last_command = None
            self._epoch = self._ros_now() - self.sim.now()
            self._wall0, self._sim0 = time.monotonic(), self.sim.now()
            self._forget_published()
            self.publish_static()
            self.publish_sensors()

    def _publish_status(self) -> None:
        status = {"resets": self.resets, "controls": self.controls, "goals_served": self.goals_served}
        self._status_pub.publish(String(data=json.dumps(status)))

    def _on_goal_pose(self, msg: PoseStampedMsg) -> None:
        if self.vanished:  # bt_navigator died with the server
            return
        goal = NavigateToPose.Goal()
        goal.pose = msg
        self._self_client.send_goal_async(goal)

    def _on_accepted(self, goal_handle: Any) -> None:
        goal_handle.execute()

    def _execute(self, goal_handle: Any) -> Any:
        """Run one NavigateToPose goal on the simulator: feedback at 10 Hz, result, cancel, preemption."""
        request = goal_handle.request
        goal = conv.pose_from_msg(request.pose.pose)
        self.resume()
        with self._sim_lock:
            sim = self.sim
            handle = sim.navigate_to(goal)
            started = sim.now()
            self._executing += 1
        self.goals_served += 1
        try:
            return self._follow(goal_handle, sim, handle, started)
        finally:
            with self._sim_lock:
                self._executing -= 1

    def _follow(self, goal_handle: Any, sim: Any, handle: Any, started: float) -> Any:
        """Poll the simulator's goal until it ends; mirror it on the action goal."""
        result = NavigateToPose.Result()
        while True:
            with self._sim_lock:
                gone = bool(self.vanished)
                if not gone and sim is not self.sim:  # reset under the goal
                    result.error_code, result.error_msg = NAV2_UNKNOWN, "the simulator was reset"
                    goal_handle.abort()
                    return result
                status = handle.status()
                feedback = handle.feedback()
                if goal_handle.is_cancel_requested and not status.done:
                    self._cancel_navigation()
                    status = handle.status()
                now = sim.now()
            if gone:  # the server vanished: the goal is never answered, as by a crashed Nav2
                self._stop.wait()
                return result
            if not goal_handle.is_active:
                return result
            if status.done or self._stop.is_set():
                break
            if feedback is not None:
                goal_handle.publish_feedback(self._feedback(feedback, now - started))
            time.sleep(0.1 / self.rate)
        outcome = handle.result()
        reason = outcome.reason if outcome is not None else "the simulator stopped"
        if self._stop.is_set() and not status.done:
            result.error_code, result.error_msg = NAV2_UNKNOWN, "the simulator was shut down"
            goal_handle.abort()
        elif status is ActionStatus.SUCCEEDED:
            goal_handle.succeed()
        elif status is ActionStatus.CANCELED and goal_handle.is_cancel_requested:
            goal_handle.canceled()
        else:  # aborted, or preempted by a newer goal (Nav2 ends the older one the same way)
            result.error_code = (outcome.code if outcome is not None and outcome.code else NAV2_UNKNOWN)
            result.error_msg = reason
            goal_handle.abort()
        return result

    def _cancel_navigation(self) -> None:
        """End the simulator's goal at once; a velocity command received lately stays in force."""
        self.sim.stop()
        if self._last_command is not None:
            v, w, received = self._last_command
            if time.monotonic() - received < CMD_VEL_HOLD:
                self.sim.drive(v, w)

    def _feedback(self, fb: Any, elapsed: float) -> Any:
        msg = NavigateToPose.Feedback()
        msg.current_pose = conv.pose_stamped_to_msg(fb.current_pose, self.stamp(self.sim.now()),
                                                    self.profile.frames.map)
        msg.navigation_time = conv.sec_to_duration(elapsed)
        speed = self.sim.profile.limits.max_v
        msg.estimated_time_remaining = conv.sec_to_duration(fb.distance_remaining / speed)
        msg.number_of_recoveries = int(fb.number_of_recoveries)
        msg.distance_remaining = float(fb.distance_remaining)
        return msg

    # ------------------------------------------------------------------------------ sensors out

    def publish_static(self) -> None:
        """Publish /tf_static (lidar and camera mounts) and /map once; transient local keeps them."""
        f, sp = self.profile.frames, self.sim.profile
        stamp = self.stamp(self.sim.now())
        lidar, cam = sp.lidar.mount, sp.camera.mount
        scan_frame = sp.lidar.frame_id
        camera_frame = self.profile.camera.frame
        transforms = [
            conv.transform_to_msg(Pose2D(lidar.x, lidar.y, math.radians(lidar.yaw_deg)), stamp, f.base,
                                  scan_frame),
            conv.transform_to_msg(Pose2D(cam.x, cam.y, math.radians(cam.yaw_deg)), stamp, f.base,
                                  camera_frame),
        ]
        transforms[0].transform.translation.z = float(lidar.z)
        transforms[1].transform.translation.z = float(cam.z)
        optical = TransformStamped()
        optical.header.stamp = conv.sec_to_time(stamp)
        optical.header.frame_id = camera_frame
        optical.child_frame_id = self._optical_frame
        q = optical.transform.rotation
        q.x, q.y, q.z, q.w = _OPTICAL
        transforms.append(optical)
        self._tf_static_pub.publish(TFMessage(transforms=transforms))
        grid = self.sim.occupancy()
        if grid is not None:
            self._map_pub.publish(conv.occupancy_to_msg(grid, f.map))

    @property
    def _optical_frame(self) -> str:
        return f"{self.profile.camera.frame.removesuffix('_frame')}_optical_frame"

    def publish_sensors(self) -> None:
        """Publish whatever the simulator produced since the last call (call with the sim lock held)."""
        sim, f = self.sim, self.profile.frames
        now = sim.now()
        if now - self._last_odom >= self.odom_period - 1e-9:
            pose = sim.pose()
            stamp = self.stamp(pose.stamp)
            v, w = self._body_velocity(pose.pose, now - self._last_odom)
            self._odom_pub.publish(conv.odometry_to_msg(pose.pose, v, w, stamp, f.odom, f.base))
            self._tf_pub.publish(TFMessage(transforms=[
                conv.transform_to_msg(Pose2D(0.0, 0.0, 0.0), stamp, f.map, f.odom),
                conv.transform_to_msg(pose.pose, stamp, f.odom, f.base),
            ]))
            amcl = PoseWithCovarianceStamped()
            amcl.header.stamp, amcl.header.frame_id = conv.sec_to_time(stamp), f.map
            amcl.pose.pose = conv.pose_to_msg(pose.pose)
            self._amcl_pub.publish(amcl)
            self._last_odom, self._last_pose = now, pose.pose
        scan = sim.scan()
        if scan is not None and scan.stamp > self._last_scan:
            self._last_scan = scan.stamp
            msg = conv.scan_to_msg(scan, scan_time=1.0 / sim.profile.lidar.rate)
            msg.header.stamp = conv.sec_to_time(self.stamp(scan.stamp))
            self._scan_pub.publish(msg)
        if getattr(sim, "unknown_map", False) and now - self._last_map >= MAP_PERIOD - 1e-9:
            grid = sim.occupancy()  # the map learned so far, republished as it grows (as slam_toolbox)
            if grid is not None:
                self._last_map = now
                msg = conv.occupancy_to_msg(grid, f.map)
                msg.header.stamp = conv.sec_to_time(self.stamp(grid.stamp))
                self._map_pub.publish(msg)
        frame = sim.rgbd()
        if frame is not None and frame.stamp > self._last_frame:
            self._last_frame = frame.stamp
            stamp = self.stamp(frame.stamp)
            optical = self._optical_frame
            self._color_pub.publish(conv.image_to_msg(frame.color, "rgb8", stamp, optical))
            self._info_pub.publish(conv.intrinsics_to_msg(frame.intrinsics, stamp, optical))
            self._depth_pub.publish(conv.depth_to_msg(frame.depth, stamp, optical, "16UC1"))
        for name, (publisher, to_msg) in self._sensor_pubs.items():
            reading = sim.sensor(name)
            if reading is not None and reading.stamp > self._last_sensor.get(name, -math.inf):
                self._last_sensor[name] = reading.stamp
                publisher.publish(to_msg(reading.value, self.stamp(reading.stamp)))

    def _body_velocity(self, pose: Pose2D, dt: float) -> tuple[float, float]:
        """Forward speed and yaw rate since the last odometry message (the estimate's own motion)."""
        last = self._last_pose
        if last is None or not 0.0 < dt < math.inf:
            return 0.0, 0.0
        dx, dy = pose.x - last.x, pose.y - last.y
        forward = dx * math.cos(last.yaw) + dy * math.sin(last.yaw)
        turn = math.atan2(math.sin(pose.yaw - last.yaw), math.cos(pose.yaw - last.yaw))
        return forward / dt, turn / dt

    # ------------------------------------------------------------------------------ the loop

    def run(self, duration: float | None = None) -> None:
        """Serve until :meth:`shutdown` (or for ``duration`` wall seconds), paced in real time.

        In a fleet the lead runs this for every robot: one world, one clock.
        """
        served = [self, *self.peers]
        with self._sim_lock:
            for bridge in served:
                bridge._epoch = bridge._ros_now() - bridge.sim.now()
                bridge._wall0, bridge._sim0 = time.monotonic(), bridge.sim.now()
                bridge.publish_static()
                bridge.publish_sensors()
        for bridge in served:
            bridge._spinner.start()
            bridge._publish_status()
        started = time.monotonic()
        while not self._stop.is_set():
            if duration is not None and time.monotonic() - started >= duration:
                break
            if self.paused:
                with self._sim_lock:
                    self._publish_clock()
                    for bridge in served:
                        bridge.republish()
                self._stop.wait(PAUSED_PERIOD)
                continue
            with self._sim_lock:
                dt = self.sim.profile.physics_dt
                wall_elapsed = time.monotonic() - self._wall0
                stride = next_stride(self.sim.now(), self._sim0, wall_elapsed, self.rate, dt)
                self._spin_to(stride.target)
                for bridge in served:
                    if stride.slipped:  # the machine cannot keep up: the world's clock slows, never leaps
                        bridge._anchor()
                    bridge.publish_sensors()  # before the clock: no client sees a time before its data
                self._publish_clock()
                next_wall = self._wall0 + (self.sim.now() - self._sim0 + dt) / self.rate
            self._stop.wait(max(0.0, next_wall - time.monotonic()))

    def _spin_to(self, target: float) -> None:
        """Step the simulator (a fleet: the whole fleet) to ``target``, killing robots due on the way."""
        while self.kills and self.kills[0][0] <= target:
            at, bridge = self.kills.pop(0)
            self.sim.spin_until(at)
            bridge.vanish(f"killed at {at:g} s (--kill-robot)")
        self.sim.spin_until(target)

    def vanish(self, reason: str) -> None:
        """A fleet robot's Nav2 crashes: its NavigateToPose server leaves the ROS graph for good.

        The robot stops where it stands (an obstacle to the others); a running goal is never
        answered, as by a crashed server; its sensors, odometry, TF and /cmd_vel go on, as the
        drivers of a robot whose navigation died would. The other robots are not touched.
        """
        with self._sim_lock:
            if self.vanished:
                return
            self.vanished = reason
            self.sim.stop()
        self._server.destroy()
        self._self_client.destroy()
        where = self.profile.namespace or "robot"
        self.node.get_logger().warning(f"{where}: NavigateToPose server gone ({reason})")

    def _publish_clock(self) -> None:
        if self.sim_time:
            self._clock_pub.publish(Clock(clock=conv.sec_to_time(self.sim.now())))

    def republish(self) -> None:
        """Publish the latest sensor data again, same stamps (while paused, for late subscribers)."""
        self._forget_published()
        self.publish_sensors()

    def shutdown(self) -> None:
        """Stop the loop (safe from a signal handler or another thread)."""
        self._stop.set()

    def close(self) -> None:
        """Stop serving, end running goals, leave the ROS graph and close the simulator (a fleet: all)."""
        for bridge in [self, *self.peers]:
            bridge._stop.set()
        time.sleep(0.2)  # let running goals publish their end while the executor still spins
        for peer in self.peers:
            peer._close_node()
        self._close_node()
        with self._sim_lock:
            for bridge in [self, *self.peers]:
                bridge.sim.close()

    def _close_node(self) -> None:
        """End the executor and leave the ROS graph (the server first, unless it vanished already)."""
        self._stop.set()
        stop_spinning(self._spin_stop, self._spinner, self._executor)
        if not self.vanished:
            self._server.destroy()
        self.node.destroy_node()
        if self._context.ok():
            self._context.try_shutdown()
