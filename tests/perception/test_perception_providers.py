from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from perception_onnx import constant_yolo_model, yolo_output

from missiontree.errors import ModelConfigError
from missiontree.perception.detectors import YoloOnnxDetector
from missiontree.perception.oracle import OracleDetector
from missiontree.perception.providers import (
    create_oracle,
    create_sim_detector,
    create_yolo_onnx,
    register_providers,
)


def test_register_providers_adds_the_three_detectors() -> None:
    """yolo_onnx, sim_detector and oracle are registered by name."""
    providers: dict[str, object] = {}
    register_providers(providers)
    assert set(providers) == {"yolo_onnx", "sim_detector", "oracle"}


def test_builtin_plugin_lists_the_perception_providers() -> None:
    """The built-in plugin pulls the detectors in through the same hook as any plugin."""
    from missiontree.plugins.builtin import PROVIDER_MODULES

    assert "missiontree.perception.providers" in PROVIDER_MODULES


def test_yolo_onnx_factory_passes_its_options(tmp_path: Path) -> None:
    """Options from a models config reach the detector."""
    model = constant_yolo_model(tmp_path / "m.onnx", yolo_output([(5, 5, 2, 2, [0.5])], 1), names="['a']")
    detector = create_yolo_onnx({"model": str(model), "score_threshold": 0.6, "threads": 1, "name": "mine"})
    assert isinstance(detector, YoloOnnxDetector)
    assert (detector.name, detector.score_threshold) == ("mine", 0.6)
    assert detector.detect(np.zeros((64, 64, 3), np.uint8)) == []
    assert detector.multi_label is False
    assert create_yolo_onnx({"model": str(model), "multi_label": True}).multi_label is True


def test_yolo_onnx_without_model_says_what_to_set() -> None:
    """The model option is required, and the message says how to get one."""
    with pytest.raises(ModelConfigError, match="'yolo_onnx': option 'model' is required"):
        create_yolo_onnx({})


def test_unknown_option_lists_the_known_ones() -> None:
    """A misspelt option is refused with the provider's known options."""
    with pytest.raises(ModelConfigError, match=r"invalid options \(treshold.*known options: model"):
        create_yolo_onnx({"model": "x.onnx", "treshold": 0.5})


def test_sim_detector_loads_the_shipped_model() -> None:
    """sim_detector needs no options: the model ships in the package with its class names."""
    detector = create_sim_detector({})
    assert detector.name == "sim_detector"
    assert "person" in detector.labels and "chair" in detector.labels


def test_sim_detector_with_a_missing_override_names_the_file(tmp_path: Path) -> None:
    """A model override that does not exist is the missing-file error, naming the provider."""
    with pytest.raises(ModelConfigError, match="'sim_detector': model file .*does not exist"):
        create_sim_detector({"model": str(tmp_path / "retrained.onnx")})


def test_oracle_factory_checks_its_rates() -> None:
    """The oracle's options are validated like the others'."""
    assert isinstance(create_oracle({}), OracleDetector)
    with pytest.raises(ModelConfigError, match="'oracle': invalid options"):
        create_oracle({"false_positive_rate": -0.1})


def test_models_config_with_a_missing_model_leaves_a_broken_role_with_the_reason(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Through session.models, a missing ONNX file makes the role unusable with the provider's message."""
    from missiontree.errors import ModelError
    from missiontree.session.models import build_models

    providers: dict[str, object] = {}
    register_providers(providers)
    monkeypatch.setenv("MISSIONTREE_MODEL_PATH", str(tmp_path))  # a folder models may be read from
    config = {"roles": {"detector": {"provider": "yolo_onnx", "model": str(tmp_path / "no.onnx")}}}
    models = build_models(config, providers)
    with pytest.raises(ModelError, match=r"'yolo_onnx'.*does not exist.*models config"):
        models["detector"].detect(np.zeros((8, 8, 3), np.uint8))


def test_non_finite_detector_options_are_config_errors() -> None:
    """NaN or infinite thresholds and rates are refused with the option named, not taken as numbers."""
    from missiontree.perception.providers import create_oracle, create_sim_detector

    with pytest.raises(ModelConfigError, match="score_threshold: expected a finite number"):
        create_sim_detector({"score_threshold": float("nan")})
    with pytest.raises(ModelConfigError, match="miss_rate: expected a finite number"):
        create_oracle({"miss_rate": float("inf")})
