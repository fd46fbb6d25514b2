"""A helper for tests that need another ROS 2 participant beside the robot under test.

:class:`SpinningPeer` owns an rclpy context on a given domain, one node and an executor spun on a
background thread; subclasses add their publishers, subscriptions and servers in ``__init__`` after
calling ``super().__init__`` and then call :meth:`SpinningPeer.start`. Keep discovery on the machine
(``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``) and give each test its own domain id.
"""

from __future__ import annotations

import threading


class SpinningPeer:
    """A ROS 2 node on its own context, spun on a daemon thread until :meth:`close`."""

    def __init__(self, domain: int, name: str, threads: int = 1) -> None:
        import rclpy
        from rclpy.executors import MultiThreadedExecutor, SingleThreadedExecutor
        from rclpy.node import Node
        from rclpy.signals import SignalHandlerOptions

        self.context = rclpy.Context()
        rclpy.init(context=self.context, domain_id=domain, signal_handler_options=SignalHandlerOptions.NO)
        self.node = Node(name, context=self.context)
        self.executor = (MultiThreadedExecutor(num_threads=threads, context=self.context) if threads > 1
                         else SingleThreadedExecutor(context=self.context))
        self.stopping = threading.Event()
        self.thread = threading.Thread(target=self._spin, daemon=True)

    def start(self) -> None:
        """Add the node to the executor and start spinning (after the subclass created its entities)."""
        self.executor.add_node(self.node)
        self.thread.start()

    def _spin(self) -> None:
        while self.context.ok() and not self.stopping.is_set():
            try:
                self.executor.spin_once(timeout_sec=0.05)
            except Exception:  # noqa: BLE001 - shutting down under the executor
                return

    def close(self) -> None:
        """Stop spinning, then leave the ROS graph."""
        self.stopping.set()
        self.thread.join(timeout=2.0)
        self.executor.shutdown(timeout_sec=1.0)
        self.node.destroy_node()
        self.context.try_shutdown()
