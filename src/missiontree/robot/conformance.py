"""The robot conformance suite: what every backend must do, as pytest tests.

A backend's test module subclasses :class:`RobotConformance` and provides the ``robot`` fixture
(and, if it can, ``silence``)::

    class TestSimConformance(RobotConformance):
        @pytest.fixture
        def robot(self, conformance_world):
            robot = create_robot({"world": conformance_world})
            yield robot
            robot.close()

The suite only uses the :class:`~missiontree.robot.interface.Robot` protocol. Time budgets are
in the backend's clock (simulated seconds in the simulator, ROS time over DDS) and tolerances
are generous, so the same tests hold for the simulator and for the simulator served as ROS 2.
The expectations about the world (where the robot starts, the wall ahead, a free goal and a
goal inside an obstacle) are class attributes matching ``config/worlds/conformance.yaml``; a
backend running elsewhere overrides them.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator

import numpy as np
import pytest

from missiontree.robot.actions import ActionStatus, NavFeedback
from missiontree.robot.interface import Robot
from missiontree.types import LaserScan, OccupancyGrid, Pose2D, PoseStamped, RGBDFrame, Tolerance

ANY_HEADING = 2.0 * math.pi


def spin_for(robot: Robot, seconds: float, step: float = 0.1,
             until: Callable[[], bool] | None = None) -> bool:
    """Spin ``robot`` for ``seconds`` of its clock in ``step``s; stop early once ``until()`` holds."""
    end = robot.now() + seconds
    while robot.now() < end:
        robot.spin_until(min(end, robot.now() + step))
        if until is not None and until():
            return True
    return until() if until is not None else True


class RobotConformance:
    """Tests every backend passes. Subclass it and override the ``robot`` fixture."""

    #: Distance from the robot's start to the wall straight ahead (m), as seen by the lidar.
    front_wall_distance: float = 4.0
    #: A goal in free space about 1.2 m from the start, and one inside an obstacle.
    free_goal: Pose2D = Pose2D(2.0, 3.2, 0.0)
    blocked_goal: Pose2D = Pose2D(3.5, 1.0, 0.0)
    #: A goal far enough away that cancelling after 2 s catches the robot on its way.
    far_goal: Pose2D = Pose2D(4.2, 4.2, 0.0)
    #: Whether the lidar follows the TurtleBot 4 index convention (index 0 right, front at 25 %).
    turtlebot4_index_convention: bool = True
    #: Backend-clock budget for a short navigation goal (s).
    navigation_budget: float = 60.0

    @pytest.fixture
    def conformance_world(self) -> str:
        """The world the backend should load or serve (a shipped world name)."""
        return "conformance"

    @pytest.fixture
    def robot(self, conformance_world: str) -> Iterator[Robot]:
        """The robot under test, standing at the world's start; backends override this."""
        raise NotImplementedError("a backend's conformance test class must override the `robot` fixture")
        yield  # pragma: no cover

    @pytest.fixture
    def silence(self) -> Callable[[str], None]:
        """A function that makes a sensor (``lidar`` or ``camera``) stop publishing; skip if impossible."""
        pytest.skip("this backend cannot silence a sensor on purpose")

    @pytest.fixture
    def ready(self, robot: Robot) -> Robot:
        """The robot after its first pose, scan and frame arrived (within 10 s of its clock)."""
        ok = spin_for(robot, 10.0, until=lambda: None not in (robot.pose(), robot.scan(), robot.rgbd()))
        assert ok, "expected a pose, a scan and an RGB-D frame within 10 s of the backend clock"
        return robot

    # -- protocol and clock ----------------------------------------------------------------------

    def test_conformance_implements_the_protocol(self, robot: Robot) -> None:
        """The backend is a Robot (every protocol method present) with a name and a simulated flag."""
        assert isinstance(robot, Robot)
        assert isinstance(robot.name, str) and isinstance(robot.simulated, bool)

    def test_conformance_clock_advances_with_spin_until(self, robot: Robot) -> None:
        """spin_until(t) returns once the clock reached t, and at once for a time already past."""
        t0 = robot.now()
        robot.spin_until(t0 + 1.0)
        t1 = robot.now()
        assert t1 >= t0 + 1.0 - 1e-6
        assert t1 < t0 + 1.0 + 0.5
        robot.spin_until(t0)
        assert robot.now() - t1 < 0.2

    # -- sensors ---------------------------------------------------------------------------------

    def test_conformance_pose_is_stamped(self, ready: Robot) -> None:
        """pose() is a PoseStamped in the map frame, stamped no later than now()."""
        stamped = ready.pose()
        assert isinstance(stamped, PoseStamped)
        assert stamped.stamp <= ready.now() + 1e-6
        assert all(math.isfinite(v) for v in (stamped.pose.x, stamped.pose.y, stamped.pose.yaw))

    def test_conformance_scan_shape_and_stamp(self, ready: Robot) -> None:
        """scan() is a LaserScan whose ranges match its angle layout, recent and within its limits."""
        scan = ready.scan()
        assert isinstance(scan, LaserScan)
        n = len(scan.ranges)
        assert n >= 4 and scan.angle_increment > 0
        assert n * scan.angle_increment <= 2 * math.pi + 1e-3
        assert len(scan.angles()) == n
        assert ready.now() - 1.0 <= scan.stamp <= ready.now() + 1e-6
        r = np.asarray(scan.ranges, dtype=float)
        finite = r[np.isfinite(r)]
        assert len(finite) > n // 2, "expected returns from most beams in a closed room"
        assert finite.min() >= scan.range_min - 1e-3 and finite.max() <= scan.range_max + 1e-3

    def test_conformance_scan_sees_the_wall_ahead(self, ready: Robot) -> None:
        """The beam whose robot-frame angle is 0 measures the wall straight ahead (±0.15 m)."""
        scan = ready.scan()
        assert scan is not None
        angles = np.angle(np.exp(1j * scan.angles()))
        front = int(np.argmin(np.abs(angles)))
        assert abs(float(scan.ranges[front]) - self.front_wall_distance) < 0.15

    def test_conformance_scan_front_at_a_quarter(self, ready: Robot) -> None:
        """TurtleBot 4 convention: index 0 looks right, a quarter of the array ahead, half left."""
        if not self.turtlebot4_index_convention:
            pytest.skip("backend does not use the TurtleBot 4 index convention")
        scan = ready.scan()
        assert scan is not None
        angles = np.angle(np.exp(1j * scan.angles()))
        n = len(scan.ranges)
        assert abs(angles[0] + math.pi / 2) < 0.05
        assert abs(angles[n // 4]) < 0.05
        assert abs(angles[n // 2] - math.pi / 2) < 0.05

    def test_conformance_rgbd_shapes_and_stamp(self, ready: Robot) -> None:
        """rgbd() holds an HxWx3 uint8 colour image, an HxW float depth in metres and matching intrinsics."""
        frame = ready.rgbd()
        assert isinstance(frame, RGBDFrame)
        h, w = frame.intrinsics.height, frame.intrinsics.width
        assert frame.color.shape == (h, w, 3) and frame.color.dtype == np.uint8
        assert frame.depth.shape == (h, w) and np.issubdtype(frame.depth.dtype, np.floating)
        valid = frame.depth[np.isfinite(frame.depth) & (frame.depth > 0)]
        assert valid.size > 0 and valid.max() < 50.0, "expected depth in metres"
        assert ready.now() - 2.0 <= frame.stamp <= ready.now() + 1e-6
        assert 40 < math.degrees(frame.intrinsics.hfov) < 120

    def test_conformance_stamps_advance(self, ready: Robot) -> None:
        """Sensor stamps move on as the clock does."""
        scan0, frame0 = ready.scan(), ready.rgbd()
        assert scan0 is not None and frame0 is not None
        spin_for(ready, 1.5)
        scan1, frame1 = ready.scan(), ready.rgbd()
        assert scan1 is not None and frame1 is not None
        assert scan1.stamp > scan0.stamp and frame1.stamp > frame0.stamp

    def test_conformance_stale_stamp_visible(self, ready: Robot, silence: Callable[[str], None]) -> None:
        """A sensor that went quiet keeps returning its last value with its old stamp."""
        silence("lidar")
        spin_for(ready, 0.3)
        last = ready.scan()
        assert last is not None
        spin_for(ready, 1.5)
        scan = ready.scan()
        assert scan is not None and scan.stamp == last.stamp
        assert ready.now() - scan.stamp >= 1.4

    def test_conformance_occupancy_map(self, ready: Robot) -> None:
        """occupancy() is a map with a resolution, an origin and cells in -1..100."""
        grid = ready.occupancy()
        assert isinstance(grid, OccupancyGrid)
        assert grid.resolution > 0 and grid.data.ndim == 2
        assert grid.data.min() >= -1 and grid.data.max() <= 100
        row, col = grid.world_to_cell(self.free_goal.x, self.free_goal.y)
        assert grid.data[row, col] == 0, "expected the free goal to lie on a free cell"

    # -- history ---------------------------------------------------------------------------------

    def test_conformance_pose_at_interpolates_recent_history(self, ready: Robot) -> None:
        """pose_at(t) answers for recent stamps (between the poses around it) and None outside."""
        ready.drive(0.2, 0.0)
        spin_for(ready, 0.5)  # under way (the command's trip and the base's acceleration)
        t0 = ready.now()
        spin_for(ready, 1.0)
        t1 = ready.now()
        spin_for(ready, 0.5)
        ready.stop()
        self._pose_after(ready, t1 + 0.1)  # the history reaches past t1
        p0, p1 = ready.pose_at(t0), ready.pose_at(t1)
        mid = ready.pose_at((t0 + t1) / 2)
        assert p0 is not None and p1 is not None and mid is not None
        assert p0.distance_to(p1) > 0.1
        assert abs(p0.distance_to(mid) + mid.distance_to(p1) - p0.distance_to(p1)) < 0.03
        assert ready.pose_at(ready.now() + 100.0) is None
        assert ready.pose_at(ready.now() - 1000.0) is None

    def test_conformance_scan_at_returns_the_scan_of_that_moment(self, ready: Robot) -> None:
        """scan_at(stamp of an earlier scan) returns that scan, not the latest; None far outside."""
        earlier = ready.scan()
        assert earlier is not None
        spin_for(ready, 1.0)
        found = ready.scan_at(earlier.stamp)
        assert found is not None and abs(found.stamp - earlier.stamp) < 1e-6
        assert ready.scan_at(ready.now() - 1000.0) is None

    # -- motion ----------------------------------------------------------------------------------

    def test_conformance_drive_moves_and_stop_halts(self, ready: Robot) -> None:
        """drive(v, 0) moves the robot forward along its heading; after stop() it stays put."""
        start = self._pose(ready)
        ready.drive(0.2, 0.0)
        spin_for(ready, 2.0)
        moved = self._pose_after(ready, ready.now()).pose
        ahead = (moved.x - start.x) * math.cos(start.yaw) + (moved.y - start.y) * math.sin(start.yaw)
        assert 0.2 < ahead < 0.6
        ready.stop()
        spin_for(ready, 1.0)
        settled = self._pose_after(ready, ready.now()).pose
        spin_for(ready, 1.0)
        assert settled.distance_to(self._pose_after(ready, ready.now()).pose) < 0.02

    def test_conformance_drive_rotates_in_place(self, ready: Robot) -> None:
        """drive(0, w) turns the robot without moving it."""
        start = self._pose(ready)
        ready.drive(0.0, 1.0)
        spin_for(ready, 1.0)
        ready.stop()
        spin_for(ready, 0.5)
        end = self._pose_after(ready, ready.now()).pose
        turned = math.remainder(end.yaw - start.yaw, 2 * math.pi)
        assert 0.6 < turned < 1.6
        assert start.distance_to(end) < 0.05

    def test_conformance_stop_is_idempotent(self, ready: Robot) -> None:
        """stop() works with nothing running and twice in a row."""
        ready.stop()
        ready.stop()
        spin_for(ready, 0.2)

    # -- navigation ------------------------------------------------------------------------------

    def test_conformance_navigate_succeeds_in_free_space(self, ready: Robot) -> None:
        """A goal in free space is accepted, gives feedback, and succeeds within its tolerance."""
        handle = ready.navigate_to(self.free_goal, Tolerance(xy=0.25, yaw=ANY_HEADING))
        assert not handle.status().done
        feedback: list[NavFeedback] = []

        def done() -> bool:
            fb = handle.feedback()
            if fb is not None:
                feedback.append(fb)
            return handle.status().done

        spin_for(ready, self.navigation_budget, until=done)
        result = handle.result()
        assert handle.status() is ActionStatus.SUCCEEDED, result
        assert result is not None and result.succeeded
        pose = self._pose_after(ready, ready.now())
        assert pose.pose.distance_to(self.free_goal) < 0.25 + 0.1, (pose, ready.now())
        assert feedback and all(fb.distance_remaining >= 0 for fb in feedback)

    def test_conformance_navigate_reaches_goal_heading(self, ready: Robot) -> None:
        """With a tight yaw tolerance the robot also turns to the goal heading."""
        goal = Pose2D(self.free_goal.x, self.free_goal.y, math.pi / 2)
        handle = ready.navigate_to(goal, Tolerance(xy=0.25, yaw=0.2))
        spin_for(ready, self.navigation_budget, until=lambda: handle.status().done)
        assert handle.status() is ActionStatus.SUCCEEDED, handle.result()
        pose = self._pose_after(ready, ready.now())
        assert abs(math.remainder(pose.pose.yaw - goal.yaw, 2 * math.pi)) < 0.2 + 0.1, (pose, ready.now())

    def test_conformance_navigate_aborts_unreachable_goal_with_reason(self, ready: Robot) -> None:
        """A goal inside an obstacle ends ABORTED (or REJECTED) with a reason, not an exception."""
        handle = ready.navigate_to(self.blocked_goal, Tolerance(xy=0.1, yaw=ANY_HEADING))
        spin_for(ready, 20.0, until=lambda: handle.status().done)
        assert handle.status() in (ActionStatus.ABORTED, ActionStatus.REJECTED)
        result = handle.result()
        assert result is not None and not result.succeeded and result.reason

    def test_conformance_navigate_cancel(self, ready: Robot) -> None:
        """cancel() ends a running goal as CANCELED and the robot comes to rest."""
        handle = ready.navigate_to(self.far_goal, Tolerance(xy=0.1, yaw=ANY_HEADING))
        spin_for(ready, 2.0)
        assert not handle.status().done
        handle.cancel()
        handle.cancel()
        spin_for(ready, 5.0, until=lambda: handle.status().done)
        assert handle.status() is ActionStatus.CANCELED
        spin_for(ready, 1.0)
        rest = self._pose(ready)
        spin_for(ready, 1.0)
        assert rest.distance_to(self._pose(ready)) < 0.02

    def test_conformance_new_goal_preempts_the_running_one(self, ready: Robot) -> None:
        """Sending a second goal ends the first one (preempted), and the second runs to success."""
        first = ready.navigate_to(self.far_goal, Tolerance(xy=0.1, yaw=ANY_HEADING))
        spin_for(ready, 1.0)
        second = ready.navigate_to(self.free_goal, Tolerance(xy=0.25, yaw=ANY_HEADING))
        spin_for(ready, self.navigation_budget, until=lambda: second.status().done)
        assert first.status().done and first.status() is not ActionStatus.SUCCEEDED
        assert second.status() is ActionStatus.SUCCEEDED, second.result()

    def test_conformance_drive_overrides_navigation(self, ready: Robot) -> None:
        """While drive() is commanded during a goal, the robot follows the drive command."""
        handle = ready.navigate_to(self.far_goal, Tolerance(xy=0.1, yaw=ANY_HEADING))
        spin_for(ready, 1.0)
        ready.drive(0.0, 0.8)
        spin_for(ready, 0.5)  # the goal's cancel takes effect (on ROS 2, a round trip to the server)
        before = self._pose_after(ready, ready.now()).pose
        spin_for(ready, 1.0)
        after = self._pose_after(ready, ready.now()).pose
        ready.stop()
        assert before.distance_to(after) < 0.05
        assert abs(math.remainder(after.yaw - before.yaw, 2 * math.pi)) > 0.4
        spin_for(ready, 1.0, until=lambda: handle.status().done)
        assert handle.status().done, "stop() must end the goal that drive() interrupted"

    # -- helpers ---------------------------------------------------------------------------------

    @staticmethod
    def _pose_after(robot: Robot, stamp: float, budget: float = 5.0) -> PoseStamped:
        """The first pose stamped at or after ``stamp``.

        A goal's result and the robot's pose travel separately (on ROS 2, an action response and
        /tf); a pose read the instant the result arrives may be older than the result.
        """
        spin_for(robot, budget, step=0.02, until=lambda: (p := robot.pose()) is not None and p.stamp >= stamp)
        stamped = robot.pose()
        assert stamped is not None and stamped.stamp >= stamp, (stamped, stamp)
        return stamped

    @staticmethod
    def _pose(robot: Robot) -> Pose2D:
        stamped = robot.pose()
        assert stamped is not None
        return stamped.pose
