"""ROS 2 test fixtures: DDS kept on this machine, a fresh ROS_DOMAIN_ID per use, sim-ros processes.

Every ROS process these tests start (this one included) gets ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST,
so discovery never leaves the machine, and a domain id no other test run uses at the same time.
"""

from __future__ import annotations

import itertools
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

# Before anything imports rclpy: discovery stays on localhost.
os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"

REPO = Path(__file__).resolve().parents[3]
_FIRST_ID, _IDS = 20, 200  # Fast DDS allows domain ids up to 232
_offset = (os.getpid() * 37) % _IDS
_counter = itertools.count()


def next_domain_id() -> int:
    """A domain id for one test: spread by process id, never repeated within the run."""
    return _FIRST_ID + (_offset + next(_counter)) % _IDS


os.environ["ROS_DOMAIN_ID"] = str(next_domain_id())


def ros_env(domain_id: int) -> dict[str, str]:
    """The environment of a child ROS process on ``domain_id``, discovery on localhost only."""
    env = dict(os.environ)
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    env["ROS_DOMAIN_ID"] = str(domain_id)
    env["PYTHONUNBUFFERED"] = "1"
    return env


def wait_until(predicate: Callable[[], Any], timeout: float, what: str) -> Any:
    """Poll ``predicate`` until it returns something truthy; fail naming ``what`` after ``timeout``."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        value = predicate()
        if value:
            return value
        time.sleep(0.02)
    pytest.fail(f"timed out after {timeout:g} s waiting for {what}")


class SimRos:
    """A ``missiontree sim-ros`` child process on its own domain."""

    def __init__(self, domain_id: int, world: str = "office", seed: int = 0, extra: list[str] | None = None):
        self.domain_id = domain_id
        log_dir = Path(os.environ.get("TMPDIR", "/tmp"))
        self.log = open(log_dir / f"missiontree-sim-ros-{os.getpid()}-{domain_id}.log", "w+")  # noqa: SIM115
        self.process = subprocess.Popen(
            [sys.executable, "-m", "missiontree.cli.main", "sim-ros", "--world", world, "--seed", str(seed),
             *(extra or [])],
            env=ros_env(domain_id), stdout=self.log, stderr=subprocess.STDOUT, cwd=REPO)

    def output(self) -> str:
        """Everything the process printed so far."""
        self.log.flush()
        self.log.seek(0)
        return self.log.read()

    def stop(self) -> int:
        """SIGINT, then wait; kill after 10 s. Returns the exit code."""
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGINT)
            try:
                self.process.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()
        self.log.close()
        return self.process.returncode


@pytest.fixture(name="wait_until")
def wait_until_fixture() -> Callable[[Callable[[], Any], float, str], Any]:
    """:func:`wait_until`: poll a predicate, fail naming what was awaited."""
    return wait_until


@pytest.fixture
def start_sim_ros() -> Iterator[Callable[..., SimRos]]:
    """Factory of sim-ros processes stopped at the end of the test: ``start_sim_ros(domain_id, *flags)``."""
    servers: list[SimRos] = []

    def start(domain: int, *flags: str) -> SimRos:
        server = SimRos(domain, extra=list(flags))
        servers.append(server)
        return server

    yield start
    for server in servers:
        server.stop()


@pytest.fixture
def domain_id() -> int:
    """A fresh ROS_DOMAIN_ID for this test."""
    return next_domain_id()


@pytest.fixture(scope="module")
def sim_ros(request: pytest.FixtureRequest) -> Iterator[SimRos]:
    """One sim-ros process shared by a test module.

    The module may name the world (``SIM_ROS_WORLD``, default office), the seed (``SIM_ROS_SEED``, 0)
    and more command-line flags (``SIM_ROS_FLAGS``).
    """
    world = getattr(request.module, "SIM_ROS_WORLD", "office")
    seed = getattr(request.module, "SIM_ROS_SEED", 0)
    flags = list(getattr(request.module, "SIM_ROS_FLAGS", []))
    server = SimRos(next_domain_id(), world=world, seed=seed, extra=flags)
    yield server
    server.stop()


@pytest.fixture
def make_robot() -> Iterator[Callable[..., Any]]:
    """Factory of Ros2Robots closed after the test: ``make_robot(domain_id, **profile_overrides)``."""
    robots: list[Any] = []

    def make(domain: int, **overrides: Any) -> Any:
        from missiontree.backends.ros2.profile import load_profile
        from missiontree.backends.ros2.robot import Ros2Robot

        profile = load_profile("turtlebot4", {"domain_id": domain, "shutdown_timeout": 0.3, **overrides})
        robot = Ros2Robot(profile, node_name=f"test_robot_{len(robots)}", install_signal_stop=False)
        robots.append(robot)
        return robot

    yield make
    for robot in robots:
        robot.close()


def pytest_collectstart(collector: pytest.Collector) -> None:
    """With MISSIONTREE_REQUIRE_ROS2=1 (``make test``), a missing ROS 2 install fails instead of skipping."""
    if os.environ.get("MISSIONTREE_REQUIRE_ROS2") != "1" or not isinstance(collector, pytest.Module):
        return
    for module in ("rclpy", "nav2_msgs.action", "tf2_msgs.msg"):
        try:
            __import__(module)
        except ImportError as error:
            raise pytest.UsageError(
                f"MISSIONTREE_REQUIRE_ROS2=1 but {module} does not import ({error}); "
                "run `make setup-ros2` (scripts/setup-ros2.sh)") from error
