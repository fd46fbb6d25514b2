"""Tests of the model wiring (session.models): config checks, building roles, broken providers."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
from pydantic import BaseModel

from missiontree.engine.context import MissionContext
from missiontree.engine.leaf import Leaf, Status
from missiontree.errors import ModelConfigError, ModelError, ProblemsError
from missiontree.reasoning.calls import SETTINGS_KEY, CallStatus, LatencyModel, ModelCall, model_caller
from missiontree.reasoning.prompts import surveillance_prompt
from missiontree.reasoning.providers import register_providers
from missiontree.reasoning.providers.offline_vlm import OfflineVisionModel
from missiontree.reasoning.schemas import SurveillanceVerdict
from missiontree.session.models import BrokenProvider, build_models
from missiontree.testing import ClockRobot, capture_tick_log
from missiontree.types import Detection


class PersonDetector:
    """Sees one person in every frame (a fake of the detector layer)."""

    name = "person_everywhere"
    labels = ["person"]

    def __init__(self, options: dict[str, Any]) -> None:
        if "model_path" in options and not Path(options["model_path"]).is_file():
            raise ModelConfigError(f"detector 'person_everywhere': model file {options['model_path']!r} "
                                   "does not exist; fix model_path")

    def detect(self, image: np.ndarray) -> list[Detection]:
        return [Detection("person", 0.9, (1.0, 1.0, 5.0, 9.0))]


def providers() -> dict[str, Any]:
    registry: dict[str, Any] = {"fake_detector": PersonDetector}
    register_providers(registry)
    return registry


def config(**roles: dict[str, Any]) -> dict[str, Any]:
    return {"roles": roles}


def test_roles_built_in_dependency_order() -> None:
    """A VLM listed before its detector still gets it; latency and timeout become call settings."""
    vlm = {"provider": "offline_vlm", "detector": "eyes", "latency": {"uniform": [0.5, 3]}, "timeout": 4}
    models = build_models(config(vlm=vlm, eyes={"provider": "fake_detector"}), providers())
    assert isinstance(models["vlm"], OfflineVisionModel)
    assert models["vlm"].detector is models["eyes"]
    settings = models[SETTINGS_KEY]
    assert settings.latency["vlm"] == LatencyModel(0.5, 3.0) and settings.timeouts["vlm"] == 4.0


def test_every_problem_reported_with_position(tmp_path: Path) -> None:
    """Unknown provider, bad latency, bad timeout and an unknown section are all reported at once, located."""
    path = tmp_path / "models.yaml"
    path.write_text("roles:\n"
                    "  vlm:\n"
                    "    provider: gpt5_magic\n"
                    "    latency: {gauss: 2}\n"
                    "    timeout: -1\n"
                    "extras: 1\n")
    with pytest.raises(ProblemsError) as failure:
        build_models(path, providers())
    text = str(failure.value)
    assert len(failure.value.problems) == 4
    assert f"{path}:3:15: roles.vlm.provider: unknown model provider 'gpt5_magic'" in text
    assert "known providers: fake_detector, minilm, offline_llm, offline_vlm, openai" in text
    assert f"{path}:4:14: roles.vlm.latency" in text and f"{path}:5:14: roles.vlm.timeout" in text
    assert f"{path}:6:1: extras: unknown section" in text


def test_missing_roles_section() -> None:
    """A config without roles says what it expected."""
    with pytest.raises(ProblemsError, match="expected 'roles:' mapping each role to a provider"):
        build_models({"calls": {"timeout": 3}}, providers())


def test_missing_model_file_becomes_broken_role_naming_fix() -> None:
    """A provider whose model file is missing is a BrokenProvider; using it raises the reason."""
    models = build_models(config(detector={"provider": "fake_detector", "model_path": "/nope/model.onnx"},
                                 vlm={"provider": "offline_vlm"}), providers())
    assert isinstance(models["detector"], BrokenProvider)
    with pytest.raises(ModelError, match="role 'detector' .*'/nope/model.onnx' does not exist; fix"):
        models["vlm"].ask([np.zeros((8, 8, 3), np.uint8)], surveillance_prompt(), SurveillanceVerdict)


def test_missing_dependency_role_names_the_fix() -> None:
    """offline_llm without an embedder role says which role to add."""
    models = build_models(config(llm={"provider": "offline_llm"}), providers())
    assert isinstance(models["llm"], BrokenProvider)
    assert "no role 'embedder' is configured" in models["llm"].reason


def test_unset_api_key_is_a_broken_role() -> None:
    """An openai role whose key variable is unset is broken, with the variable named."""
    models = build_models(config(vlm={"provider": "openai", "model": "m", "api_key_env": "MT_UNSET_KEY_VAR"}),
                          providers())
    with pytest.raises(ModelError, match="MT_UNSET_KEY_VAR .* is not set"):
        models["vlm"].check()


def test_shipped_configs_parse() -> None:
    """The shipped offline and openai configs pass checking (providers may be missing in this build)."""
    for name in ("offline", "openai"):
        models = build_models(name, providers(), strict=False)
        assert {"detector", "vlm", "llm", "embedder"} <= set(models)


# -- a mission that depends on a model -------------------------------------------------------------


class AskVLM(Leaf):
    """Asks the vlm whether a person is in view; SUCCESS on ALARM (test leaf of the layer above)."""

    class Params(BaseModel):
        timeout: float = 10.0

    def initialise(self) -> None:
        image = np.zeros((16, 16, 3), np.uint8)
        self.call: ModelCall | None = model_caller(self.context).ask(
            "vlm", [image], surveillance_prompt(), SurveillanceVerdict, timeout=self.params.timeout,
            node=self.name)

    def update(self) -> Status:
        assert self.call is not None
        status = self.call.status()
        if not status.done:
            return self.running("waiting for the vlm")
        if status is not CallStatus.SUCCEEDED:
            return self.fail(self.call.error())
        return self.succeed() if self.call.result().value.alarm else self.fail("no person")

    def terminate(self, new_status: Status) -> None:
        if getattr(self, "call", None) is not None and new_status == Status.INVALID:
            self.call.cancel()


Run = tuple[Any, list[dict[str, Any]], ClockRobot]


def run_mission(models: dict[str, Any], timeout: float = 10.0) -> Run:
    robot = ClockRobot()
    context = MissionContext(robot=robot, models=models, seed=3)
    result, log = capture_tick_log(AskVLM("ask", AskVLM.Params(timeout=timeout)), context, tick_hz=10.0)
    return result, log, robot


def model_calls(log: list[dict[str, Any]]) -> list[dict[str, Any]]:
    return [line for line in log if line.get("event") == "model_call"]


def test_mission_on_broken_model_fails_cleanly_with_reason() -> None:
    """A mission whose VLM's detector is missing fails with the reason in the tick log, robot stopped."""
    models = build_models(config(detector={"provider": "fake_detector", "model_path": "/nope.onnx"},
                                 vlm={"provider": "offline_vlm"}), providers())
    result, log, robot = run_mission(models)
    assert result.status == Status.FAILURE
    assert robot.stop_calls >= 1
    (call,) = model_calls(log)
    assert call["outcome"] == "failed" and call["role"] == "vlm" and call["node"] == "ask"
    assert "/nope.onnx' does not exist; fix model_path" in call["error"]
    finished = [line for line in log if line.get("changed")][-2]["changed"][0]
    assert finished["status"] == "FAILURE" and "/nope.onnx' does not exist" in finished["feedback"]


def test_simulated_latency_costs_simulated_time_and_repeats() -> None:
    """With a 2 s simulated VLM the mission succeeds after 2 s of robot time, identically twice."""
    spec = config(detector={"provider": "fake_detector"},
                  vlm={"provider": "offline_vlm", "latency": {"uniform": [1.0, 3.0]}})
    first, log1, _ = run_mission(build_models(spec, providers()))
    second, log2, _ = run_mission(build_models(spec, providers()))
    assert first.status == Status.SUCCESS
    (call,) = model_calls(log1)
    assert 1.0 <= call["latency"] <= 3.0 and call["t"] == pytest.approx(call["latency"], abs=0.1)
    assert first.duration == pytest.approx(call["t"])
    assert log1 == log2


def test_simulated_timeout_fails_the_mission_with_reason() -> None:
    """A VLM slower than the leaf's timeout fails the mission with a timeout reason at the timeout."""
    spec = config(detector={"provider": "fake_detector"}, vlm={"provider": "offline_vlm", "latency": 5.0})
    result, log, _ = run_mission(build_models(spec, providers()), timeout=2.0)
    assert result.status == Status.FAILURE
    (call,) = model_calls(log)
    assert call["outcome"] == "timed_out" and "no answer for role 'vlm' within 2 s" in call["error"]
    assert call["t"] == pytest.approx(2.0)
