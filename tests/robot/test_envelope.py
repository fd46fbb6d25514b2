"""The safety envelope: goals outside the geofence or in a keep-out zone are never sent; speeds capped."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from missiontree.backends.sim import create_robot
from missiontree.errors import BackendError, ConfigError
from missiontree.robot.actions import ActionStatus
from missiontree.robot.envelope import REFUSED, EnvelopedRobot, Zone, parse_envelope, unwrap, wrap_robot
from missiontree.robot.interface import Drawable, Robot
from missiontree.session import MissionRequest, run_mission
from missiontree.types import Pose2D

SQUARE = [[0, 0], [10, 0], [10, 10], [0, 10]]
SAFETY = {"geofence": SQUARE, "keep_out": [{"name": "stairs", "polygon": [[4, 4], [6, 4], [6, 6], [4, 6]]}],
          "max_linear": 0.2, "max_angular": 1.0}


def test_a_concave_zone_holds_its_inside_and_edge_only() -> None:
    """An L-shaped zone contains points in both arms and on its edge, not the notch."""
    ell = Zone("L", ((0, 0), (4, 0), (4, 1), (1, 1), (1, 4), (0, 4)))
    assert ell.contains(3, 0.5) and ell.contains(0.5, 3) and ell.contains(4, 0.5)
    assert not ell.contains(3, 3) and not ell.contains(-0.1, 2)


@pytest.mark.parametrize(("section", "named"), [
    ({"geofense": SQUARE}, "unknown keys ['geofense']"),
    ({"geofence": [[0, 0], [1, 1]]}, "safety.geofence: expected a list of 3"),
    ({"geofence": [[0, 0], [1, math.nan], [1, 0]]}, "safety.geofence[1][1]: expected a finite number"),
    ({"keep_out": [{"name": "x"}]}, "safety.keep_out[0]: expected {name"),
    ({"max_linear": -1}, "safety.max_linear: expected a speed above 0"),
    ([1, 2], "safety: expected a mapping"),
])
def test_a_malformed_section_names_the_key(section: object, named: str) -> None:
    """Each malformed safety section is a ConfigError naming the key and what was expected."""
    with pytest.raises(ConfigError, match=named.replace("[", r"\[").replace("]", r"\]")):
        parse_envelope(section)


def test_without_a_section_the_robot_is_not_wrapped() -> None:
    """No safety section: the backend's robot as it is (nothing changes for existing runs)."""
    robot = create_robot({"world": "corridor"})
    assert wrap_robot(robot, {}) is robot


def test_refused_goals_are_never_sent_and_allowed_goals_are() -> None:
    """Outside the geofence or inside a keep-out zone: REJECTED at once, kind refused, robot unmoved."""
    events: list[tuple[str, dict[str, object]]] = []
    robot = wrap_robot(create_robot({"world": "corridor"}), {"safety": SAFETY})
    assert isinstance(robot, EnvelopedRobot) and isinstance(robot, Robot) and isinstance(robot, Drawable)
    robot.emit = lambda event, **fields: events.append((event, fields))
    cases = ((Pose2D(12, 5, 0), "outside the geofence"), (Pose2D(5, 5, 0), "keep-out zone 'stairs'"),
             (Pose2D(math.nan, 1, 0), "not a finite pose"))
    for goal, words in cases:
        handle = robot.navigate_to(goal)
        assert handle.status() is ActionStatus.REJECTED
        assert handle.result().kind == REFUSED and words in handle.result().reason
    assert [e for e, _ in events] == ["safety_refused"] * 3
    assert unwrap(robot).navigate_to(Pose2D(1, 1, 0)).status() is not ActionStatus.REJECTED


def test_speeds_are_capped_and_a_non_finite_command_stops_the_robot() -> None:
    """drive() passes capped speeds to the backend; NaN raises BackendError after stopping."""
    sent: list[tuple[float, float]] = []

    class Inner:
        name, simulated = "inner", True

        def drive(self, v: float, w: float) -> None:
            sent.append((v, w))

        def stop(self) -> None:
            sent.append((0.0, 0.0))

    robot = wrap_robot(Inner(), {"safety": SAFETY})
    robot.drive(1.0, -3.0)
    robot.drive(0.1, 0.5)
    with pytest.raises(BackendError, match="not finite"):
        robot.drive(math.inf, 0.0)
    assert sent == [(0.2, -1.0), (0.1, 0.5), (0.0, 0.0)]


def test_a_blackboard_goal_in_a_keep_out_zone_fails_with_the_zone_named(tmp_path: Path) -> None:
    """A blackboard goal in a keep-out zone ends FAILURE naming the zone; the log has the refusal."""
    mission = tmp_path / "go.yaml"
    mission.write_text("version: 1\nrun: {world: corridor, max_duration: 30}\nblackboard: {gx: 5.0}\n"
                       "root:\n  NavigateTo: {x: {bb: gx}, y: 0.0}\n")
    config = tmp_path / "safety.yaml"
    zone = {"name": "wet floor", "polygon": [[4, -1], [6, -1], [6, 1], [4, 1]]}
    config.write_text(json.dumps({"safety": {"keep_out": [zone]}}))
    result = run_mission(MissionRequest(mission=mission, config=str(config), out=tmp_path / "run",
                                        quiet=True, handle_signals=False))
    assert result.status.value == "FAILURE" and result.ticks == 1
    log = (tmp_path / "run" / "ticks.jsonl").read_text()
    assert "keep-out zone 'wet floor'" in log and '"event":"safety_refused"' in log
