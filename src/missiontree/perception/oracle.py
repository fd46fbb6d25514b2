"""A simulation-only detector that reads the simulator's instance mask: perfect, or as bad as asked.

**Simulation only.** The oracle labels a camera frame from the ground truth the simulator keeps
beside it (which prism every pixel shows), so it needs a simulated robot exposing ``truth``
(:class:`missiontree.backends.sim.truth.GroundTruth`: ``instance_mask(stamp)`` and
``instances``). Binding it to any other robot is refused with an error that says what to use
instead. It exists so that tests of the layers above (search, surveillance, scene graph) can
control exactly what "the detector" sees: with ``miss_rate`` and ``false_positive_rate`` a test
can make it miss objects and hallucinate others, reproducibly from ``seed``.

It answers ``detect(image)`` for whole camera frames the robot produced: the image is matched
to the frame it came from (the robot's latest frame, or one the oracle saw recently), and that
frame's stamp selects the instance mask. ``detect_frame(frame)`` takes the stamp from the frame
itself and works for any frame the simulator still keeps.

**Threads.** Detections are model calls that run on worker threads while the simulator steps on
the tick thread. The simulator's state is best read on the tick thread:
:meth:`OracleDetector.prepare_frame` (called there by
:func:`~missiontree.perception.detectors.detection_job`) fetches the frame's mask and keeps it, and
a ``detect(image)`` from a worker (the offline VLM asking about that frame) finds the kept mask.
Misses and made-up boxes are drawn from a generator seeded by the seed and the frame's stamp, so
a frame gets the same answer whichever thread asks first. A ``detect(image)`` about a frame nobody
prepared still works, reading the simulator from the calling thread as before; leaves that ask
models about frames call :func:`~missiontree.perception.detectors.share_frame` first.
"""

from __future__ import annotations

import threading
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from missiontree.errors import ModelConfigError, ModelError
from missiontree.perception.detectors import check_image
from missiontree.types import Detection, RGBDFrame

#: Instance kinds the oracle reports (walls, floor and ceiling are never detections).
DETECTABLE_KINDS = ("object", "person")


@dataclass(frozen=True)
class _Seen:
    """A frame the oracle was shown, with its instance mask once fetched."""

    stamp: float
    color: np.ndarray
    mask: np.ndarray | None = None


class OracleDetector:
    """Ground-truth detections from the simulator's instance mask, with seeded misses and ghosts.

    Args:
        robot: A simulated robot with ``truth``; may be bound later with :meth:`bind`.
        miss_rate: Probability in [0, 1] that a visible object is left out of a frame's answer.
        false_positive_rate: Probability in [0, 1] that a frame's answer holds one made-up box.
        seed: Seed of the misses and made-up boxes.
        min_pixels: Objects showing fewer pixels than this are not reported.
        score: Score given to every detection.
        labels: Labels to report and to draw made-up boxes from; default every label of the
            world's objects and people.
        name: Provider name used in errors and events.
    """

    #: The CLI binds providers marked so to the robot once it exists (providers.bind_robot).
    needs_robot = True
    simulation_only = True

    def __init__(
        self,
        robot: Any = None,
        miss_rate: float = 0.0,
        false_positive_rate: float = 0.0,
        seed: int = 0,
        min_pixels: int = 30,
        score: float = 0.99,
        labels: list[str] | None = None,
        name: str = "oracle",
    ) -> None:
        self.name = name
        for option, value in (("miss_rate", miss_rate), ("false_positive_rate", false_positive_rate),
                              ("score", score)):
            if not 0.0 <= float(value) <= 1.0:
                raise ModelConfigError(
                    f"detector {name!r}: {option} must lie in [0, 1], found {value!r}; fix it in the "
                    f"models config (config/models/*.yaml)"
                )
        self.miss_rate = float(miss_rate)
        self.false_positive_rate = float(false_positive_rate)
        self.min_pixels = int(min_pixels)
        self.score = float(score)
        self._wanted = list(labels) if labels is not None else None
        self.seed = int(seed)
        self._robot: Any = None
        self._truth: Any = None
        self._seen: deque[_Seen] = deque(maxlen=16)
        self._lock = threading.Lock()
        if robot is not None:
            self.bind(robot)

    # -- binding -------------------------------------------------------------------------------

    def bind(self, robot: Any) -> None:
        """Attach the oracle to a simulated robot.

        Raises:
            ModelConfigError: The robot is not simulated or exposes no ground truth.
        """
        truth = getattr(robot, "truth", None)
        if not getattr(robot, "simulated", False) or truth is None or not hasattr(truth, "instance_mask"):
            raise ModelConfigError(
                f"detector {self.name!r} is simulation-only: it reads the simulator's instance mask, "
                f"but robot {getattr(robot, 'name', type(robot).__name__)!r} is not a simulated robot "
                f"with ground truth; configure a real detector for it (provider 'sim_detector' or "
                f"'yolo_onnx' in config/models/*.yaml)"
            )
        self._robot, self._truth = robot, truth

    def _bound_truth(self) -> Any:
        if self._truth is None:
            raise ModelConfigError(
                f"detector {self.name!r} is not bound to a simulated robot; build it with the robot "
                f"(options 'robot') or call bind(robot) before detecting"
            )
        return self._truth

    # -- the Detector protocol -----------------------------------------------------------------

    @property
    def labels(self) -> list[str]:
        """Labels this oracle reports: the configured ones, else those of the bound world."""
        if self._wanted is not None:
            return list(self._wanted)
        if self._truth is None:
            return []
        return sorted({i.label for i in self._truth.instances.values() if i.kind in DETECTABLE_KINDS})

    def detect(self, image: np.ndarray) -> list[Detection]:
        """Detections in a camera frame the robot produced (matched to it by content)."""
        check_image(image, self.name)
        stamp, mask = self._mask_of(image)
        return self._detect_in(stamp, mask, image.shape[:2])

    def detect_frame(self, frame: RGBDFrame) -> list[Detection]:
        """Detections in ``frame``, whose stamp selects the instance mask."""
        return self.prepare_frame(frame)()

    def prepare_frame(self, frame: RGBDFrame) -> Callable[[], list[Detection]]:
        """Fetch ``frame``'s mask now (on the simulator's thread); the returned function finds the boxes."""
        check_image(frame.color, self.name)
        mask = self._fetch_mask(frame.stamp)
        self._remember(_Seen(frame.stamp, frame.color, mask))
        shape = frame.color.shape[:2]
        return lambda: self._detect_in(frame.stamp, mask, shape)

    def check(self) -> str:
        """One-line description for ``missiontree models``; usable once bound to the simulated robot."""
        rates = f"miss rate {self.miss_rate:g}, false-positive rate {self.false_positive_rate:g}"
        if self._robot is None:
            return f"simulation-only oracle ({rates}); reads the simulator's instance mask once bound to it"
        return f"simulation-only oracle on robot {getattr(self._robot, 'name', '?')!r} ({rates})"

    def describe(self) -> dict[str, Any]:
        """What this detector is, for ``missiontree models`` and run summaries."""
        return {"provider": self.name, "simulation_only": True, "miss_rate": self.miss_rate,
                "false_positive_rate": self.false_positive_rate, "bound": self._truth is not None}

    # -- internals -----------------------------------------------------------------------------

    def _remember(self, seen: _Seen) -> None:
        with self._lock:
            self._seen = deque((s for s in self._seen if s.stamp != seen.stamp), maxlen=self._seen.maxlen)
            self._seen.append(seen)

    def _mask_of(self, image: np.ndarray) -> tuple[float, np.ndarray]:
        """The stamp and instance mask of the recent camera frame that ``image`` is."""
        self._bound_truth()
        match = self._find_seen(image)
        if match is None:
            # Not shown to the oracle beforehand (a caller that did not use share_frame): look at the
            # robot's latest frame, from this thread if need be, as the oracle always did.
            latest = self._robot.rgbd()
            if latest is not None:
                self._remember(_Seen(latest.stamp, latest.color))
            match = self._find_seen(image)
        if match is None:
            raise ModelError(
                f"detector {self.name!r}: the image is not a recent camera frame of robot "
                f"{getattr(self._robot, 'name', '?')!r}; the oracle labels whole frames the simulator "
                f"rendered (pass frame.color of robot.rgbd(), or call detect_frame(frame))"
            )
        if match.mask is not None:
            return match.stamp, match.mask
        mask = self._fetch_mask(match.stamp)
        self._remember(_Seen(match.stamp, match.color, mask))
        return match.stamp, mask

    def _find_seen(self, image: np.ndarray) -> _Seen | None:
        with self._lock:
            seen = list(self._seen)
        match = next((s for s in reversed(seen) if s.color is image), None)
        if match is None:
            match = next((s for s in reversed(seen)
                          if s.color.shape == image.shape and np.array_equal(s.color, image)), None)
        return match

    def _fetch_mask(self, stamp: float) -> np.ndarray:
        """The instance mask of the frame at ``stamp``: kept from prepare_frame, else read now."""
        truth = self._bound_truth()
        with self._lock:
            kept = next((s.mask for s in self._seen if s.stamp == stamp and s.mask is not None), None)
        if kept is not None:
            return kept
        mask = truth.instance_mask(stamp)
        if mask is None:
            raise ModelError(
                f"detector {self.name!r}: the simulator keeps no instance mask for the frame at "
                f"t={stamp:.3f} (too old); detect frames while they are recent"
            )
        return mask

    def _rng_for(self, stamp: float) -> np.random.Generator:
        """The generator of one frame's misses and made-up boxes (same frame, same answer)."""
        return np.random.default_rng(np.random.SeedSequence(
            [self.seed % (1 << 63), int(round(stamp * 1e6)) % (1 << 63)]))

    def _detect_in(self, stamp: float, mask: np.ndarray, shape: tuple[int, int]) -> list[Detection]:
        if mask.shape != shape:
            raise ModelError(
                f"detector {self.name!r}: the instance mask at t={stamp:.3f} is {mask.shape}, the image "
                f"{shape}; pass the frame's own colour image"
            )
        rng = self._rng_for(stamp)
        instances = self._bound_truth().instances
        wanted = set(self.labels)
        ids, counts = np.unique(mask, return_counts=True)
        found: list[Detection] = []
        for inst, count in zip(ids.tolist(), counts.tolist(), strict=True):
            info = instances.get(inst)
            if info is None or info.kind not in DETECTABLE_KINDS or info.label not in wanted:
                continue
            if count < self.min_pixels:
                continue
            if self.miss_rate > 0.0 and rng.random() < self.miss_rate:
                continue
            pixels = mask == inst
            rows = np.flatnonzero(pixels.any(axis=1))
            cols = np.flatnonzero(pixels.any(axis=0))
            box = (float(cols[0]), float(rows[0]), float(cols[-1] + 1), float(rows[-1] + 1))
            found.append(Detection(info.label, self.score, box, mask=pixels,
                                   attributes={"instance": info.name, "kind": info.kind, "oracle": True}))
        if self.false_positive_rate > 0.0 and wanted and rng.random() < self.false_positive_rate:
            found.append(self._made_up(rng, sorted(wanted), shape))
        return found

    def _made_up(self, rng: np.random.Generator, labels: list[str], shape: tuple[int, int]) -> Detection:
        """A box of a random label at a random place: what a hallucinating detector reports."""
        height, width = shape
        w = float(rng.uniform(0.05, 0.3) * width)
        h = float(rng.uniform(0.05, 0.4) * height)
        x1 = float(rng.uniform(0, width - w))
        y1 = float(rng.uniform(0, height - h))
        label = labels[int(rng.integers(len(labels)))]
        return Detection(label, self.score, (x1, y1, x1 + w, y1 + h),
                         attributes={"instance": None, "kind": "false_positive", "oracle": True})
