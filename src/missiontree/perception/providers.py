"""The perception layer's model providers, registered through the plugin hooks.

:func:`register_providers` adds, by name (the ``provider:`` of a models config):

- ``yolo_onnx`` — :class:`~missiontree.perception.detectors.YoloOnnxDetector` on any YOLOv8/YOLO11
  ONNX export; ``model:`` is required.
- ``sim_detector`` — the same detector on the model shipped in the package
  (``missiontree/data/models/sim_detector.onnx``), trained on the simulator's rendered images
  by the repository's ``tools/detector/train.py``; by default it also detects in the mirror image
  (``test_time_flip``) of frames where that can change a mission's decision (``flip_band``).
- ``oracle`` — :class:`~missiontree.perception.oracle.OracleDetector`, simulation only: it must be
  bound to the simulated robot (``options["robot"]``, or :func:`bind_robot` once the robot
  exists) and refuses any other robot.

A models config section, e.g.::

    roles:
      detector:
        provider: yolo_onnx
        model: models/yolov8n.onnx
        score_threshold: 0.4
        threads: 2
        multi_label: false      # true: a box under every class above the threshold, not only its best
        test_time_flip: false   # true: also detect in the mirror image and pool both (twice the time)
        flip_band: [0.3, 0.7]   # with test_time_flip: mirror only frames with a candidate scoring here

``model:`` and ``labels_file:`` resolve against the models config's folder and must lie inside it,
inside the package's data or inside a folder of ``$MISSIONTREE_MODEL_PATH`` (at most 512 MiB for a
model, 1 MiB for a labels file; see :mod:`missiontree.file_limits`).

Options are checked: an unknown or mistyped option is a :class:`ModelConfigError` naming the
provider and the options it knows. onnxruntime is imported only when a detector is built.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ConfigDict, Field, field_validator

from missiontree.errors import ModelConfigError
from missiontree.file_limits import DETECTOR_FILES
from missiontree.options import parse_provider_options

#: The detector shipped in the package (trained on the simulator's images).
SIM_DETECTOR_MODEL = Path(__file__).resolve().parents[1] / "data" / "models" / "sim_detector.onnx"

#: The shipped detector's mirror pass runs on frames with a single-pass candidate scoring in this
#: band: from its score threshold to the highest of the missions' confidence filters (0.7).
SIM_FLIP_BAND = (0.3, 0.7)


class YoloOptions(BaseModel):
    """Options of ``yolo_onnx`` and ``sim_detector`` (numbers must be finite)."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)

    model: str | None = None
    labels_file: str | None = None
    score_threshold: float = Field(0.25, ge=0, le=1)
    iou_threshold: float = Field(0.45, ge=0, le=1)
    max_detections: int = Field(100, ge=1)
    threads: int = Field(2, ge=1, le=64)
    input_size: tuple[int, int] = (640, 640)
    name: str | None = None
    multi_label: bool = False
    test_time_flip: bool = False
    flip_band: tuple[float, float] | None = None

    @field_validator("flip_band")
    @classmethod
    def _band_in_order(cls, band: tuple[float, float] | None) -> tuple[float, float] | None:
        if band is not None and not 0.0 <= band[0] <= band[1] <= 1.0:
            raise ValueError(f"flip_band must be [low, high] with 0 <= low <= high <= 1, found {list(band)}")
        return band


class OracleOptions(BaseModel):
    """Options of ``oracle`` (numbers must be finite)."""

    model_config = ConfigDict(extra="forbid", arbitrary_types_allowed=True, allow_inf_nan=False)

    robot: Any = None
    miss_rate: float = Field(0.0, ge=0, le=1)
    false_positive_rate: float = Field(0.0, ge=0, le=1)
    seed: int = 0
    min_pixels: int = Field(30, ge=1)
    score: float = Field(0.99, ge=0, le=1)
    labels: list[str] | None = None
    name: str = "oracle"


def _yolo(parsed: YoloOptions, model: str | Path, name: str) -> Any:
    import yaml

    try:
        return _yolo_detector(parsed, model, name)
    except yaml.YAMLError as exc:  # a broken YAML labels file: where, never the file's lines
        mark = getattr(exc, "problem_mark", None)
        where = f" (line {mark.line + 1}, column {mark.column + 1})" if mark is not None else ""
        raise ModelConfigError(
            f"detector {parsed.name or name!r}: labels file {parsed.labels_file!r} is not valid YAML{where}; "
            "give one class name a line, or a 'names' list or mapping") from None


def _yolo_detector(parsed: YoloOptions, model: str | Path, name: str) -> Any:
    from missiontree.perception.detectors import YoloOnnxDetector

    return YoloOnnxDetector(
        model,
        labels_file=parsed.labels_file,
        score_threshold=parsed.score_threshold,
        iou_threshold=parsed.iou_threshold,
        max_detections=parsed.max_detections,
        threads=parsed.threads,
        input_size=parsed.input_size,
        name=parsed.name or name,
        multi_label=parsed.multi_label,
        test_time_flip=parsed.test_time_flip,
        flip_band=parsed.flip_band,
    )


def create_yolo_onnx(options: Mapping[str, Any]) -> Any:
    """Build ``yolo_onnx`` on the model its ``model:`` option names."""
    parsed = parse_provider_options(YoloOptions, options, "yolo_onnx")
    if parsed.model is None:
        raise ModelConfigError(
            "model provider 'yolo_onnx': option 'model' is required; set it to a YOLOv8/YOLO11 ONNX "
            "export (yolo export model=yolov8n.pt format=onnx), or use provider 'sim_detector' for "
            "the shipped simulator model"
        )
    return _yolo(parsed, parsed.model, "yolo_onnx")


def create_sim_detector(options: Mapping[str, Any]) -> Any:
    """Build ``sim_detector``: the shipped model, or ``model:`` if given (e.g. a retrained one).

    It detects in the image and in its mirror image (``test_time_flip``) unless told not to, but
    only on frames where the single pass left a candidate scoring in :data:`SIM_FLIP_BAND`:
    between its own threshold and 0.7, where the missions' filters (0.5-0.7) decide and the pooled
    answer can change their decision. On the simulator's scenes the mirror pass lifts mAP@0.5 by
    about 0.007-0.01 and recall at 0.7 by 2-3 points; on the frames left out it changes nothing
    the missions keep (benchmarks/detector_quality.py measures all three: every frame, the band,
    none). ``flip_band: null`` mirrors every frame.

    It runs on one onnxruntime thread unless told otherwise: the model is small (0.5 M
    parameters), and a second thread cost more CPU than it saved time (8.9 against 9.8 CPU ms a
    frame with both passes; the missions' other work runs beside it on the other core).
    """
    defaults = {"score_threshold": 0.3, "test_time_flip": True, "flip_band": SIM_FLIP_BAND, "threads": 1}
    parsed = parse_provider_options(YoloOptions, {**defaults, **options}, "sim_detector")
    return _yolo(parsed, parsed.model or SIM_DETECTOR_MODEL, "sim_detector")


# the options each factory takes, so a models config is checked (file:line:col) before anything is built
create_yolo_onnx.options_model = YoloOptions  # type: ignore[attr-defined]
create_sim_detector.options_model = YoloOptions  # type: ignore[attr-defined]
# the options that name files, confined and size-checked by the session before the detector is built
create_yolo_onnx.path_options = DETECTOR_FILES  # type: ignore[attr-defined]
create_sim_detector.path_options = DETECTOR_FILES  # type: ignore[attr-defined]


def create_oracle(options: Mapping[str, Any]) -> Any:
    """Build ``oracle``, bound now if ``options["robot"]`` holds the simulated robot."""
    from missiontree.perception.oracle import OracleDetector

    parsed = parse_provider_options(OracleOptions, options, "oracle")
    return OracleDetector(
        robot=parsed.robot,
        miss_rate=parsed.miss_rate,
        false_positive_rate=parsed.false_positive_rate,
        seed=parsed.seed,
        min_pixels=parsed.min_pixels,
        score=parsed.score,
        labels=parsed.labels,
        name=parsed.name,
    )


def bind_robot(models: Mapping[str, Any], robot: Any) -> None:
    """Bind every provider marked ``needs_robot`` (the oracle) to ``robot``, once it exists.

    Raises:
        ModelConfigError: A simulation-only provider was configured for a robot that is not
            simulated.
    """
    for provider in models.values():
        if getattr(provider, "needs_robot", False) is True:
            provider.bind(robot)


def register_providers(providers: dict[str, Any]) -> None:
    """Add the perception layer's detectors to ``providers`` (name → factory)."""
    providers["yolo_onnx"] = create_yolo_onnx
    providers["sim_detector"] = create_sim_detector
    providers["oracle"] = create_oracle
