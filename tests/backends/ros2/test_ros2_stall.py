"""sim-ros under a machine that cannot keep up: its clock slows, it never leaps past its sensors.

A loaded CI runner once descheduled sim-ros for a few seconds; at rate 4 it then caught up ten
simulated seconds in one stride and sent /clock before the odometry of that stride, so a mission
following /clock saw its pose ten seconds old and called the robot lost. Here sim-ros is stopped
with SIGSTOP for 2.5 wall seconds while a plain rclpy node records, for every /clock message, how far
it lies ahead of the newest odometry received before it.
"""

from __future__ import annotations

import signal
import threading
import time
from collections.abc import Callable
from typing import Any

import pytest

pytest.importorskip("rclpy", reason="ROS 2 extra not installed: pip install -e .[ros2]; setup-ros2.sh")
pytest.importorskip("nav2_msgs.action", reason="nav2_msgs not built: run scripts/setup-ros2.sh")
pytestmark = [pytest.mark.ros2, pytest.mark.slow]


class _Listener:
    """/clock and /odom in arrival order, on one single-threaded executor of its own."""

    def __init__(self, domain_id: int) -> None:
        import rclpy
        from nav_msgs.msg import Odometry
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.qos import QoSProfile, ReliabilityPolicy
        from rosgraph_msgs.msg import Clock

        self.context = rclpy.Context()
        rclpy.init(context=self.context, domain_id=domain_id)
        self.node = rclpy.create_node("stall_listener", context=self.context)
        qos = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
        self.odom = -1.0
        self.clock = -1.0
        self.worst_lead = 0.0  # the largest /clock time minus the newest odometry stamp before it
        self.node.create_subscription(Odometry, "/odom", self._on_odom, qos)
        self.node.create_subscription(Clock, "/clock", self._on_clock, qos)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self._stop = threading.Event()
        self.thread = threading.Thread(target=self._spin, daemon=True)
        self.thread.start()

    @staticmethod
    def _sec(stamp: Any) -> float:
        return float(stamp.sec) + float(stamp.nanosec) * 1e-9

    def _on_odom(self, msg: Any) -> None:
        self.odom = max(self.odom, self._sec(msg.header.stamp))

    def _on_clock(self, msg: Any) -> None:
        self.clock = self._sec(msg.clock)
        if self.odom >= 0.0:
            self.worst_lead = max(self.worst_lead, self.clock - self.odom)

    def _spin(self) -> None:
        while not self._stop.is_set() and self.context.ok():
            self.executor.spin_once(timeout_sec=0.05)

    def close(self) -> None:
        self._stop.set()
        self.thread.join(timeout=5)
        self.node.destroy_node()
        self.context.try_shutdown()


def test_a_stalled_sim_ros_does_not_leap_its_clock_past_its_odometry(
        start_sim_ros: Callable[..., Any], domain_id: int, wait_until: Callable) -> None:
    """After a 2.5 s stall at rate 4, no /clock message runs more than a stride ahead of /odom."""
    server = start_sim_ros(domain_id, "--sim-time", "--rate", "4")
    listener = _Listener(domain_id)
    try:
        wait_until(lambda: listener.odom > 1.0, 60.0, f"sim-ros's odometry; its output: {server.output()}")
        before = listener.clock
        server.process.send_signal(signal.SIGSTOP)
        time.sleep(2.5)
        server.process.send_signal(signal.SIGCONT)
        wait_until(lambda: listener.clock > before + 2.0, 60.0, "the clock to run again after the stall")
        # 2.5 wall seconds at rate 4 would be a 10 s stride; a slowed clock leads by one stride at most
        assert listener.worst_lead < 1.0, f"/clock ran {listener.worst_lead:.2f} s ahead of /odom"
    finally:
        listener.close()
