"""Model files a models config may name: the size limits and the allow-list (no imports of the layers).

A provider factory declares the options that name files with the attribute ``path_options``:
option name → :class:`FileOption`. The session checks each such file before the provider is built
(:mod:`missiontree.session.model_files`): inside the models config's folder, the package's own data
or a folder of ``$MISSIONTREE_MODEL_PATH``, and no larger than its limit.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

#: Environment variable: extra folders model files may be read from (``os.pathsep``-separated).
MODEL_PATH_ENV = "MISSIONTREE_MODEL_PATH"
#: Largest ONNX model file read (512 MiB).
MAX_MODEL_BYTES = 512 * 2**20
#: Largest tokenizer file read (64 MiB).
MAX_TOKENIZER_BYTES = 64 * 2**20
#: Largest labels file read (1 MiB).
MAX_LABELS_BYTES = 2**20
#: The package's own data (the shipped detector model, the tokenizer): always allowed.
PACKAGE_DATA = Path(__file__).resolve().parent / "data"


@dataclass(frozen=True)
class FileOption:
    """A provider option that names a file: what it is (for messages) and its size limit in bytes."""

    what: str
    max_bytes: int


#: The file options of an ONNX detector (``yolo_onnx``, ``sim_detector``).
DETECTOR_FILES = {"model": FileOption("ONNX model", MAX_MODEL_BYTES),
                  "labels_file": FileOption("labels file", MAX_LABELS_BYTES)}
#: The file options of the MiniLM embedder.
EMBEDDER_FILES = {"model_path": FileOption("ONNX model", MAX_MODEL_BYTES),
                  "tokenizer_path": FileOption("tokenizer file", MAX_TOKENIZER_BYTES)}


def model_dirs() -> list[Path]:
    """The folders ``$MISSIONTREE_MODEL_PATH`` allows model files in, besides the config's own folder."""
    return [Path(p).resolve() for p in os.environ.get(MODEL_PATH_ENV, "").split(os.pathsep) if p]
