"""Without ROS 2 installed, the ros2 backend says which extra to install (runs without ROS)."""

from __future__ import annotations

import subprocess
import sys
import textwrap


def test_missing_rclpy_raises_backend_unavailable_naming_the_extra() -> None:
    """create_robot with rclpy not importable raises BackendUnavailableError naming the extra and script."""
    code = textwrap.dedent("""
        import sys
        sys.modules["rclpy"] = None  # as if ROS 2 were not installed
        from missiontree.backends.ros2 import create_robot
        from missiontree.errors import BackendUnavailableError
        try:
            create_robot({})
        except BackendUnavailableError as error:
            assert isinstance(error, ImportError)
            print(error)
        else:
            raise SystemExit("no error raised")
    """)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60,
                         env={"ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST", "PATH": "/usr/bin:/bin"})
    assert out.returncode == 0, out.stderr
    assert "pip install -e .[ros2]" in out.stdout
    assert "scripts/setup-ros2.sh" in out.stdout


def test_importing_the_backend_package_does_not_import_rclpy() -> None:
    """Listing backends costs nothing: the package imports rclpy only when a robot is created."""
    code = "import sys, missiontree.backends.ros2; print('rclpy' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert out.stdout.strip() == "False", out.stderr


def _sim_ros_without(module: str) -> subprocess.CompletedProcess[str]:
    code = textwrap.dedent(f"""
        import sys
        sys.modules[{module!r}] = None  # as if this part of ROS 2 were not installed
        from missiontree.cli.main import main
        sys.exit(main(["sim-ros", "--duration", "1"]))
    """)
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                          env={"ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST", "PATH": "/usr/bin:/bin"})


def test_sim_ros_without_the_ros2_extra_exits_2_naming_it() -> None:
    """No rclpy, or rclpy without the NavigateToPose interface: exit 2, the extra named, no traceback."""
    for module in ("rclpy", "nav2_msgs"):
        out = _sim_ros_without(module)
        assert out.returncode == 2, (module, out.stderr)
        assert "Traceback" not in out.stderr and "ModuleNotFoundError" not in out.stderr.splitlines()[-1]
        assert "pip install -e .[ros2]" in out.stderr and "sim-ros" in out.stderr, out.stderr
