"""Files a models config names: inside its folder or $MISSIONTREE_MODEL_PATH, size-bounded, never echoed."""

from __future__ import annotations

import os
import shutil
from pathlib import Path
from typing import Any

import pytest

from missiontree.cli.main import main
from missiontree.errors import MissionFileError, ModelError, ProblemsError
from missiontree.file_limits import MAX_LABELS_BYTES, MAX_MODEL_BYTES, MODEL_PATH_ENV
from missiontree.perception.providers import SIM_DETECTOR_MODEL, create_sim_detector
from missiontree.perception.providers import register_providers as register_perception
from missiontree.plugins.manager import load_plugins
from missiontree.reasoning.providers import register_providers as register_reasoning
from missiontree.session import MissionRequest, Session
from missiontree.session.models import build_models
from missiontree.session.preflight import check_models_file
from missiontree.testing import ClockRobot, clean_state

SECRET = "TOP-SECRET-LINE-4711: hunter2\n"


@pytest.fixture(autouse=True)
def _clean(monkeypatch: pytest.MonkeyPatch) -> None:
    clean_state()
    monkeypatch.delenv(MODEL_PATH_ENV, raising=False)


def providers() -> dict[str, Any]:
    registry: dict[str, Any] = {}
    register_perception(registry)
    register_reasoning(registry)
    return registry


@pytest.fixture()
def tree(tmp_path: Path) -> dict[str, Path]:
    """A models folder and, beside it, a folder of secrets the config must not reach."""
    models = tmp_path / "cfg"
    outside = tmp_path / "outside"
    models.mkdir()
    outside.mkdir()
    (outside / "secret.onnx").write_text(SECRET, encoding="utf-8")
    (outside / "labels.txt").write_text("person\nchair\n", encoding="utf-8")
    return {"models": models, "outside": outside}


def write_config(folder: Path, role_lines: str, name: str = "models.yaml") -> Path:
    path = folder / name
    path.write_text(f"roles:\n  detector:\n{role_lines}", encoding="utf-8")
    return path


def assert_refused(path: Path, line: int, needle: str) -> str:
    """Both the run's build and `validate`'s check refuse it at line:col, without the file's content."""
    with pytest.raises(ProblemsError) as caught:
        build_models(path, providers())
    text = str(caught.value)
    assert f"{path}:{line}:" in text and needle in text
    assert "hunter2" not in text and "TOP-SECRET" not in text
    checked = [str(p) for p in check_models_file(path, providers())]
    assert len(checked) == 1 and f"{path}:{line}:" in checked[0] and needle in checked[0]
    return text


def test_an_absolute_path_outside_the_folder_is_refused(tree: dict[str, Path]) -> None:
    config = write_config(tree["models"], "    provider: yolo_onnx\n    model: /etc/passwd\n")
    text = assert_refused(config, 4, "found '/etc/passwd' outside them")
    assert "root:" not in text and MODEL_PATH_ENV in text


def test_a_dotdot_escape_is_refused(tree: dict[str, Path]) -> None:
    config = write_config(tree["models"], "    provider: sim_detector\n    model: ../outside/secret.onnx\n")
    assert_refused(config, 4, "'../outside/secret.onnx' outside them")


def test_a_symlink_beside_the_config_to_a_file_outside_is_refused(tree: dict[str, Path]) -> None:
    (tree["models"] / "model.onnx").symlink_to(tree["outside"] / "secret.onnx")
    config = write_config(tree["models"], "    provider: yolo_onnx\n    model: model.onnx\n")
    assert_refused(config, 4, "'model.onnx' outside them")


def test_a_labels_file_and_a_tokenizer_outside_are_refused(tree: dict[str, Path]) -> None:
    config = write_config(tree["models"], f"    provider: sim_detector\n    labels_file: "
                          f"{tree['outside'] / 'labels.txt'}\n")
    assert_refused(config, 4, "expected a labels file inside")
    config = tree["models"] / "embedder.yaml"
    config.write_text(f"roles:\n  embedder:\n    provider: minilm\n    tokenizer_path: "
                      f"{tree['outside'] / 'secret.onnx'}\n", encoding="utf-8")
    assert_refused(config, 4, "expected a tokenizer file inside")


def test_a_folder_in_the_env_allow_list_is_allowed(tree: dict[str, Path],
                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    names = [f"class{i}" for i in range(len(create_sim_detector({"threads": 1}).labels))]
    labels = tree["outside"] / "labels.txt"
    labels.write_text("\n".join(names), encoding="utf-8")
    config = write_config(tree["models"], f"    provider: sim_detector\n    labels_file: {labels}\n")
    with pytest.raises(ProblemsError):
        build_models(config, providers())
    allowed = [str(tree["models"] / "nowhere"), str(tree["outside"])]
    monkeypatch.setenv(MODEL_PATH_ENV, os.pathsep.join(allowed))
    assert check_models_file(config, providers()) == []
    detector = build_models(config, providers())["detector"]
    assert detector.labels == names


def test_a_relative_path_resolves_beside_the_config_not_the_working_directory(
        tree: dict[str, Path], monkeypatch: pytest.MonkeyPatch) -> None:
    shutil.copy(SIM_DETECTOR_MODEL, tree["models"] / "mine.onnx")
    config = write_config(tree["models"], "    provider: yolo_onnx\n    model: mine.onnx\n")
    monkeypatch.chdir(tree["outside"])
    detector = build_models(config, providers())["detector"]
    assert Path(detector.model_path) == (tree["models"] / "mine.onnx").resolve()
    assert detector.model_path.is_file()


def test_the_shipped_model_in_the_package_is_allowed(tree: dict[str, Path]) -> None:
    config = write_config(tree["models"], f"    provider: yolo_onnx\n    model: {SIM_DETECTOR_MODEL}\n")
    assert check_models_file(config, providers()) == []
    assert Path(build_models(config, providers())["detector"].model_path) == SIM_DETECTOR_MODEL


def test_a_model_over_the_size_limit_is_refused_before_it_is_read(tree: dict[str, Path]) -> None:
    big = tree["models"] / "huge.onnx"
    with big.open("wb") as f:  # sparse: no disk used
        f.truncate(MAX_MODEL_BYTES + 1)
    config = write_config(tree["models"], "    provider: yolo_onnx\n    model: huge.onnx\n")
    assert_refused(config, 4, "expected an ONNX model of at most 512 MiB, found 'huge.onnx' of 512.0 MiB")


def test_a_labels_file_over_its_limit_is_refused_without_its_content(tree: dict[str, Path]) -> None:
    secrets = SECRET * (MAX_LABELS_BYTES // len(SECRET) + 1)
    (tree["models"] / "labels.txt").write_text(secrets, encoding="utf-8")
    config = write_config(tree["models"], "    provider: sim_detector\n    labels_file: labels.txt\n")
    assert_refused(config, 4, "expected a labels file of at most 1 MiB")


def test_a_fifo_beside_the_config_is_refused_without_blocking(tree: dict[str, Path]) -> None:
    os.mkfifo(tree["models"] / "pipe.onnx")
    config = write_config(tree["models"], "    provider: yolo_onnx\n    model: pipe.onnx\n")
    assert_refused(config, 4, "which is not a regular file")


def test_a_model_name_that_is_not_a_file_option_is_not_checked(tree: dict[str, Path]) -> None:
    """The openai provider's `model:` is a model name on a server, not a file."""
    config = tree["models"] / "openai.yaml"
    config.write_text("roles:\n  vlm: {provider: openai, model: /etc/passwd, api_key_env: null}\n",
                      encoding="utf-8")
    assert check_models_file(config, providers()) == []


def test_a_session_refuses_a_models_config_with_a_file_outside_before_building_the_robot(
        tree: dict[str, Path], tmp_path: Path) -> None:
    mission = tmp_path / "m.yaml"
    mission.write_text("version: 1\nrun: {backend: fake, max_duration: 1}\nroot:\n  Wait: {seconds: 0.1}\n",
                       encoding="utf-8")
    config = write_config(tree["models"], "    provider: yolo_onnx\n    model: ../outside/secret.onnx\n")
    plugins = load_plugins(autoload=False)
    robots: list[ClockRobot] = []
    plugins.backends["fake"] = lambda options: robots.append(ClockRobot()) or robots[-1]
    with pytest.raises(MissionFileError, match="outside them") as caught:
        Session.open(MissionRequest(mission=mission, plugins=plugins, models=config, out=tmp_path / "run"))
    assert robots == [] and "hunter2" not in str(caught.value)


def test_missiontree_run_and_validate_exit_2_at_the_line(tree: dict[str, Path], tmp_path: Path,
                                                         capsys: pytest.CaptureFixture[str]) -> None:
    mission = tmp_path / "m.yaml"
    mission.write_text("version: 1\nrun: {max_duration: 1}\nroot:\n  Wait: {seconds: 0.1}\n",
                       encoding="utf-8")
    secret = tree["outside"] / "secret.onnx"
    config = write_config(tree["models"], f"    provider: yolo_onnx\n    model: {secret}\n")
    out_dir = tmp_path / "run"
    assert main(["run", str(mission), "--models", str(config), "--out", str(out_dir), "--quiet"]) == 2
    assert main(["validate", str(config)]) == 2
    out = capsys.readouterr()
    assert out.out.count(f"{config}:4:") + out.err.count(f"{config}:4:") >= 2
    assert "hunter2" not in out.out + out.err and "Traceback" not in out.err


def test_the_embedder_checks_a_tokenizer_size_before_reading_it(tmp_path: Path) -> None:
    """Used directly (no models config), MiniLM still refuses an oversized file by its size."""
    from missiontree.errors import ModelConfigError
    from missiontree.file_limits import MAX_TOKENIZER_BYTES
    from missiontree.reasoning.embedder import MiniLMEmbedder

    big = tmp_path / "tokenizer.json"
    with big.open("wb") as f:
        f.truncate(MAX_TOKENIZER_BYTES + 1)
    with pytest.raises(ModelConfigError, match="larger than 64 MiB"):
        MiniLMEmbedder(tokenizer_path=big).embed(["a chair"])


def test_a_config_given_as_data_is_confined_to_the_working_directory(
        tree: dict[str, Path], monkeypatch: pytest.MonkeyPatch) -> None:
    """Relative to the working directory; absolute or relative paths outside it refused."""
    monkeypatch.chdir(tree["models"])
    for value in (str(tree["outside"] / "secret.onnx"), "../outside/secret.onnx"):
        config = {"roles": {"embedder": {"provider": "minilm", "tokenizer_path": value}}}
        with pytest.raises(ProblemsError, match="outside them") as caught:
            build_models(config, providers())
        assert "<models config>:" in str(caught.value) and "hunter2" not in str(caught.value)
    monkeypatch.setenv(MODEL_PATH_ENV, str(tree["outside"]))
    allowed = {"roles": {"embedder": {"provider": "minilm", "tokenizer_path": "../outside/secret.onnx"}}}
    embedder = build_models(allowed, providers())["embedder"]
    assert embedder._tokenizer_path == (tree["outside"] / "secret.onnx").resolve()  # handed over absolute


def test_a_models_config_named_in_the_run_section_is_read_beside_the_mission(
        tree: dict[str, Path], tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """As checked before the run: from another working directory, the run uses the checked files."""
    shutil.copy(SIM_DETECTOR_MODEL, tree["models"] / "mine.onnx")
    write_config(tree["models"], "    provider: yolo_onnx\n    model: mine.onnx\n", "mymodels.yaml")
    mission = tree["models"] / "m.yaml"
    mission.write_text("version: 1\nrun: {backend: fake, max_duration: 1, models: mymodels.yaml}\nroot:\n"
                       "  Wait: {seconds: 0.1}\n", encoding="utf-8")
    plugins = load_plugins(autoload=False)
    plugins.backends["fake"] = lambda options: ClockRobot()
    monkeypatch.chdir(tree["outside"])
    session = Session.open(MissionRequest(mission=mission, plugins=plugins, out=tmp_path / "run"))
    try:
        assert Path(session.models["detector"].model_path) == (tree["models"] / "mine.onnx").resolve()
    finally:
        session.close()


def test_a_broken_yaml_labels_file_makes_the_role_unusable_without_its_lines(tree: dict[str, Path]) -> None:
    (tree["models"] / "labels.yaml").write_text("names: [a, b\npassword: hunter2\n", encoding="utf-8")
    config = write_config(tree["models"], "    provider: sim_detector\n    labels_file: labels.yaml\n")
    detector = build_models(config, providers())["detector"]
    with pytest.raises(ModelError, match=r"not valid YAML \(line 2, column 9\)") as caught:
        detector.detect(None)
    assert "hunter2" not in str(caught.value)
