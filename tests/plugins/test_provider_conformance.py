"""The detector conformance suite (missiontree.testing_models) on the built-in detectors and the plugin's.

``sim_detector`` and ``yolo_onnx`` (on the same shipped ONNX model) run on a frame the simulator
rendered of a shipped world, where they must find objects; the battery plugin's ``colour_blob``
runs as a plugin author would run it. The ``oracle`` detector is exempt: it is not a model but
reads the simulator's instance masks of frames the simulator produced, so it refuses other images
by design.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from missiontree.perception.providers import SIM_DETECTOR_MODEL, create_sim_detector, create_yolo_onnx
from missiontree.testing import fresh_plugins
from missiontree.testing_models import DetectorConformance

_FRAME: list[np.ndarray] = []


def simulator_frame() -> np.ndarray:
    """A camera frame of the office world, facing its furniture (rendered once per test run)."""
    if not _FRAME:
        from missiontree.backends.sim import create_robot

        robot = create_robot({"world": "office", "seed": 0, "sensors": []})
        robot.spin_until(0.5)
        frame = robot.rgbd()
        robot.close()
        assert frame is not None
        _FRAME.append(frame.color)
    return _FRAME[0]


class TestSimDetectorConformance(DetectorConformance):
    @pytest.fixture
    def detector(self) -> Any:
        return create_sim_detector({"threads": 1})

    @pytest.fixture
    def image(self) -> np.ndarray:
        return simulator_frame()


class TestYoloOnnxConformance(DetectorConformance):
    @pytest.fixture
    def detector(self) -> Any:
        return create_yolo_onnx({"model": str(SIM_DETECTOR_MODEL), "threads": 1, "score_threshold": 0.3})

    @pytest.fixture
    def image(self) -> np.ndarray:
        return simulator_frame()


class TestColourBlobFromThePlugin(DetectorConformance):
    """The plugin's provider, built by name from the loaded plugins as a models config would."""

    @pytest.fixture
    def detector(self) -> Any:
        plugins = fresh_plugins(autoload=True)
        if "colour_blob" not in plugins.providers:
            pytest.skip("missiontree-battery is not installed (make setup installs it)")
        return plugins.provider("colour_blob")({"colour": "red", "min_area": 20})
