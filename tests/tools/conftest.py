"""The detector tools' tests: the repository's root on the import path, and the train extra required in CI."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
if str(ROOT) not in sys.path:  # tools/ is a development package at the root, not installed
    sys.path.insert(0, str(ROOT))


def pytest_collectstart(collector: pytest.Collector) -> None:
    """With MISSIONTREE_REQUIRE_TRAIN=1 (``make test``), a missing CPU torch fails instead of skipping."""
    if os.environ.get("MISSIONTREE_REQUIRE_TRAIN") != "1" or not isinstance(collector, pytest.Module):
        return
    for module in ("torch", "onnx"):
        try:
            __import__(module)
        except ImportError as error:
            raise pytest.UsageError(
                f"MISSIONTREE_REQUIRE_TRAIN=1 but {module} does not import ({error}); "
                "run `make setup-train` (.venv/bin/pip install -e '.[train]')") from error
