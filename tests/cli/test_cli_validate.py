"""Tests of `missiontree validate`."""

from __future__ import annotations

from pathlib import Path

import pytest

from missiontree.cli.main import main

REPO = Path(__file__).resolve().parents[2]


def test_valid_missions_exit_zero(capsys: pytest.CaptureFixture[str]) -> None:
    """Valid files print one ok line each and exit 0."""
    names = ("timer_and_blackboard.yaml", "subtree_include.yaml")
    files = [str(REPO / "trees/examples" / name) for name in names]
    assert main(["validate", "--no-plugins", *files]) == 0
    out = capsys.readouterr().out
    assert out.count("ok: ") == 2


def test_mixed_files_report_all_problems_and_exit_two(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A valid and two broken files: every problem of both broken files is listed, exit 2."""
    (tmp_path / "a.yaml").write_text("root:\n  Wait: {}\n")
    (tmp_path / "b.yaml").write_text("root: Nothing\n")
    good = REPO / "trees/examples/timer_and_blackboard.yaml"
    code = main(["validate", "--no-plugins", str(good), str(tmp_path / "a.yaml"), str(tmp_path / "b.yaml")])
    captured = capsys.readouterr()
    assert code == 2
    assert "a.yaml:2:3: root/Wait: expected parameter 'seconds'" in captured.err
    assert "b.yaml:1:7: root/Nothing: expected a known node type" in captured.err
    assert captured.err.strip().endswith("2 problems in 2 files")
    assert "ok: " in captured.out


def test_quiet_prints_nothing_for_valid_files(capsys: pytest.CaptureFixture[str]) -> None:
    """--quiet suppresses the ok lines."""
    assert main(["validate", "-q", "--no-plugins", str(REPO / "trees/examples/subtree_include.yaml")]) == 0
    assert capsys.readouterr().out == ""


def _validate(capsys: pytest.CaptureFixture[str], *files: Path | str) -> tuple[int, str, str]:
    code = main(["validate", "--no-plugins", *map(str, files)])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def test_references_of_a_mission_are_checked_with_their_lines(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`world: ofice`, `waypoints_file: no_such_route` and `goal_x: "six"` are problems at their lines."""
    mission = tmp_path / "m.yaml"
    mission.write_text(
        "run:\n  world: ofice\n"
        "blackboard:\n  goal_x: six\n"
        "root:\n  Sequence:\n    memory: true\n    children:\n"
        "      - Patrol: {waypoints_file: no_such_route}\n"
        "      - NavigateTo: {x: {bb: goal_x}, y: 1.0}\n")
    code, _, err = _validate(capsys, mission)
    assert code == 2
    assert f"{mission}:2:10: run.world: unknown world 'ofice'" in err and "office" in err
    assert f"{mission}:9:34: root/Sequence/Patrol[0]: unknown waypoint file 'no_such_route'" in err
    assert f"{mission}:10:25: root/Sequence/NavigateTo[1]: x: expected number in the blackboard default " \
           "'goal_x'" in err and "found 'six'" in err


def test_a_waypoint_file_for_another_world_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A waypoint file that says it was written for the corridor does not validate in the office."""
    mission = tmp_path / "m.yaml"
    mission.write_text("run: {world: office}\nroot:\n  Patrol: {waypoints_file: scenario_a}\n")
    code, _, err = _validate(capsys, mission)
    assert code == 2 and "written for 'corridor'" in err and f"{mission}:3:28:" in err


def test_waypoints_outside_the_map_or_in_obstacles_are_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A waypoint file (found beside the mission) whose points miss the world's free space is refused."""
    (tmp_path / "route.yaml").write_text("waypoints:\n  - [1.0, 1.0]\n  - [500.0, 3.0]\n")
    mission = tmp_path / "m.yaml"
    mission.write_text("run: {world: conformance}\nroot:\n  Patrol: {waypoints_file: route.yaml}\n")
    code, _, err = _validate(capsys, mission)
    assert code == 2 and "P2 (500, 3) lies outside the map" in err
    inline = tmp_path / "inline.yaml"
    inline.write_text("run: {world: conformance}\nroot:\n  Patrol: {waypoints: [[1.0, 1.0], [-300, 0]]}\n")
    code, _, err = _validate(capsys, inline)
    assert code == 2 and "lies outside the map" in err


def test_world_path_resolves_relative_to_the_mission(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`world: w.yaml` beside the mission is found from any working directory; its problems keep its lines."""
    (tmp_path / "w.yaml").write_text((REPO / "config/worlds/conformance.yaml").read_text())
    mission = tmp_path / "m.yaml"
    mission.write_text("run: {world: w.yaml}\nroot: Succeed\n")
    assert _validate(capsys, mission)[0] == 0
    (tmp_path / "w.yaml").write_text("name: w\nrobot: {start: {x: 1, y: .nan}}\nwalls: {segmnts: []}\n")
    code, _, err = _validate(capsys, mission)
    assert code == 2 and "w.yaml:2:" in err and "w.yaml:3:" in err and "segmnts" in err


def test_world_robot_models_and_waypoint_files_are_recognised(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Shipped configs validate alone naming their kind; broken ones report every problem at its line."""
    files = [REPO / "config/worlds/office.yaml", REPO / "config/robots/turtlebot4.yaml",
             REPO / "config/models/offline.yaml", REPO / "config/waypoints/scenario_a.yaml"]
    code, out, _ = _validate(capsys, *files)
    assert code == 0
    for kind in ("(world)", "(robot)", "(models)", "(waypoints)"):
        assert kind in out
    world = tmp_path / "world.yaml"
    world.write_text("name: w\nrobot: {start: {x: 1, y: 1}}\nwalls:\n  hieght: 2\n"
                     "  segments: [[[0, 0], [5, 0]]]\n"
                     "objects:\n  - {label: cup, size: [0.1, .inf, 0.1], pose: {x: 2, y: 2}}\n"
                     "people:\n  - {id: p, route: [[1, 1]], speed: .nan}\n")
    robot = tmp_path / "robot.yaml"
    robot.write_text("name: r\nbody: {radius: -1}\nlidar: {beams: 3, rnage_max: 4}\n")
    code, _, err = _validate(capsys, world, robot)
    assert code == 2
    assert f"{world}:4:3:" in err and "hieght" in err and f"{world}:7:" in err and f"{world}:9:" in err
    assert f"{robot}:2:" in err and f"{robot}:3:" in err and "rnage_max" in err and "beams" in err


def test_a_waypoint_file_alone_is_checked_against_the_world_it_names(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The corridor's route relabelled `world: office` is refused: its points lie outside the office."""
    text = (REPO / "config/waypoints/scenario_a.yaml").read_text().replace("world: corridor", "world: office")
    path = tmp_path / "route.yaml"
    path.write_text(text)
    code, _, err = _validate(capsys, path)
    assert code == 2 and "expected waypoints in the world 'office'" in err and "outside the map" in err


@pytest.mark.parametrize("command", [["validate"], ["render"], ["run"], ["batch", "--out", "OUT"]])
def test_a_text_file_read_as_a_mission_is_not_echoed(
        command: list[str], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A text file that parses as one YAML scalar (like /etc/passwd) is refused without printing its text."""
    secret = "root:x:0:0:root:/root:/bin/bash daemon:x:1:1:hunter2-password-line " * 20
    path = tmp_path / "passwd"
    path.write_text(secret.replace(" daemon", "\ndaemon"), encoding="utf-8")
    argv = [c.replace("OUT", str(tmp_path / "out")) for c in command]
    assert main([argv[0], "--no-plugins", str(path), *argv[1:]]) == 2
    captured = capsys.readouterr()
    assert "hunter2" not in captured.err + captured.out
    assert "text of 1,3" in captured.err  # says what it found, not the text


@pytest.mark.parametrize("body", [
    "root: {text}\n",
    "root:\n  {text}: {{}}\n",
    "root:\n  Include: {{file: {text}}}\n",
    "root:\n  Wait: {{seconds: {text}}}\n",
    "root:\n  Wait: {{name: [{text}]}}\n",
])
def test_a_long_value_in_a_mission_is_never_echoed_whole(
        body: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Pasted text as a node type, a key, an include, a number or a name is named by its size, not printed."""
    path = tmp_path / "m.yaml"
    path.write_text(body.format(text="PASTEDLINE" * 80), encoding="utf-8")
    assert main(["validate", "--no-plugins", str(path)]) == 2
    captured = capsys.readouterr()
    assert "PASTEDLINE" * 6 not in captured.err + captured.out
    assert "Traceback" not in captured.err
