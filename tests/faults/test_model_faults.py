"""Fault injection on the models: every call failing ends the mission FAILURE with the reason.

The faults: a server that hangs, answers 429/500, garbage or huge bodies, or malformed answers.

The server is the OpenAI-compatible fake on loopback (tests/reasoning/fake_openai_server.py), reached
by the real ``openai`` provider through the session, on the simulator.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
from conftest import FaultyRobot, assert_clean_end, faulty_plugins, read_lines
from fake_openai_server import FakeOpenAIServer, Reply

from missiontree.cli.main import main
from missiontree.session import MissionRequest, run_mission

pytest.importorskip("openai")

KEY = "sk-test-SECRET0123456789abcdefXYZ"

WATCH = """\
version: 1
run: {{backend: faulty, world: combined, tick_hz: 10, max_duration: 120, seed: 1{models}}}
root:
  Parallel:
    name: watch_a_while
    policy: success_on_all
    children:
      - Wait: {{seconds: 60}}
      - Surveillance: {{name: surveillance, mode: poll, period: 0.5, max_failed_calls: 3}}
"""


def _models(url: str) -> dict[str, Any]:
    return {"roles": {"detector": {"provider": "sim_detector"},
                      "vlm": {"provider": "openai", "model": "test-model", "base_url": url,
                              "api_key_env": "MT_FAULT_KEY", "timeout": 0.5, "max_retries": 0}}}


FAULTS = {
    "hangs": Reply.text("late", delay=3.0),
    "429": Reply.error(429, "rate limited", **{"Retry-After": "0"}),
    "500": Reply.error(500, "upstream exploded"),
    "garbage": Reply.not_json(),
    "huge": Reply(status=200, body="{" + "x" * 4_000_000),
    "malformed": Reply.text("I think everything is fine, no JSON here"),
}


@pytest.mark.parametrize("fault", sorted(FAULTS))
def test_every_model_call_failing_fails_the_mission(fault: str, tmp_path: Path,
                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    """3 failed VLM calls in a row: Surveillance fails, so the mission does, saying why."""
    monkeypatch.setenv("MT_FAULT_KEY", KEY)
    mission = tmp_path / "watch.yaml"
    mission.write_text(WATCH.format(models=""), encoding="utf-8")
    made: list[FaultyRobot] = []
    out = tmp_path / "run"
    with FakeOpenAIServer(default=FAULTS[fault]) as server:
        result = run_mission(MissionRequest(mission=mission, out=out, models=_models(server.url),
                                            plugins=faulty_plugins(made)))
        assert server.chat_requests(), "the model server was never asked"
    assert result.exit_code == 1
    robot = made[0]
    summary = assert_clean_end(out, why="3 vlm calls in a row failed",
                               stopped=lambda: robot.stop_calls >= 1 and robot._robot._base.cmd_v == 0.0)
    assert summary["status"] == "FAILURE" and summary["duration"] < 60.0
    calls = [e for e in read_lines(out / "ticks.jsonl") if e.get("event") == "model_call"]
    assert len(calls) >= 3 and not any(c.get("ok") for c in calls), calls[:3]


def test_an_answer_reflecting_the_key_is_scrubbed_end_to_end(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                             capsys: pytest.CaptureFixture[str]) -> None:
    """`missiontree run`, the key in answers: alarms.jsonl, ticks.jsonl, stdout, stderr hold none of it."""
    import yaml

    from missiontree.plugins import manager

    monkeypatch.setenv("MT_FAULT_KEY", KEY)
    monkeypatch.setattr(manager, "discover_entry_points", lambda: [])
    verdict = json.dumps({"verdict": "ALARM", "description": f"intruder; my key is {KEY}", "people": []})
    with FakeOpenAIServer() as server:
        server.script(Reply.text(f"not json, but the key {KEY} and {KEY[4:20]}"),
                      *[Reply.text(verdict) for _ in range(400)])
        models = tmp_path / "models.yaml"
        models.write_text(yaml.safe_dump(_models(server.url)), encoding="utf-8")
        mission = tmp_path / "watch.yaml"
        text = WATCH.format(models=f", models: {models}").replace("faulty", "sim")
        text = text.replace("seconds: 60", "seconds: 6").replace("success_on_all", "success_on_one")
        mission.write_text(text, encoding="utf-8")
        out = tmp_path / "run"
        code = main(["run", str(mission), "--out", str(out), "--quiet"])
    captured = capsys.readouterr()
    assert code == 0, captured
    alarms = (out / "alarms.jsonl").read_text(encoding="utf-8")
    ticks = (out / "ticks.jsonl").read_text(encoding="utf-8")
    assert "intruder; my key is ***" in alarms  # the alarm is kept, the key is not
    assert "model_answer_rejected" in captured.out  # the warning is shown, scrubbed
    for where, text in {"alarms.jsonl": alarms, "ticks.jsonl": ticks, "stdout": captured.out,
                        "stderr": captured.err, "summary.json": (out / "summary.json").read_text()}.items():
        assert KEY not in text and KEY[4:20] not in text and "SECRET" not in text, where


def test_the_key_in_any_form_reaches_no_output(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    """`missiontree run`, the key split, base64-encoded, reversed, upper-cased: no output holds 8 of it."""
    import base64

    import yaml

    from missiontree.plugins import manager

    monkeypatch.setenv("MT_FAULT_KEY", KEY)
    monkeypatch.setattr(manager, "discover_entry_points", lambda: [])
    forms = [" ".join(KEY[i:i + 6] for i in range(0, len(KEY), 6)), base64.b64encode(KEY.encode()).decode(),
             KEY[::-1], KEY.upper()]
    verdicts = [json.dumps({"verdict": "ALARM", "description": f"intruder; {form}", "people": []})
                for form in forms]
    with FakeOpenAIServer() as server:
        server.script(*[Reply.text(f"not json: {form}") for form in forms],
                      *[Reply.text(verdicts[i % len(verdicts)]) for i in range(400)])
        models = tmp_path / "models.yaml"
        models.write_text(yaml.safe_dump(_models(server.url)), encoding="utf-8")
        mission = tmp_path / "watch.yaml"
        text = WATCH.format(models=f", models: {models}").replace("faulty", "sim")
        text = text.replace("seconds: 60", "seconds: 6").replace("max_failed_calls: 3", "max_failed_calls: 9")
        mission.write_text(text, encoding="utf-8")
        out = tmp_path / "run"
        main(["run", str(mission), "--out", str(out)])
    captured = capsys.readouterr()
    letters = "".join(c for c in KEY.lower() if c.isalnum())
    runs = {text[i:i + 8] for text in (letters, letters[::-1]) for i in range(len(letters) - 7)}
    for where, found in {"ticks.jsonl": (out / "ticks.jsonl").read_text(encoding="utf-8"),
                         "summary.json": (out / "summary.json").read_text(encoding="utf-8"),
                         "alarms.jsonl": (out / "alarms.jsonl").read_text(encoding="utf-8"),
                         "stdout": captured.out, "stderr": captured.err}.items():
        compact = "".join(c for c in found.lower() if c.isalnum())
        assert not [r for r in runs if r in compact], where
        assert base64.b64encode(KEY.encode()).decode()[:12] not in found, where
