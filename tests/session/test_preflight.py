"""What a mission references is checked before the run starts, with the mission's file:line:col."""

from __future__ import annotations

from pathlib import Path

import pytest

from missiontree.cli.main import main
from missiontree.engine.loader import load_mission
from missiontree.errors import MissionFileError
from missiontree.plugins.manager import load_plugins
from missiontree.session import MissionRequest, Session
from missiontree.session.preflight import check_references

PLUGINS = load_plugins(autoload=False)


def _mission(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "m.yaml"
    path.write_text(text)
    return path


def test_a_run_refuses_a_waypoint_file_for_another_world_before_starting(tmp_path: Path) -> None:
    """The corridor's waypoints in the office: refused at the parameter's line, no robot is built."""
    mission = _mission(tmp_path, "run: {world: office}\nroot:\n  Patrol: {waypoints_file: scenario_a}\n")
    with pytest.raises(MissionFileError) as caught:
        Session.open(MissionRequest(mission=mission, plugins=PLUGINS, out=tmp_path / "run"))
    assert f"{mission}:3:28:" in str(caught.value) and "written for 'corridor'" in str(caught.value)
    assert not (tmp_path / "run").exists()


def test_run_exits_2_on_a_misspelt_world(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """`world: ofice` ends `missiontree run` with exit 2 and the line, not a raw error dump."""
    mission = _mission(tmp_path, "run: {world: ofice}\nroot: Succeed\n")
    assert main(["run", "--no-plugins", "--quiet", str(mission), "--out", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err
    assert f"{mission}:1:14: run.world: unknown world 'ofice'" in err and "Traceback" not in err


def test_a_flag_world_overrides_and_is_named_as_the_flag(tmp_path: Path) -> None:
    """A bad --world is reported as the flag's problem, not at the mission's run section."""
    spec = load_mission(_mission(tmp_path, "run: {world: office}\nroot: Succeed\n"), PLUGINS.nodes)
    (problem,) = check_references(spec, world="atlantis")
    assert problem.file == "--world" and "atlantis" in problem.message


def test_a_waypoint_file_beside_the_mission_is_handed_over_as_checked(tmp_path: Path) -> None:
    """A waypoint file found beside the mission is resolved there, and the node reads that file."""
    (tmp_path / "route.yaml").write_text("waypoints:\n  - [1.0, 1.0]\n  - [2.0, 1.0]\n")
    spec = load_mission(_mission(tmp_path, "run: {world: conformance}\nroot:\n"
                                           "  Patrol: {waypoints_file: route.yaml}\n"), PLUGINS.nodes)
    assert check_references(spec) == []
    assert spec.root.params.waypoints_file == str((tmp_path / "route.yaml").resolve())  # type: ignore[union-attr]


def test_models_config_problems_are_located(tmp_path: Path) -> None:
    """A models config with an unknown provider is reported in its own file, at its line."""
    models = tmp_path / "models.yaml"
    models.write_text("roles:\n  vlm: {provider: gpt_magic}\n")
    spec = load_mission(_mission(tmp_path, f"run: {{models: {models}}}\nroot: Succeed\n"), PLUGINS.nodes)
    problems = check_references(spec, providers=PLUGINS.providers)
    assert any(p.file == str(models) and p.line == 2 and "gpt_magic" in p.message for p in problems)


def test_provider_options_are_checked_at_their_lines(tmp_path: Path) -> None:
    """A misspelt or out-of-range provider option is a problem at its line, before anything is built."""
    from missiontree.session.preflight import check_models_file

    models = tmp_path / "models.yaml"
    models.write_text("roles:\n  detector:\n    provider: sim_detector\n    score_threshold: 1.5\n"
                      "    thredas: 2\n  vlm:\n    provider: offline_vlm\n    detector: detector\n"
                      "    min_score: .nan\n")
    problems = [str(p) for p in check_models_file(models, PLUGINS.providers)]
    assert any(p.startswith(f"{models}:4:22: roles.detector.score_threshold") for p in problems), problems
    assert any(p.startswith(f"{models}:5:5:") and "'thredas'" in p and "threads" in p for p in problems)
    assert any(p.startswith(f"{models}:9:16:") and "finite" in p for p in problems)


_GOALS = ("root:\n  Sequence:\n    memory: true\n    children:\n"
          "      - NavigateTo: {x: 9.5, y: 7.5}\n"        # on the office's grey sofa
          "      - NavigateTo: {x: 9.5, y: 6.9}\n"        # 0.1 m from it: inside the robot's radius
          "      - NavigateTo: {x: 30, y: 1}\n"           # off the map
          "      - NavigateTo: {x: 3.5, y: 4.0}\n"        # open floor
          "      - NavigateTo: {x: {bb: gx}, y: 1.0}\n"   # known only when the leaf starts
          "blackboard: {gx: 40.0}\n")


def test_literal_goals_are_checked_against_the_named_world(tmp_path: Path) -> None:
    """Goals on an obstacle, within a robot radius of one, or off the map are reported at their line."""
    mission = _mission(tmp_path, "run: {world: office}\n" + _GOALS)
    problems = check_references(load_mission(mission, PLUGINS.nodes))
    assert [(p.line, p.path) for p in problems] == [(6, "root/Sequence/NavigateTo[0]"),
                                                    (7, "root/Sequence/NavigateTo[1]"),
                                                    (8, "root/Sequence/NavigateTo[2]")]
    assert "inside an obstacle" in problems[0].message
    assert "inscribed zone" in problems[1].message and "robot radius" in problems[1].message
    assert "outside the map" in problems[2].message


def test_goals_are_checked_in_a_world_named_by_the_flag_only_when_named(tmp_path: Path) -> None:
    """--world names the world for the check; a mission that names no world has its goals unchecked."""
    spec = load_mission(_mission(tmp_path, _GOALS), PLUGINS.nodes)
    assert check_references(spec) == []
    assert len(check_references(spec, world="office")) == 3


def test_validate_reports_a_goal_in_an_obstacle_with_file_line_col(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`missiontree validate` exits 2 with file:line:col and the node path for a goal on the sofa."""
    mission = _mission(tmp_path, "run: {world: office}\nroot:\n  NavigateTo: {x: 9.5, y: 7.5}\n")
    assert main(["validate", "--no-plugins", str(mission)]) == 2
    assert f"{mission}:3:19: root/NavigateTo: expected a goal the robot can reach" in capsys.readouterr().err


def test_a_flag_problem_names_the_flag_without_a_fake_position(tmp_path: Path) -> None:
    """A bad --world prints as `--world: ...` (no 0:0 position), a missing mission as `path: ...`."""
    spec = load_mission(_mission(tmp_path, "root: Succeed\n"), PLUGINS.nodes)
    (problem,) = check_references(spec, world="atlantis")
    assert str(problem).startswith("--world: unknown world 'atlantis'")
    missing = tmp_path / "patrl.yaml"
    with pytest.raises(MissionFileError) as caught:
        load_mission(missing, PLUGINS.nodes)
    assert str(caught.value).startswith(f"{missing}: file not found")
