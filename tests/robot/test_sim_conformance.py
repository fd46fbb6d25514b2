"""The robot conformance suite run against the simulator."""

from __future__ import annotations

from collections.abc import Callable, Iterator

import pytest

from missiontree.backends.sim import SimRobot, create_robot
from missiontree.robot.conformance import RobotConformance


class TestSimConformance(RobotConformance):
    @pytest.fixture
    def robot(self, conformance_world: str) -> Iterator[SimRobot]:
        robot = create_robot({"world": conformance_world, "seed": 3})
        yield robot
        robot.close()

    @pytest.fixture
    def silence(self, robot: SimRobot) -> Callable[[str], None]:
        return robot.silence
