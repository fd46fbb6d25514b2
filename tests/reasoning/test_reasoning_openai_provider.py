"""Tests of the OpenAI-compatible provider against the scripted loopback server."""

from __future__ import annotations

import base64
import json
import logging
import socket
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from fake_openai_server import FakeOpenAIServer as Fake
from fake_openai_server import Reply

from missiontree.errors import ModelConfigError, ModelError, ModelTimeoutError
from missiontree.reasoning.checks import RejectedAnswerError, ask_checked, chat_checked
from missiontree.reasoning.prompts import intent_messages, surveillance_prompt
from missiontree.reasoning.providers.openai import OpenAIChatModel
from missiontree.reasoning.schemas import IntentResolution, SurveillanceVerdict
from missiontree.redact import forget_secrets

KEY = "sk-test-0123456789abcdefSECRET"

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "behaviours"))  # the behaviour test doubles


@pytest.fixture
def server(monkeypatch: pytest.MonkeyPatch) -> Iterator[Fake]:
    forget_secrets()  # only this test's key is scrubbed
    monkeypatch.setenv("MT_TEST_KEY", KEY)
    with Fake(api_key=KEY) as fake:
        yield fake


def provider(server: Fake, **options: object) -> OpenAIChatModel:
    model = OpenAIChatModel.from_options({
        "model": "test-model", "base_url": server.url, "api_key_env": "MT_TEST_KEY", "timeout": 2.0,
        "backoff": 0.01, **options})
    model.sleeps = []  # type: ignore[attr-defined]
    model.sleep = model.sleeps.append  # type: ignore[attr-defined, method-assign]
    return model


def image() -> np.ndarray:
    picture = np.zeros((24, 32, 3), dtype=np.uint8)
    picture[:, :16] = (200, 30, 30)
    return picture


def test_image_sent_as_base64_data_url_with_json_schema(server: Fake) -> None:
    """ask() sends the image as a base64 JPEG data URL and asks for the schema as response_format."""
    server.script(Reply.text('{"verdict": "SAFE", "description": "An empty corridor."}'))
    vlm = provider(server)
    answer = vlm.ask([image()], surveillance_prompt(), SurveillanceVerdict)
    assert SurveillanceVerdict.model_validate_json(answer).verdict == "SAFE"
    request = server.chat_requests()[0]
    parts = request["messages"][0]["content"]
    url = parts[1]["image_url"]["url"]
    assert url.startswith("data:image/jpeg;base64,")
    assert base64.b64decode(url.split(",", 1)[1])[:2] == b"\xff\xd8"  # JPEG magic
    assert request["response_format"]["type"] == "json_schema"
    assert request["response_format"]["json_schema"]["name"] == "SurveillanceVerdict"
    assert server.requests[0]["headers"]["authorization"] == f"Bearer {KEY}"


def test_png_images_when_configured(server: Fake) -> None:
    """image_format: png sends PNG data URLs."""
    vlm = provider(server, image_format="png")
    vlm.ask([image()], "what is this?")
    url = server.chat_requests()[0]["messages"][0]["content"][1]["image_url"]["url"]
    assert base64.b64decode(url.split(",", 1)[1])[:4] == b"\x89PNG"


def test_429_and_500_are_retried_with_backoff(server: Fake) -> None:
    """A 429 then a 500 are retried with doubling backoff (Retry-After honoured), then the answer arrives."""
    server.script(Reply.error(429, "slow down", **{"Retry-After": "0.05"}), Reply.error(500),
                  Reply.text("ok"))
    vlm = provider(server)
    assert vlm.ask([image()], "hi") == "ok"
    assert len(server.chat_requests()) == 3
    assert vlm.sleeps == [0.05, 0.02]  # type: ignore[attr-defined]


def test_retries_give_up_with_the_status_and_fix(server: Fake) -> None:
    """After max_retries the error names the provider, the HTTP status and the attempts."""
    server.script(*[Reply.error(503, "overloaded")] * 3)
    vlm = provider(server, max_retries=2)
    with pytest.raises(ModelError, match=r"openai: chat at .* failed with HTTP 503 after 3 attempts"):
        vlm.ask([image()], "hi")


def test_slow_server_times_out(server: Fake) -> None:
    """A server slower than the timeout raises ModelTimeoutError naming the provider and the fix."""
    server.script(Reply.text("late", delay=1.0))
    vlm = provider(server, timeout=0.2)
    with pytest.raises(ModelTimeoutError, match="took longer than 0.2 s; raise timeout"):
        vlm.ask([image()], "hi")


def test_rejected_key_error_and_logs_never_hold_the_key(
        server: Fake, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture) -> None:
    """A 401 says the key was rejected and which variable to fix; neither error nor logs contain the key."""
    monkeypatch.setenv("MT_TEST_KEY", "sk-wrong-key-ABCDEFGH12345678")
    vlm = OpenAIChatModel.from_options({"model": "test-model", "base_url": server.url,
                                        "api_key_env": "MT_TEST_KEY"})
    caplog.set_level(logging.DEBUG)
    with pytest.raises(ModelError) as failure:
        vlm.ask([image()], "hi")
    text = str(failure.value)
    assert "rejected the API key (HTTP 401)" in text and "set MT_TEST_KEY" in text
    assert "ABCDEFGH" not in text and "5678" not in text and "sk-" not in text
    assert "ABCDEFGH12345678" not in caplog.text
    assert "ABCDEFGH" not in repr(vlm)


def test_key_absent_from_logs_on_success(server: Fake, caplog: pytest.LogCaptureFixture) -> None:
    """With debug logging of the client and httpx switched on, a successful call logs no key."""
    caplog.set_level(logging.DEBUG)
    vlm = provider(server)
    vlm.ask([image()], "hi")
    assert caplog.records  # the client did log something
    assert KEY not in caplog.text and "SECRET" not in caplog.text


def test_missing_key_variable_is_a_config_error(monkeypatch: pytest.MonkeyPatch) -> None:
    """An unset key variable is a ModelConfigError naming the variable and the fix."""
    monkeypatch.delenv("MT_NO_SUCH_KEY", raising=False)
    with pytest.raises(ModelConfigError, match="MT_NO_SUCH_KEY .* is not set; export MT_NO_SUCH_KEY"):
        OpenAIChatModel.from_options({"model": "m", "api_key_env": "MT_NO_SUCH_KEY"})


def test_unknown_option_is_a_config_error() -> None:
    """A misspelt option is refused with the known options listed."""
    with pytest.raises(ModelConfigError, match="timout.*known options: model, base_url"):
        OpenAIChatModel.from_options({"model": "m", "api_key_env": None, "timout": 3})


def test_unreachable_server_names_the_url_and_fix() -> None:
    """A server nobody listens on gives an error naming the URL and how to fix it."""
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    url = f"http://127.0.0.1:{port}/v1"
    vlm = OpenAIChatModel.from_options({"model": "m", "api_key_env": None, "base_url": url, "timeout": 2.0})
    with pytest.raises(ModelError, match=rf"cannot reach the server at {url} .*start the server"):
        vlm.ask([image()], "hi")


def test_body_that_is_not_json_fails_clearly(server: Fake) -> None:
    """A 200 answer whose body is not JSON fails with a ModelError, not a bare traceback."""
    server.script(Reply.not_json())
    vlm = provider(server)
    with pytest.raises(ModelError, match="openai"):
        vlm.ask([image()], "hi")


def test_malformed_answer_retried_once_with_error_fed_back(server: Fake) -> None:
    """Malformed JSON is rejected, the reason is fed back, and the second (valid) answer is used."""
    server.script(Reply.text('{"verdict": "ALARM", '),
                  Reply.text('{"verdict": "ALARM", "description": "a man"}'))
    vlm = provider(server)
    answer = ask_checked(vlm, [image()], surveillance_prompt(), SurveillanceVerdict)
    assert answer.value.alarm and answer.attempts == 2
    second_prompt = server.chat_requests()[1]["messages"][0]["content"][0]["text"]
    assert "Your previous answer was rejected: expected a JSON object" in second_prompt


def test_wrong_schema_twice_fails_with_reason(server: Fake) -> None:
    """An answer of the wrong shape twice raises RejectedAnswerError with the validation reason."""
    server.script(Reply.text('{"status": "fine"}'), Reply.text('{"verdict": "MAYBE"}'))
    vlm = provider(server)
    with pytest.raises(RejectedAnswerError, match="rejected 2 times.*verdict") as failure:
        ask_checked(vlm, [image()], surveillance_prompt(), SurveillanceVerdict)
    assert failure.value.attempts == 2 and len(failure.value.rejected) == 2
    assert len(server.chat_requests()) == 2


def test_hallucinated_ids_rejected_then_corrected(server: Fake) -> None:
    """An answer naming an object id not in the scene is rejected; the retry sees the valid ids."""
    objects = [{"id": "cup_1", "label": "cup"}, {"id": "sofa_2", "label": "sofa"}]
    server.script(Reply.text('{"candidates": ["fridge_9"]}'), Reply.text('{"candidates": ["cup_1"]}'))
    llm = provider(server)
    answer = chat_checked(llm, intent_messages("I am thirsty", objects), IntentResolution,
                          valid_ids={"cup_1", "sofa_2"})
    assert answer.value.candidates == ["cup_1"]
    assert "fridge_9" in answer.rejected[0]
    retry = server.chat_requests()[1]["messages"]
    assert retry[-2] == {"role": "assistant", "content": '{"candidates": ["fridge_9"]}'}
    assert "do not exist: ['fridge_9']" in retry[-1]["content"] and "cup_1" in retry[-1]["content"]


def test_check_pings_the_server(server: Fake) -> None:
    """check() lists the served models."""
    vlm = provider(server)
    assert "test-model at http://127.0.0.1" in vlm.check()
    assert server.requests[-1]["path"].endswith("/models")


def test_empty_image_names_provider_and_fix(server: Fake) -> None:
    """An empty image is refused before any request, naming the provider and the fix."""
    vlm = provider(server)
    with pytest.raises(ValueError, match="openai: expected a non-empty HxWx3 image"):
        vlm.ask([np.zeros((0, 10, 3), dtype=np.uint8)], "hi")
    with pytest.raises(ValueError, match="openai: expected an HxWx3 RGB image, found shape"):
        vlm.ask([np.zeros((4, 4, 2), dtype=np.uint8)], "hi")
    assert server.chat_requests() == []


def test_json_object_mode_for_servers_without_schemas(server: Fake) -> None:
    """structured: json_object asks for a JSON object and puts the schema in a system message."""
    vlm = provider(server, structured="json_object")
    vlm.ask([image()], "look", SurveillanceVerdict)
    request = server.chat_requests()[0]
    assert request["response_format"] == {"type": "json_object"}
    assert request["messages"][0]["role"] == "system" and "verdict" in request["messages"][0]["content"]


def test_chat_sends_roles_and_images(server: Fake) -> None:
    """chat() keeps the roles and sends a message's images as data URLs."""
    from missiontree.reasoning.protocols import Message

    llm = provider(server)
    llm.chat([Message("system", "be brief"), Message("user", "what is this?", (image(),))])
    messages = server.chat_requests()[0]["messages"]
    assert messages[0] == {"role": "system", "content": "be brief"}
    assert messages[1]["content"][1]["image_url"]["url"].startswith("data:image/jpeg;base64,")
    assert "response_format" not in server.chat_requests()[0]


# -- answers that reflect the key -------------------------------------------------------------------

def test_an_answer_reflecting_the_key_is_scrubbed_at_the_provider(server: Fake) -> None:
    """The key, whole or a 12-character run of it, never leaves the provider in an answer."""
    server.script(Reply.text(f"my key is {KEY} and again {KEY[5:22]}!"), Reply.text("short sk-test ok"))
    vlm = provider(server)
    answer = vlm.ask([image()], "what is your key?")
    assert KEY not in answer and KEY[5:22] not in answer and "SECRET" not in answer
    assert answer.startswith("my key is ***") and answer.endswith("!")
    assert vlm.ask([image()], "hi") == "short sk-test ok"  # a few characters in common are just text


def test_a_reflected_key_reaches_no_alarm_tick_log_or_warning(server: Fake, tmp_path: Path) -> None:
    """Through a real Surveillance run: alarms.jsonl, the events and the rejection warning hold no key."""
    import structlog
    from patrol_doubles import Events, FakeRobot, person_frame

    from missiontree.behaviours.surveillance import Surveillance
    from missiontree.engine.context import MissionContext
    from missiontree.reasoning.calls import CALLER_KEY, ModelCaller

    verdict = json.dumps({"verdict": "ALARM", "description": f"the key is {KEY}", "people": []})
    server.script(Reply.text(f"not json, but {KEY}"), Reply.text(verdict))
    robot, events = FakeRobot(), Events()
    models: dict = {"vlm": provider(server)}
    models[CALLER_KEY] = ModelCaller(robot.now, events, simulated=False, models=models)
    leaf = Surveillance("watch", Surveillance.Params(mode="poll", period=0.5, lidar_check=False))
    leaf.setup(context=MissionContext(robot=robot, models=models, events=events, run_dir=tmp_path))
    with structlog.testing.capture_logs() as logs:
        for _ in range(40):
            robot.advance(0.1)
            robot.frame = person_frame(robot.time, robot.current, 0.0)
            leaf.tick_once()
            if events.of("alarm"):
                break
            time.sleep(0.02)
    assert events.of("alarm"), events.items
    assert any(entry.get("event") == "model_answer_rejected" for entry in logs)
    for text in (json.dumps(events.items), (tmp_path / "alarms.jsonl").read_text(), repr(logs)):
        assert KEY not in text and "SECRET" not in text
    assert "the key is ***" in (tmp_path / "alarms.jsonl").read_text()


# -- the role's timeout is the HTTP timeout ---------------------------------------------------------

def test_the_roles_timeout_reaches_the_http_client(server: Fake) -> None:
    """A role's `timeout: 0.3` in the models config: a hanging server times out after ~0.3 s, not 30 s."""
    from missiontree.plugins.manager import load_plugins
    from missiontree.session.models import build_models

    config = {"roles": {"vlm": {"provider": "openai", "model": "test-model", "base_url": server.url,
                                "api_key_env": "MT_TEST_KEY", "timeout": 0.3}}}
    models = build_models(config, load_plugins(autoload=False).providers)
    vlm = models["vlm"]
    assert vlm.timeout == 0.3
    server.script(Reply.text("late", delay=3.0))
    start = time.monotonic()
    with pytest.raises(ModelTimeoutError, match="longer than 0.3 s"):
        vlm.ask([image()], "hi")
    assert time.monotonic() - start < 2.0


def test_without_a_role_timeout_the_calls_default_is_used(server: Fake) -> None:
    """No role timeout: the HTTP timeout is `calls: timeout:` (what `missiontree models` shows)."""
    from missiontree.plugins.manager import load_plugins
    from missiontree.session.models import build_models

    config = {"roles": {"vlm": {"provider": "openai", "model": "test-model", "base_url": server.url,
                                "api_key_env": "MT_TEST_KEY"}},
              "calls": {"timeout": 7}}
    assert build_models(config, load_plugins(autoload=False).providers)["vlm"].timeout == 7.0


def test_a_hanging_server_does_not_freeze_a_simulated_patrol_watch(server: Fake) -> None:
    """A server that never answers in time: each call ends at the role's timeout, then the leaf fails."""
    from patrol_doubles import Events, FakeRobot, person_frame

    from missiontree.behaviours.surveillance import Surveillance
    from missiontree.engine.context import MissionContext
    from missiontree.engine.leaf import Status
    from missiontree.plugins.manager import load_plugins
    from missiontree.reasoning.calls import CALLER_KEY, LatencyModel, ModelCaller
    from missiontree.session.models import build_models

    config = {"roles": {"vlm": {"provider": "openai", "model": "test-model", "base_url": server.url,
                                "api_key_env": "MT_TEST_KEY", "timeout": 0.3, "max_retries": 0}}}
    models = build_models(config, load_plugins(autoload=False).providers)
    server.script(*[Reply.text("late", delay=30.0) for _ in range(10)])
    robot, events = FakeRobot(), Events()
    caller = ModelCaller(robot.now, events, simulated=True, models=models, timeouts={"vlm": 0.3},
                         latency={"vlm": LatencyModel(0.2, 0.2)})
    models[CALLER_KEY] = caller
    leaf = Surveillance("watch", Surveillance.Params(mode="poll", period=0.5, max_failed_calls=3))
    leaf.setup(context=MissionContext(robot=robot, models=models, events=events))
    start = time.monotonic()
    try:
        for _ in range(100):
            robot.advance(0.1)
            robot.frame = person_frame(robot.time, robot.current, 0.0)
            leaf.tick_once()
            if leaf.status != Status.RUNNING:
                break
    finally:
        caller.close()
    assert leaf.status == Status.FAILURE and "3 vlm calls in a row failed" in leaf.feedback_message
    assert "took longer than 0.3 s" in leaf.feedback_message
    assert time.monotonic() - start < 5.0  # three 0.3 s timeouts, not three 30 s hangs


# -- every form of the key, credentials in base_url, redirects ---------------------------------------

def _runs_of_key(text: str, size: int = 8) -> list[str]:
    """Runs of ``size`` of the key's letters and digits (either direction, any case) found in ``text``."""
    compact = "".join(c for c in text.lower() if c.isalnum())
    found = []
    for candidate in (KEY.lower(), KEY[::-1].lower()):
        letters = "".join(c for c in candidate if c.isalnum())
        found += [run for i in range(len(letters) - size + 1) if (run := letters[i:i + size]) in compact]
    return found


KEY_FORMS = {
    "pieces under 12": " | ".join(KEY[i:i + 7] for i in range(0, len(KEY), 7)),
    "base64": base64.b64encode(f"key={KEY}".encode()).decode(),
    "reversed": KEY[::-1],
    "upper-cased": KEY.upper(),
}


@pytest.mark.parametrize("form", KEY_FORMS)
def test_the_key_in_any_form_is_scrubbed_from_answers(server: Fake, form: str) -> None:
    """Split into short pieces, base64-encoded, reversed or upper-cased, the key never leaves the provider."""
    server.script(Reply.text(f"here you are: {KEY_FORMS[form]} (done)"))
    answer = provider(server).ask([image()], "what is your key?")
    assert answer.startswith("here you are: ") and answer.endswith("(done)")
    assert "***" in answer and not _runs_of_key(answer)
    if form == "base64":
        encoded = answer.split(": ")[1].split(" ")[0]
        assert KEY not in base64.b64decode(encoded + "===", validate=False).decode(errors="replace")


def test_a_400_body_holding_most_of_the_key_is_scrubbed(server: Fake) -> None:
    """An error body with 3 of every 4 key characters (the rest masked) leaves none of them in the error."""
    masked = "".join("*" if i % 4 == 3 else c for i, c in enumerate(KEY))
    server.script(Reply.error(400, f"invalid value '{masked[8:]}' for field auth"))
    with pytest.raises(ModelError) as failure:
        provider(server).ask([image()], "hi")
    text = str(failure.value)
    assert "HTTP 400" in text and "invalid value '***" in text
    assert not any(masked[i:i + 6] in text for i in range(8, len(masked) - 5))


def test_credentials_in_base_url_are_never_shown() -> None:
    """user:password in base_url is in no error, repr or check line; answers holding it are scrubbed."""
    secret = "hunter2-Pa55w0rdXyZ"
    with Fake() as server:
        url = server.url.replace("http://", f"http://operator:{secret}@")
        vlm = OpenAIChatModel.from_options({"model": "test-model", "base_url": url, "api_key_env": None,
                                            "timeout": 2.0})
        _check_url_credentials(server, vlm, url, secret)


def _check_url_credentials(server: Fake, vlm: OpenAIChatModel, url: str, secret: str) -> None:
    assert secret not in repr(vlm) and secret not in vlm.check() and "***@127.0.0.1" in vlm.check()
    server.script(Reply.error(404, f"no route for {url}"), Reply.text(f"I was called at {url}"))
    with pytest.raises(ModelError) as failure:
        vlm.ask([image()], "hi")
    assert secret not in str(failure.value) and "operator" not in str(failure.value)
    assert secret not in vlm.ask([image()], "hi")


def test_a_redirect_to_another_host_is_refused(server: Fake) -> None:
    """A 307 to another server is not followed: the prompt is not re-sent there and its answer not used."""
    with Fake() as elsewhere:
        elsewhere.script(Reply.text("an answer from a server nobody configured"))
        server.script(Reply(status=307, body="", headers={"Location": f"{elsewhere.url}/chat/completions"}))
        with pytest.raises(ModelError, match="redirected .* to another origin.*not followed"):
            provider(server).ask([image()], "hi")
        assert elsewhere.chat_requests() == []


def test_a_redirect_within_the_server_is_followed(server: Fake) -> None:
    """A 307 to another path of the same server is followed."""
    server.script(Reply(status=307, body="", headers={"Location": f"{server.url}/chat/completions"}),
                  Reply.text("ok"))
    assert provider(server).ask([image()], "hi") == "ok"


def test_a_short_password_in_base_url_is_not_echoed_by_an_error_body() -> None:
    """A server echoing the whole URL with a two-letter password: the error shows ***@ instead."""
    forget_secrets()
    with Fake() as server:
        url = server.url.replace("http://", "http://u:pw@")
        server.script(Reply.error(404, f"no such route {url}/chat/completions"))
        vlm = OpenAIChatModel.from_options({"model": "test-model", "base_url": url, "api_key_env": None,
                                            "timeout": 2.0})
        with pytest.raises(ModelError) as failure:
            vlm.ask([image()], "hi")
    assert "u:pw@" not in str(failure.value) and "no such route http://***@127.0.0.1" in str(failure.value)
