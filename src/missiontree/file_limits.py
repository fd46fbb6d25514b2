"""Model files a models config may name: the size limits and the allow-list (no imports of the layers).

A provider factory declares the options that name files with the attribute ``path_options``:
option name → :class:`FileOption`. The session checks each such file before the provider is built
(:mod:`missiontree.session.model_files`): inside the models config's folder, the package's own data
or a folder of ``$MISSIONTREE_MODEL_PATH``, and no larger than its limit.
"""

from __future__ import annotations

import os
from collections.abc import Callable
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


#: Largest scene-graph file read (``scene_graph.json``; 64 MiB is about 300,000 objects).
MAX_SCENE_GRAPH_BYTES = 64 * 2**20
#: Largest room-polygon file read.
MAX_ROOMS_BYTES = 16 * 2**20
#: Largest run view file read (``runview.json``: tree, map picture, trajectory).
MAX_RUNVIEW_BYTES = 256 * 2**20
#: Largest pose trail read (``poses.jsonl``).
MAX_POSES_BYTES = 256 * 2**20
#: Largest map image read by the map_server reader (``map convert``, ``--map`` files).
MAX_MAP_IMAGE_BYTES = 64 * 2**20
#: Largest ROS 2 robot profile read.
MAX_PROFILE_BYTES = 2**20


class FileTooLargeError(OSError):
    """A file is larger than the limit for what it holds (raised before it is read whole)."""


def read_bounded(path: str | os.PathLike[str], limit: int, what: str) -> bytes:
    """The bytes of a file, refused before reading when it holds more than ``limit`` bytes.

    The size is checked on the open file (``fstat``) and the read stops at ``limit + 1`` bytes, so a
    file that grows while read, a FIFO or a device is bounded too.

    Raises:
        FileTooLargeError: The file is larger than ``limit`` (names the file, its size and the limit).
        OSError: The file cannot be opened or read.
    """
    with open(path, "rb") as file:
        size = os.fstat(file.fileno()).st_size
        if size > limit:
            raise FileTooLargeError(f"{path}: the {what} is {size:,} bytes, over the limit of {limit:,}")
        data = file.read(limit + 1)
    if len(data) > limit:
        raise FileTooLargeError(f"{path}: the {what} is over the limit of {limit:,} bytes")
    return data


def read_text_bounded(path: str | os.PathLike[str], limit: int, what: str) -> str:
    """:func:`read_bounded` decoded as UTF-8 (``UnicodeDecodeError`` when it is not)."""
    return read_bounded(path, limit, what).decode("utf-8")


def read_input_text(path: str | os.PathLike[str], limit: int, what: str, expected: str,
                    error: Callable[[str], Exception]) -> str:
    """A user's text file, bounded, every way it can fail said as ``error`` naming the file.

    Args:
        path: The file.
        limit: Its size limit in bytes.
        what: What the file holds, for messages ("scene graph file").
        expected: What its text should be, said when it is not UTF-8 ("a scene graph file is JSON").
        error: The exception raised, made from the message (a ``ConfigError`` class, usually).
    """
    try:
        return read_text_bounded(path, limit, what)
    except FileTooLargeError as exc:
        raise error(str(exc)) from None
    except UnicodeDecodeError:
        raise error(f"{path}: not UTF-8 text; {expected}") from None
    except OSError as exc:
        raise error(f"cannot read the {what} {path}: {exc.strerror or exc}") from None
