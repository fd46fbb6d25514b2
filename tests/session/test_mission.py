"""Tests of the session: one wiring path for a mission run, --set params, map choice, progress line."""

from __future__ import annotations

import gc
import io
import json
from pathlib import Path
from typing import Any

import pytest

from missiontree.cli.main import main
from missiontree.engine.loader import load_mission
from missiontree.errors import ConfigError, MissionFileError
from missiontree.plugins.manager import load_plugins
from missiontree.session import MissionRequest, Session, process, run_mission
from missiontree.session.progress import ProgressLine
from missiontree.testing import ClockRobot, clean_state

MISSION = """\
version: 1
params:
  wait: 0.5
  laps: 1
  label: start
  flag: true
run:
  backend: {backend}
  tick_hz: 10
  max_duration: 20
  seed: 3
{extra}
root:
  Sequence:
    name: main
    memory: true
    children:
      - SetBlackboard: {{key: label, value: "${{label}}"}}
      - Wait: {{seconds: "${{wait}}"}}
"""


@pytest.fixture(autouse=True)
def _clean() -> None:
    clean_state()


def _mission(tmp_path: Path, backend: str = "sim", extra: str = "") -> Path:
    path = tmp_path / "m.yaml"
    path.write_text(MISSION.format(backend=backend, extra=extra), encoding="utf-8")
    return path


class _Recorded:
    """A backend factory that records the options it was given and hands out a clock robot."""

    def __init__(self) -> None:
        self.options: list[dict[str, Any]] = []
        self.robots: list[ClockRobot] = []

    def __call__(self, options: dict[str, Any]) -> ClockRobot:
        self.options.append(dict(options))
        robot = ClockRobot()
        self.robots.append(robot)
        return robot


def _plugins_with_fake() -> tuple[Any, _Recorded]:
    plugins = load_plugins(autoload=False)
    fake = _Recorded()
    plugins.backends["fake"] = fake
    return plugins, fake


# -- --set ---------------------------------------------------------------------------------------------


def _load(path: Path, given: dict[str, Any]) -> Any:
    return load_mission(path, load_plugins(autoload=False).nodes, params=given)


def _param(spec: Any, name: str) -> Any:
    """The value the mission's Wait/SetBlackboard nodes got for ``name`` (through ${name})."""
    nodes = {node.type: node for node in spec.nodes()}
    return {"wait": nodes["Wait"].raw["seconds"], "label": nodes["SetBlackboard"].raw["value"]}[name]


def test_set_values_take_the_type_of_the_default(tmp_path: Path) -> None:
    """--set text is read as YAML and held to the default's type; text stays text as typed."""
    path = _mission(tmp_path)
    spec = _load(path, {"wait": "2", "laps": "3", "label": "red backpack", "flag": "false"})
    assert _param(spec, "wait") == 2.0 and isinstance(_param(spec, "wait"), float)
    assert _param(spec, "label") == "red backpack"
    assert _param(_load(path, {"label": "3"}), "label") == "3"


@pytest.mark.parametrize(("given", "words", "line"), [
    ({"lap": "3"}, "params.lap: --set lap: the mission declares no parameter 'lap'; did you mean 'laps'?", 2),
    ({"laps": "two"}, "params.laps: --set laps: expected a whole number (the default is 1), found 'two'", 4),
    ({"laps": "2.5"}, "params.laps: --set laps: expected a whole number", 4),
    ({"flag": "maybe"}, "params.flag: --set flag: expected a true/false", 6),
])
def test_a_bad_set_is_a_problem_at_the_param_with_its_position(tmp_path: Path, given: dict[str, str],
                                                               words: str, line: int) -> None:
    """A bad --set value is a problem while loading, at params.<name> with file:line:col, params listed."""
    with pytest.raises(MissionFileError) as caught:
        _load(_mission(tmp_path), given)
    text = str(caught.value)
    assert f"m.yaml:{line}:" in text and words in text
    assert "wait=0.5 (number), laps=1 (whole number), label=start (text), flag=true (true/false)" in text


def test_set_replaces_the_default_in_the_run(tmp_path: Path) -> None:
    plugins, fake = _plugins_with_fake()
    request = MissionRequest(mission=_mission(tmp_path, backend="fake"),
                             params={"wait": "1.5", "label": "x y"}, out=tmp_path / "run", plugins=plugins,
                             handle_signals=False)
    result = run_mission(request)
    assert result.status.name == "SUCCESS"
    assert result.duration == pytest.approx(1.5, abs=0.11)  # waited 1.5 s, not the default 0.5 s
    log = (tmp_path / "run" / "ticks.jsonl").read_text()
    assert '"label":"x y"' in log


def test_a_set_value_a_node_cannot_take_is_reported_at_its_line(tmp_path: Path) -> None:
    """A value of the right kind for the default but wrong for the port that reads it: located problem."""
    plugins, _ = _plugins_with_fake()
    request = MissionRequest(mission=_mission(tmp_path, backend="fake"), params={"wait": "-4"},
                             plugins=plugins, handle_signals=False)
    with pytest.raises(MissionFileError) as caught:
        Session.open(request)
    assert "m.yaml:" in str(caught.value)


def test_cli_set_with_an_unknown_key_exits_two(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["run", str(_mission(tmp_path)), "--set", "lapz=3", "--quiet", "--no-plugins"]) == 2
    err = capsys.readouterr().err
    assert "no parameter 'lapz'" in err and "laps=1 (whole number)" in err
    assert "Traceback" not in err


def test_cli_set_without_equals_exits_two(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["run", str(_mission(tmp_path)), "--set", "laps", "--no-plugins"]) == 2
    assert "--set expects key=value" in capsys.readouterr().err


def test_run_help_says_the_run_section_supplies_the_defaults(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        main(["run", "--help"])
    out = capsys.readouterr().out
    assert "`run:` section supplies the defaults" in " ".join(out.split())
    assert "--set KEY=VALUE" in out and "--unknown-map" in out and "--quiet" in out


# -- wiring ----------------------------------------------------------------------------------------------


def test_flags_override_the_run_section_which_overrides_defaults(tmp_path: Path) -> None:
    plugins, fake = _plugins_with_fake()
    path = _mission(tmp_path, backend="fake")
    with Session.open(MissionRequest(mission=path, plugins=plugins, out=tmp_path / "a")) as session:
        assert (session.settings["seed"], session.settings["tick_hz"]) == (3, 10.0)  # from run:
        assert session.settings["realtime"] is False  # the default
    with Session.open(MissionRequest(mission=path, plugins=plugins, seed=9, tick_hz=20,
                                     out=tmp_path / "b")) as session:
        assert (session.settings["seed"], session.settings["tick_hz"]) == (9, 20.0)
    assert [o["seed"] for o in fake.options] == [3, 9]
    assert all(robot.closed for robot in fake.robots)


def test_the_session_binds_the_model_caller_before_any_leaf_is_set_up(tmp_path: Path) -> None:
    """Once open, the context holds the mission's caller (paced as the run is) and its typed models."""
    from missiontree.reasoning.calls import ModelCaller
    from missiontree.reasoning.models import Models

    plugins, _ = _plugins_with_fake()
    request = MissionRequest(mission=_mission(tmp_path, backend="fake"), plugins=plugins, out=tmp_path / "a",
                             realtime=True)
    with Session.open(request) as session:
        assert isinstance(session.models, Models) and session.context.models is session.models
        calls = session.context.calls
        assert isinstance(calls, ModelCaller) and session.models.caller is calls
        assert calls.realtime is True


@pytest.mark.parametrize(("extra", "flag", "expected"), [
    ("  map: unknown", None, True), ("  map: known", None, False), ("", True, True),
    ("  map: known", True, True), ("", None, False),
])
def test_unknown_map_reaches_the_backend(tmp_path: Path, extra: str, flag: bool | None,
                                         expected: bool) -> None:
    plugins, fake = _plugins_with_fake()
    request = MissionRequest(mission=_mission(tmp_path, backend="fake", extra=extra), unknown_map=flag,
                             plugins=plugins, out=tmp_path / "run")
    with Session.open(request):
        pass
    assert fake.options[0].get("unknown_map", False) is expected


def test_a_bad_map_value_in_the_run_section_is_a_located_problem(tmp_path: Path) -> None:
    plugins, _ = _plugins_with_fake()
    with pytest.raises(MissionFileError) as caught:
        Session.open(MissionRequest(mission=_mission(tmp_path, backend="fake", extra="  map: partial"),
                                    plugins=plugins))
    assert "m.yaml:" in str(caught.value) and "map" in str(caught.value)


def test_on_tick_sees_the_robot_between_ticks(tmp_path: Path) -> None:
    plugins, _ = _plugins_with_fake()
    seen: list[float] = []
    request = MissionRequest(mission=_mission(tmp_path, backend="fake"), plugins=plugins,
                             out=tmp_path / "run", on_tick=lambda session: seen.append(session.robot.now()))
    result = run_mission(request)
    assert len(seen) == result.ticks and seen[:3] == pytest.approx([0.0, 0.1, 0.2])


def test_what_the_session_opened_is_frozen_for_the_run_and_unfrozen_after(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """In a process the application tuned, the run's heap is frozen during the run only."""
    monkeypatch.setattr(process, "_tuned", True)  # as tune_process() leaves it, without pinning glibc
    plugins, _ = _plugins_with_fake()
    frozen: list[int] = []
    request = MissionRequest(mission=_mission(tmp_path, backend="fake"), plugins=plugins,
                             out=tmp_path / "run", on_tick=lambda _: frozen.append(gc.get_freeze_count()))
    before = gc.get_freeze_count()
    run_mission(request)
    assert frozen and min(frozen) > before  # full collections skip the session's objects during the run
    assert gc.get_freeze_count() == before  # and a batch worker's next mission starts unfrozen


def test_a_process_nobody_tuned_keeps_its_garbage_collector_as_it_was(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Library use alone (no tune_process) leaves the process's settings alone: nothing frozen."""
    monkeypatch.setattr(process, "_tuned", False)  # as in a program that only imports missiontree
    plugins, _ = _plugins_with_fake()
    frozen: list[int] = []
    request = MissionRequest(mission=_mission(tmp_path, backend="fake"), plugins=plugins,
                             out=tmp_path / "run", on_tick=lambda _: frozen.append(gc.get_freeze_count()))
    before = gc.get_freeze_count()
    run_mission(request)
    assert frozen and set(frozen) == {before}


def test_a_missing_models_config_is_a_problem_before_any_robot_is_built(tmp_path: Path) -> None:
    plugins, fake = _plugins_with_fake()
    with pytest.raises(MissionFileError, match="missing_models.yaml' does not exist"):
        Session.open(MissionRequest(mission=_mission(tmp_path, backend="fake"), plugins=plugins,
                                    models=tmp_path / "missing_models.yaml"))
    assert fake.robots == []


def test_the_robot_is_closed_when_wiring_fails(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    def failing_build(*args: Any, **kwargs: Any) -> Any:
        raise ConfigError("the models cannot be built")

    monkeypatch.setattr("missiontree.session.mission.build_models", failing_build)
    plugins, fake = _plugins_with_fake()
    with pytest.raises(ConfigError, match="cannot be built"):
        Session.open(MissionRequest(mission=_mission(tmp_path, backend="fake"), plugins=plugins))
    assert fake.robots and fake.robots[0].closed


def test_summary_records_the_final_and_the_true_pose_on_the_simulator(tmp_path: Path) -> None:
    mission = tmp_path / "drive.yaml"
    mission.write_text("version: 1\nrun: {backend: sim, world: office, max_duration: 3}\n"
                       "root:\n  Rotate: {angle: 1.0}\n", encoding="utf-8")
    result = run_mission(MissionRequest(mission=mission, out=tmp_path / "run",
                                        plugins=load_plugins(autoload=False), handle_signals=False))
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary == result.summary
    assert set(summary["final_pose"]) == {"x", "y", "yaw", "stamp"}
    assert set(summary["true_final_pose"]) == {"x", "y", "yaw"}
    assert summary["bumps"]["contacts"] == 0 and summary["bumps"]["where"] == []  # turning touches nothing
    assert summary["final_pose"]["yaw"] != 0.0  # it turned


# -- progress line ---------------------------------------------------------------------------------------


class _Clock:
    def __init__(self) -> None:
        self.t = 100.0

    def __call__(self) -> float:
        return self.t


def test_plain_progress_lines_every_interval(tmp_path: Path) -> None:
    plugins, _ = _plugins_with_fake()
    stream = io.StringIO()
    wall = _Clock()
    progress = ProgressLine("m", stream, tty=False, interval=10.0, wall=wall)
    session = Session.open(MissionRequest(mission=_mission(tmp_path, backend="fake"), plugins=plugins,
                                          out=tmp_path / "run"))
    with session:
        runner = session.runner
        runner.setup()
        progress.update(runner)           # first call: starts the clocks, writes nothing
        assert stream.getvalue() == ""
        runner.tick()
        session.robot.spin_until(5.0)
        wall.t += 4.0
        progress.update(runner)           # 4 s of wall time: not yet
        assert stream.getvalue() == ""
        wall.t += 6.0
        progress.update(runner)
    line = stream.getvalue()
    assert line.endswith("\n") and line.count("\n") == 1
    assert "t=5.0 s" in line and "0.5x real time" in line and "root RUNNING" in line
    assert "last:" not in line or "last: " in line


def test_terminal_progress_redraws_one_line() -> None:
    stream = io.StringIO()
    wall = _Clock()
    progress = ProgressLine("m", stream, tty=True, interval=0.2, wall=wall)

    class _Runner:
        robot = ClockRobot()
        recorder = None
        log = type("L", (), {"last_event": "goal_sent (main/go)"})()
        root = type("R", (), {"status": type("S", (), {"name": "RUNNING"})()})()

    runner = _Runner()
    progress.update(runner)
    for step in range(3):
        wall.t += 0.5
        runner.robot.spin_until((step + 1) * 5.0)
        progress.update(runner)
    progress.close()
    text = stream.getvalue()
    assert "\n" not in text and text.count("\r") == 5  # three redraws, then the clearing (two)
    assert "last: goal_sent (main/go)" in text and "10.0x real time" in text


def test_quiet_cli_run_writes_no_progress(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = _mission(tmp_path)
    assert main(["run", str(path), "--quiet", "--out", str(tmp_path / "run"), "--no-plugins"]) == 0
    captured = capsys.readouterr()
    assert captured.err == ""
    assert "m: SUCCESS" in captured.out


def test_request_substitute_stubs_nodes_and_the_summary_lists_them(tmp_path: Path) -> None:
    """`MissionRequest(substitute=...)`: the session swaps matched nodes for stubs; summary.json says so."""
    plugins, _ = _plugins_with_fake()
    rules = tmp_path / "rules.yaml"
    rules.write_text("rules:\n  - match: Wait\n    status: SUCCESS\n", encoding="utf-8")
    request = MissionRequest(mission=_mission(tmp_path, backend="fake"), out=tmp_path / "run",
                             plugins=plugins, handle_signals=False, substitute=rules)
    result = run_mission(request)
    assert result.status.name == "SUCCESS"
    assert result.duration < 0.5  # the stub ended at once; the real Wait takes 0.5 s
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert [(s["node"], s["type"]) for s in summary["substitutions"]] == [("main/Wait", "Wait")]


def test_a_bad_rules_file_is_refused_before_the_robot_starts(tmp_path: Path) -> None:
    """A rules file with a bad rule is a located problem and no robot is built."""
    plugins, fake = _plugins_with_fake()
    rules = tmp_path / "rules.yaml"
    rules.write_text("rules:\n  - match: Wait\n    status: MAYBE\n", encoding="utf-8")
    request = MissionRequest(mission=_mission(tmp_path, backend="fake"), plugins=plugins,
                             handle_signals=False, substitute=rules)
    with pytest.raises(MissionFileError) as caught:
        Session.open(request)
    assert "rules.yaml:3" in str(caught.value)
    assert fake.robots == []
