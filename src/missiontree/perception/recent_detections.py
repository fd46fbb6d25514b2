"""What a detector found in recent images, found again by the image's content (and its raw output).

Used by :class:`~missiontree.perception.detectors.YoloOnnxDetector`: a frame asked about twice (the
surveillance's detection, then the offline VLM's question about the same frame) is run once.
"""

from __future__ import annotations

import hashlib
import threading
from collections import OrderedDict
from dataclasses import replace
from typing import Any

import numpy as np

from missiontree.types import Detection

__all__ = ["RecentDetections"]


def _copy_detection(det: Detection) -> Detection:
    """A copy whose attributes (and their nested dicts) the caller may change freely."""
    attributes = {k: dict(v) if isinstance(v, dict) else v for k, v in det.attributes.items()}
    return replace(det, attributes=attributes)


class RecentDetections:
    """The detections of the last few images, found again by the image's content.

    A frame is often asked about twice: the surveillance leaf detects in it, then the offline VLM
    stand-in, asked about the same frame, runs its detector on it again (790 detections for 690
    frames in the patrol). A detector is deterministic, so the second answer is the first one: it
    is taken from here (a SHA-1 of the pixels, about 0.5 ms for 320x240, against 15-30 ms a run).

    Args:
        size: Images remembered (the oldest is forgotten first); 0 remembers none.
    """

    def __init__(self, size: int = 8) -> None:
        self.size = max(0, int(size))
        self._found: OrderedDict[tuple[Any, ...], list[Detection]] = OrderedDict()
        self._outputs: OrderedDict[tuple[Any, ...], np.ndarray] = OrderedDict()
        self._lock = threading.Lock()
        self.hits = 0

    @staticmethod
    def key(image: np.ndarray) -> tuple[Any, ...]:
        """The image's identity by content: shape, dtype and a digest of its pixels."""
        digest = hashlib.sha1(np.ascontiguousarray(image).data, usedforsecurity=False).digest()
        return (image.shape, image.dtype.str, digest)

    def get(self, key: tuple[Any, ...]) -> list[Detection] | None:
        """Copies of the detections found for ``key``, or None when it is not remembered."""
        with self._lock:
            found = self._found.get(key)
            if found is None:
                return None
            self._found.move_to_end(key)
            self.hits += 1
        return [_copy_detection(d) for d in found]

    def put(self, key: tuple[Any, ...], found: list[Detection]) -> None:
        """Remember ``found`` for ``key`` (copies: the caller keeps its own list)."""
        if self.size:
            self._remember(self._found, key, [_copy_detection(d) for d in found])

    def get_output(self, key: tuple[Any, ...]) -> np.ndarray | None:
        """The model's raw single-pass output remembered for image ``key`` (read-only), or None."""
        with self._lock:
            output = self._outputs.get(key)
            if output is not None:
                self._outputs.move_to_end(key)
        return output

    def put_output(self, key: tuple[Any, ...], output: np.ndarray) -> None:
        """Remember the raw single-pass ``output`` for image ``key`` (kept read-only)."""
        if self.size:
            output.flags.writeable = False
            self._remember(self._outputs, key, output)

    def _remember(self, table: OrderedDict[tuple[Any, ...], Any], key: tuple[Any, ...], value: Any) -> None:
        with self._lock:
            table[key] = value
            table.move_to_end(key)
            while len(table) > self.size:
                table.popitem(last=False)
