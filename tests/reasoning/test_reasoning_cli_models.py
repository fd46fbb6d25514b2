"""Tests of ``missiontree models``: list the configured providers, check each, exit 0 only when all usable."""

from __future__ import annotations

import json
import socket
from pathlib import Path

import pytest
from fake_openai_server import FakeOpenAIServer

from missiontree.cli.main import main

KEY = "sk-cli-test-key-0000SECRET"


def write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "models.yaml"
    path.write_text(text)
    return path


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


def test_all_usable_exits_0(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                            capsys: pytest.CaptureFixture[str]) -> None:
    """A server that answers, the embedder and the intent stand-in are all ok: exit 0, one line each."""
    monkeypatch.setenv("MT_CLI_KEY", KEY)
    with FakeOpenAIServer(api_key=KEY) as server:
        path = write(tmp_path, f"""
roles:
  vlm: {{provider: openai, model: test-model, base_url: "{server.url}", api_key_env: MT_CLI_KEY,
        latency: {{uniform: [0.5, 3.0]}}}}
  embedder: {{provider: minilm}}
  llm: {{provider: offline_llm, timeout: 5}}
""")
        code = main(["models", "--models", str(path), "--no-plugins"])
    out = capsys.readouterr().out
    assert code == 0, out
    assert "all providers usable" in out
    assert "vlm" in out and "test-model at http://127.0.0.1" in out and "simulated latency 0.5-3 s" in out
    assert "all-MiniLM-L6-v2" in out and "timeout 5 s" in out
    assert KEY not in out


def test_unusable_providers_exit_1_with_reasons(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    """An unreachable server, an unset key and a missing model file each get their reason; exit 1."""
    monkeypatch.delenv("MT_CLI_UNSET", raising=False)
    path = write(tmp_path, f"""
roles:
  vlm: {{provider: openai, model: m, base_url: "http://127.0.0.1:{free_port()}/v1", api_key_env: null}}
  llm: {{provider: openai, model: m, api_key_env: MT_CLI_UNSET}}
  embedder: {{provider: minilm, model_path: {tmp_path}/missing.onnx}}
""")
    code = main(["models", "--models", str(path), "--no-plugins", "--json"])
    report = json.loads(capsys.readouterr().out)
    assert code == 1 and report["usable"] is False
    errors = {row["role"]: row.get("error", "") for row in report["roles"]}
    assert "cannot reach the server" in errors["vlm"] and "start the server" in errors["vlm"]
    assert "MT_CLI_UNSET" in errors["llm"] and "export MT_CLI_UNSET" in errors["llm"]
    assert "missing.onnx' does not exist" in errors["embedder"]


def test_rejected_key_is_reported_without_the_key(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    """A server refusing the key gives 'rejected the API key' and the variable, never the key itself."""
    monkeypatch.setenv("MT_CLI_KEY", "sk-wrong-WRONGKEY-99999999")
    with FakeOpenAIServer(api_key=KEY) as server:
        path = write(tmp_path, f"""
roles:
  vlm: {{provider: openai, model: test-model, base_url: "{server.url}", api_key_env: MT_CLI_KEY}}
""")
        code = main(["models", "--models", str(path), "--no-plugins"])
    captured = capsys.readouterr()
    assert code == 1
    assert "rejected the API key (HTTP 401); set MT_CLI_KEY" in captured.out
    assert "WRONGKEY" not in captured.out + captured.err and "9999" not in captured.out + captured.err


def test_broken_config_exits_2_with_position(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A config with a malformed latency exits 2 with file:line:col."""
    path = write(tmp_path, "roles:\n  vlm:\n    provider: openai\n    latency: fast\n")
    assert main(["models", "--models", str(path), "--no-plugins"]) == 2
    assert f"{path}:4:14: roles.vlm.latency: latency: expected a number" in capsys.readouterr().err


def test_unknown_provider_is_an_unusable_row(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """An unknown provider is listed as unusable with the known ones (exit 1), not a crash."""
    path = write(tmp_path, "roles:\n  vlm:\n    provider: nonsense\n")
    assert main(["models", "--models", str(path), "--no-plugins"]) == 1
    assert "unknown model provider 'nonsense' (known: minilm, offline_llm" in capsys.readouterr().out


def test_no_check_only_lists(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """--no-check lists the roles without contacting anything."""
    url = f"http://127.0.0.1:{free_port()}/v1"
    path = write(tmp_path, f"roles:\n  vlm: {{provider: openai, model: m, base_url: '{url}', "
                           "api_key_env: null}\n")
    assert main(["models", "--models", str(path), "--no-plugins", "--no-check"]) == 0
    assert "unchecked" in capsys.readouterr().out


def test_shipped_default_config_is_usable(capsys: pytest.CaptureFixture[str]) -> None:
    """The default (offline) models config is usable as shipped: detector, stand-ins and embedder load."""
    code = main(["models", "--no-plugins"])
    out = capsys.readouterr().out
    assert code == 0, out
    assert "offline.yaml" in out and "all providers usable" in out


def test_a_detector_answering_non_finite_boxes_is_not_ok() -> None:
    """A detector whose check passes but whose boxes are NaN or far outside the frame is unusable."""
    from missiontree.cli.models import check_provider
    from missiontree.errors import ModelError
    from missiontree.types import Detection

    class Liar:
        name = "liar"
        labels = ["person"]

        def check(self) -> str:
            return "all fine"

        def detect(self, image):  # type: ignore[no-untyped-def]
            return [Detection("person", 0.9, (float("nan"), 1.0, 2.0, 3.0))]

    class FarAway(Liar):
        def detect(self, image):  # type: ignore[no-untyped-def]
            return [Detection("person", 0.9, (90000.0, 90000.0, 90010.0, 90010.0))]

    class Honest(Liar):
        def detect(self, image):  # type: ignore[no-untyped-def]
            return [Detection("person", 0.9, (1.0, 1.0, 20.0, 30.0))]

    with pytest.raises(ModelError, match="not finite"):
        check_provider(Liar())
    with pytest.raises(ModelError, match="outside"):
        check_provider(FarAway())
    assert check_provider(Honest()) == "all fine"


def test_the_http_timeout_shown_is_the_one_the_client_uses(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                            capsys: pytest.CaptureFixture[str]) -> None:
    """The role's timeout is both the row's timeout and the client's HTTP timeout (one value)."""
    monkeypatch.setenv("MT_CLI_KEY", KEY)
    with FakeOpenAIServer(api_key=KEY) as server:
        path = write(tmp_path, f"""
roles:
  vlm: {{provider: openai, model: test-model, base_url: "{server.url}", api_key_env: MT_CLI_KEY,
        timeout: 4}}
""")
        code = main(["models", "--models", str(path), "--no-plugins", "--json"])
    row = json.loads(capsys.readouterr().out)["roles"][0]
    assert code == 0 and row["timeout"] == 4.0
    assert "HTTP timeout 4 s" in row["detail"]


def test_credentials_in_base_url_are_not_printed(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """`missiontree models` names a base_url with user:password as ***@host, in text and JSON."""
    secret = "Pa55w0rd-Hunter2"
    with FakeOpenAIServer() as server:
        url = server.url.replace("http://", f"http://operator:{secret}@")
        path = write(tmp_path, f"""
roles:
  vlm: {{provider: openai, model: test-model, base_url: "{url}", api_key_env: null}}
""")
        main(["models", "--models", str(path), "--no-plugins"])
        main(["models", "--models", str(path), "--no-plugins", "--json"])
    captured = capsys.readouterr()
    assert secret not in captured.out + captured.err and "operator" not in captured.out + captured.err
    assert "***@127.0.0.1" in captured.out


def test_no_check_builds_no_provider(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str],
) -> None:
    """--no-check lists the shipped config's roles without building any of them (no model loaded)."""
    from missiontree.reasoning.models import PendingProvider

    built: list[object] = []
    real_get = PendingProvider.get

    def counting_get(self: PendingProvider) -> object:
        built.append(self)
        return real_get(self)

    monkeypatch.setattr(PendingProvider, "get", counting_get)
    assert main(["models", "--no-plugins", "--no-check"]) == 0
    out = capsys.readouterr().out
    assert "detector" in out and "embedder" in out and "unchecked" in out
    assert built == []
