"""Object detectors: the ``Detector`` protocol and a YOLO-layout ONNX detector on onnxruntime.

Every detector answers ``detect(image) -> list[Detection]`` for an HxWx3 uint8 RGB image, with
boxes in that image's pixels. :class:`YoloOnnxDetector` runs any model exported in the standard
YOLOv8/YOLO11 layout (``yolo export format=onnx``): one input ``[1, 3, H, W]`` of RGB scaled to
[0, 1], one output ``[1, 4 + classes, N]`` holding, per candidate, the box centre, width and
height in input pixels followed by one score per class. Around the model it does what the
Ultralytics runtime does: letterbox (resize keeping aspect ratio, pad with grey 114), a score
threshold, class-wise non-maximum suppression and the mapping of boxes back to the image.

Class names come from the model's metadata (``names``, which Ultralytics writes as the text of a
Python dict ``{0: 'person', ...}``) or from a labels file (one name a line, or a YAML/JSON
``names`` list or mapping, as in an Ultralytics dataset file).
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any, Protocol, runtime_checkable

import numpy as np

from missiontree.errors import ModelConfigError, ModelError
from missiontree.perception.detector_labels import parse_names, read_labels_file
from missiontree.perception.recent_detections import RecentDetections
from missiontree.perception.yolo_layout import (
    PAD_VALUE,
    Letterbox,
    decode_yolo,
    decode_yolo_with_scores,
    iou_matrix,
    letterbox,
    nms,
)
from missiontree.types import Detection, RGBDFrame

__all__ = [
    "CLASS_SCORES", "PAD_VALUE", "Detector", "Letterbox", "YoloOnnxDetector", "check_image",
    "checked_detections", "decode_yolo", "decode_yolo_with_scores", "detect_checked", "detection_job",
    "iou_matrix", "letterbox", "nms", "share_frame",
]


#: Key of :attr:`Detection.attributes` holding the box's score for each class the model gave a real
#: share (label → score, at least :data:`CLASS_SCORE_FLOOR`), its reported label included.
CLASS_SCORES = "class_scores"

#: Least per-class score kept in a detection's :data:`CLASS_SCORES` (the rest is noise).
CLASS_SCORE_FLOOR = 0.01


def class_scores(labels: Sequence[str], row: np.ndarray) -> dict[str, float]:
    """The classes of one box's score vector ``row`` that reach :data:`CLASS_SCORE_FLOOR`, label → score."""
    return {labels[i]: round(float(v), 4) for i, v in enumerate(row) if v >= CLASS_SCORE_FLOOR}


@runtime_checkable
class Detector(Protocol):
    """Finds labelled boxes in a colour image."""

    #: Provider name, used in errors and tick-log events.
    name: str

    @property
    def labels(self) -> list[str]:
        """Every class name this detector can report."""
        ...

    def detect(self, image: np.ndarray) -> list[Detection]:
        """Detections in ``image`` (HxWx3 uint8 RGB), boxes in its pixels, best score first."""
        ...


def check_image(image: Any, provider: str) -> np.ndarray:
    """Return ``image`` if it is a non-empty HxWx3 uint8 array, else raise a clear error.

    Args:
        image: What the caller passed as an image.
        provider: Name of the detector, for the message.

    Raises:
        ModelConfigError: Not an array, wrong rank, channel count or dtype, or empty.
    """
    fix = "pass the colour image of an RGBDFrame (frame.color), HxWx3 uint8 RGB"
    if not isinstance(image, np.ndarray):
        raise ModelConfigError(
            f"detector {provider!r}: expected an image as a numpy array, found {type(image).__name__}; {fix}"
        )
    if image.ndim != 3 or image.shape[2] != 3:
        raise ModelConfigError(
            f"detector {provider!r}: expected an image of shape HxWx3, found shape {image.shape}; {fix}"
        )
    if image.shape[0] == 0 or image.shape[1] == 0:
        raise ModelConfigError(f"detector {provider!r}: the image is empty (shape {image.shape}); {fix}")
    if image.dtype != np.uint8:
        raise ModelConfigError(
            f"detector {provider!r}: expected a uint8 image, found dtype {image.dtype}; {fix}"
        )
    return image


def checked_detections(
    detections: Any, width: int, height: int, provider: str = "detector",
) -> tuple[list[Detection], list[str]]:
    """Keep the detections that are usable in a ``width`` x ``height`` image; say why the others are not.

    A detector is a model: its answer is checked where it enters, like any model's. A detection is
    dropped when it is not a :class:`Detection`, its score or a box coordinate is not a finite
    number, its box is inverted, or the box lies wholly outside the image; a box that reaches
    past the border is clipped to it (a person cut by the frame's edge keeps the part in view).
    Scores are clamped to [0, 1].

    Returns:
        (kept detections, one short reason per dropped detection).
    """
    kept: list[Detection] = []
    dropped: list[str] = []
    if not isinstance(detections, Sequence) or isinstance(detections, str | bytes):
        return [], [f"{provider}: expected a list of detections, found {type(detections).__name__}"]
    for det in detections:
        reason = _unusable(det, width, height)
        if reason:
            dropped.append(f"{provider}: {reason}")
            continue
        x1, y1, x2, y2 = (float(v) for v in det.box)
        box = (min(max(x1, 0.0), width), min(max(y1, 0.0), height),
               min(max(x2, 0.0), width), min(max(y2, 0.0), height))
        score = min(max(float(det.score), 0.0), 1.0)
        if box != det.box or score != det.score:
            det = replace(det, box=box, score=score)
        kept.append(det)
    return kept, dropped


def _unusable(det: Any, width: int, height: int) -> str:
    """Why ``det`` cannot be used in a ``width`` x ``height`` image ("" when it can)."""
    if not isinstance(det, Detection):
        return f"expected a Detection, found {type(det).__name__}"
    try:
        box = [float(v) for v in det.box]
        score = float(det.score)
    except (TypeError, ValueError):
        return f"box {det.box!r} or score {det.score!r} is not numbers"
    if len(box) != 4:
        return f"box {det.box!r} does not have 4 numbers (x1, y1, x2, y2)"
    if not all(math.isfinite(v) for v in [*box, score]):
        return f"{det.label!r}: box {det.box!r} or score {det.score!r} is not finite"
    x1, y1, x2, y2 = box
    if x2 < x1 or y2 < y1:
        return f"{det.label!r}: box {det.box!r} is inverted (expected x1 <= x2, y1 <= y2)"
    if x2 <= 0 or y2 <= 0 or x1 >= width or y1 >= height or x2 - x1 <= 0 or y2 - y1 <= 0:
        return f"{det.label!r}: box {det.box!r} is empty or outside the {width}x{height} image"
    return ""


def detect_checked(
    detector: Any, image: np.ndarray, band_labels: Sequence[str] | None = None,
) -> list[Detection]:
    """``detector.detect(image)`` with its answer checked (:func:`checked_detections`).

    Dropped detections are not an error (one bad box must not hide the good ones); they are logged.
    ``band_labels``: the classes the caller decides on, for a detector whose mirror pass is banded
    (:class:`YoloOnnxDetector`); other detectors ignore it.
    """
    name = getattr(detector, "name", type(detector).__name__)
    if band_labels is not None and isinstance(detector, YoloOnnxDetector):
        found = detector.detect(image, band_labels=tuple(band_labels))
    else:
        found = detector.detect(image)
    kept, dropped = checked_detections(found, image.shape[1], image.shape[0], str(name))
    if dropped:
        _log_dropped(dropped)
    return kept


def detection_job(
    detector: Any, frame: RGBDFrame, mirror: bool | None = None,
    band_labels: Sequence[str] | None = None,
) -> Callable[[], list[Detection]]:
    """The blocking work of detecting in ``frame``, to be submitted as a model call.

    Call this on the tick thread: a detector that must read state the tick thread owns (the
    simulation oracle reads the simulator's instance mask) does so here, through its
    ``prepare_frame(frame)``; the returned function does the rest on a worker and checks the answer.
    ``mirror`` asks a detector with a mirror pass (:class:`YoloOnnxDetector`) for it (True) or for
    the single pass only (False); None, and other detectors, detect as configured.
    ``band_labels`` (with ``mirror`` None) names the classes the caller decides on: the mirror
    pass's band is tested on their candidates only (see :meth:`YoloOnnxDetector.detect`).
    """
    prepare = getattr(detector, "prepare_frame", None)
    if callable(prepare):
        work: Callable[[], Any] = prepare(frame)
    elif (mirror is not None or band_labels is not None) and isinstance(detector, YoloOnnxDetector):
        labels = None if band_labels is None else tuple(band_labels)
        work = lambda: detector.detect(frame.color, mirror=mirror, band_labels=labels)  # noqa: E731
    else:
        work = lambda: detector.detect(frame.color)  # noqa: E731
    name = str(getattr(detector, "name", type(detector).__name__))
    height, width = frame.color.shape[:2]

    def run() -> list[Detection]:
        kept, dropped = checked_detections(work(), width, height, name)
        if dropped:
            _log_dropped(dropped)
        return kept

    return run


def share_frame(models: Any, frame: RGBDFrame) -> None:
    """Show ``frame`` to the providers that read state at a frame's instant (call on the tick thread).

    A model call about ``frame`` runs on a worker; a provider that must read what the tick thread
    owns to answer it (the simulation oracle reads the simulator's instance mask, also when the
    offline VLM asks it) fetches it here first. Other providers are not touched.
    """
    seen: set[int] = set()
    for provider in list(models.values()):
        prepare = getattr(provider, "prepare_frame", None)
        if callable(prepare) and id(provider) not in seen:
            seen.add(id(provider))
            prepare(frame)


def _log_dropped(dropped: list[str]) -> None:
    import structlog

    structlog.get_logger("missiontree.perception").warning(
        "detections_dropped", count=len(dropped), first=dropped[0])


#: Open onnxruntime sessions by (model file, its size and modification time, threads): a model is
#: opened once per process and shared by every detector on it (the runs of a batch, the offline
#: VLM's detector). onnxruntime's ``run`` may be called from several threads at once.
_SESSIONS: dict[tuple[str, int, int, int], Any] = {}
_SESSIONS_LOCK = threading.Lock()


class YoloOnnxDetector:
    """A detector for any ONNX model in the YOLOv8/YOLO11 export layout, run by onnxruntime.

    Args:
        model: Path of the ``.onnx`` file.
        labels_file: Optional class names file; else the model's ``names`` metadata is used.
        score_threshold: Candidates scoring at or below this are dropped before NMS.
        iou_threshold: Class-wise NMS overlap threshold.
        max_detections: At most this many detections a frame.
        multi_label: Report a box under every class scoring above ``score_threshold``, not only
            its best (see :func:`decode_yolo`).
        test_time_flip: Also run the model on the mirror image and pool both passes' candidate
            boxes (the mirrored ones mapped back) before NMS, as Ultralytics' ``augment`` does with
            flips: an object one pass misses or misnames the other often gets right. Twice the
            inference time.
        flip_band: With ``test_time_flip``, run the mirror pass only on frames whose single pass
            left a candidate scoring in ``[low, high)`` (its best class), where the pooled
            answer can change a caller's decision; None runs it on every frame. Frames whose
            candidates all score below ``low`` or at ``high`` and above keep the single pass.
        threads: onnxruntime intra-op threads (the robot's CPU is shared: default 2).
        input_size: (height, width) for a model whose input size is dynamic; ignored otherwise.
        name: Provider name used in errors and events.
        recent: Images whose detections are remembered (:class:`RecentDetections`); 0 for none.
    """

    def __init__(
        self,
        model: str | Path,
        labels_file: str | Path | None = None,
        score_threshold: float = 0.25,
        iou_threshold: float = 0.45,
        max_detections: int = 100,
        threads: int = 2,
        input_size: tuple[int, int] = (640, 640),
        name: str = "yolo_onnx",
        multi_label: bool = False,
        test_time_flip: bool = False,
        recent: int = 8,
        flip_band: tuple[float, float] | None = None,
    ) -> None:
        self.name = name
        self.model_path = Path(model)
        self.score_threshold = float(score_threshold)
        self.iou_threshold = float(iou_threshold)
        self.max_detections = int(max_detections)
        self.multi_label = bool(multi_label)
        self.test_time_flip = bool(test_time_flip)
        self.flip_band = None if flip_band is None else (float(flip_band[0]), float(flip_band[1]))
        if self.flip_band is not None and not 0.0 <= self.flip_band[0] <= self.flip_band[1]:
            raise ModelConfigError(
                f"detector {name!r}: flip_band {list(flip_band or ())} must be [low, high] with "
                f"0 <= low <= high")
        #: Model runs on images (``single``) and mirror passes among them (``mirror``).
        self.passes = {"single": 0, "mirror": 0}
        self.recent = RecentDetections(recent)
        self._buffers = threading.local()  # each thread's input tensors, reused (see _input_tensors)
        self._session = self._open_session(int(threads))
        self._input = self._session.get_inputs()[0]
        self.input_height, self.input_width = self._input_size(input_size)
        self._input_dtype = np.float16 if self._input.type == "tensor(float16)" else np.float32
        if labels_file is not None:
            self._labels = read_labels_file(Path(labels_file), name)
        else:
            self._labels = self._labels_from_metadata()
        self._check_output_layout()

    # -- loading -------------------------------------------------------------------------------

    def _open_session(self, threads: int) -> Any:
        """The model's session: opened once per process for a file and thread count (``_SESSIONS``)."""
        if not self.model_path.is_file():
            raise ModelConfigError(
                f"detector {self.name!r}: model file {str(self.model_path)!r} does not exist; "
                f"set 'model:' in the models config (config/models/*.yaml) to a YOLOv8/YOLO11 ONNX "
                f"export (yolo export model=yolov8n.pt format=onnx)"
            )
        stat = self.model_path.stat()
        key = (str(self.model_path.resolve()), stat.st_size, stat.st_mtime_ns, max(1, threads))
        with _SESSIONS_LOCK:
            session = _SESSIONS.get(key)
            if session is None:
                session = _SESSIONS[key] = self._new_session(threads)
        return session

    def _new_session(self, threads: int) -> Any:
        import onnxruntime as ort  # vendor SDK stays inside the provider

        options = ort.SessionOptions()
        options.intra_op_num_threads = max(1, threads)
        options.inter_op_num_threads = 1
        # onnxruntime's worker threads otherwise busy-wait after each run. On a robot's shared CPU
        # that time is taken from everything else, other detectors included: with four sessions
        # taking turns on 2 cores here, a run cost 6.4 ms spinning and 3.0 ms not (alone: 2.1, 1.9).
        options.add_session_config_entry("session.intra_op.allow_spinning", "0")
        options.log_severity_level = 3
        try:
            return ort.InferenceSession(str(self.model_path), options, providers=["CPUExecutionProvider"])
        except Exception as exc:  # onnxruntime raises its own untyped errors for unreadable models
            raise ModelConfigError(
                f"detector {self.name!r}: {str(self.model_path)!r} is not a loadable ONNX model "
                f"({type(exc).__name__}: {str(exc).splitlines()[0][:200]}); re-export it with "
                f"'yolo export format=onnx'"
            ) from None

    def _input_size(self, fallback: tuple[int, int]) -> tuple[int, int]:
        shape = self._input.shape
        if len(shape) != 4 or (isinstance(shape[1], int) and shape[1] != 3):
            raise ModelConfigError(
                f"detector {self.name!r}: {str(self.model_path)!r} takes input {shape}; expected one "
                f"image tensor [1, 3, H, W] as a YOLOv8/YOLO11 ONNX export has"
            )
        h, w = shape[2], shape[3]
        return (h if isinstance(h, int) else int(fallback[0]), w if isinstance(w, int) else int(fallback[1]))

    def _labels_from_metadata(self) -> list[str]:
        meta = self._session.get_modelmeta().custom_metadata_map
        if "names" not in meta:
            raise ModelConfigError(
                f"detector {self.name!r}: {str(self.model_path)!r} carries no class names in its "
                f"metadata ('names'); give 'labels_file:' with one class name a line"
            )
        try:
            return parse_names(meta["names"])
        except (ValueError, SyntaxError) as exc:
            raise ModelConfigError(
                f"detector {self.name!r}: the 'names' metadata of {str(self.model_path)!r} is not a "
                f"dict or list of class names ({exc}); give 'labels_file:' instead"
            ) from None

    def _check_output_layout(self, found: tuple[int, ...] | None = None) -> None:
        outputs = self._session.get_outputs()
        shape = tuple(found) if found is not None else tuple(outputs[0].shape)
        expected_rows = 4 + len(self._labels)
        rows = shape[1] if len(shape) == 3 else None
        if len(outputs) == 1 and len(shape) == 3 and (not isinstance(rows, int) or rows == expected_rows):
            return
        shown = [list(o.shape) for o in outputs] if found is None else [list(shape)]
        raise ModelConfigError(
            f"detector {self.name!r}: {str(self.model_path)!r} has output(s) {shown}; expected one "
            f"output [1, 4 + classes, N] = [1, {expected_rows}, N] for its {len(self._labels)} class "
            f"names (the standard YOLOv8/YOLO11 layout); re-export without NMS or end-to-end heads "
            f"(yolo export format=onnx nms=False), or fix the labels file"
        )

    # -- the Detector protocol -----------------------------------------------------------------

    @property
    def labels(self) -> list[str]:
        """Class names in the model's order."""
        return list(self._labels)

    def preprocess(self, image: np.ndarray) -> tuple[np.ndarray, Letterbox]:
        """Letterbox ``image`` into the model's input tensor ``[1, 3, H, W]`` scaled to [0, 1].

        The image (resized first only when it does not fit) is divided straight into its place in
        a tensor filled with the padding's grey: one pass, no padded copy; the numbers are those of
        padding, converting and dividing in turn (the same division in the input's dtype).
        """
        h, w = image.shape[:2]
        height, width = self.input_height, self.input_width
        if round(w * min(height / h, width / w)) != w or round(h * min(height / h, width / w)) != h:
            padded, box = letterbox(image, height, width)  # a resize: the general path
            image, top, left = padded, 0, 0
        else:
            top, left = round((height - h) / 2.0 - 0.1), round((width - w) / 2.0 - 0.1)
            box = Letterbox(scale=min(height / h, width / w), pad_x=float(left), pad_y=float(top))
        dtype = self._input_dtype
        scale = dtype(255.0)
        tensor = np.empty((1, 3, height, width), dtype=dtype)
        tensor[...] = dtype(PAD_VALUE) / scale
        ih, iw = image.shape[:2]
        np.divide(image.transpose(2, 0, 1), scale, out=tensor[0, :, top : top + ih, left : left + iw],
                  dtype=dtype, casting="unsafe")
        return tensor, box

    def _input_tensors(self) -> tuple[np.ndarray, np.ndarray, list[Any]]:
        """This thread's input tensor, its mirror's, and what the first holds outside its image slot.

        Reused from call to call: a fresh 1 MB tensor a call is mapped and faulted in page by page
        (the runner pins glibc's mmap threshold at 128 KiB), 241 page faults a pass.
        """
        buffers = getattr(self._buffers, "tensors", None)
        if buffers is None:
            shape = (1, 3, self.input_height, self.input_width)
            buffers = (np.empty(shape, self._input_dtype), np.empty(shape, self._input_dtype), [None])
            self._buffers.tensors = buffers
        return buffers

    def _preprocess_reused(self, image: np.ndarray) -> tuple[np.ndarray, Letterbox]:
        """:meth:`preprocess` into this thread's reused tensor: the same numbers.

        The result is overwritten by this thread's next call, so it is used at once and never kept.
        """
        h, w = image.shape[:2]
        height, width = self.input_height, self.input_width
        if round(w * min(height / h, width / w)) != w or round(h * min(height / h, width / w)) != h:
            tensor, box = self.preprocess(image)  # a resize: the general path
            return tensor, box
        top, left = round((height - h) / 2.0 - 0.1), round((width - w) / 2.0 - 0.1)
        box = Letterbox(scale=min(height / h, width / w), pad_x=float(left), pad_y=float(top))
        tensor, _, slot = self._input_tensors()
        dtype = self._input_dtype
        scale = dtype(255.0)
        if slot[0] != (top, left, h, w):  # the padding around this image's slot is laid once
            tensor[...] = dtype(PAD_VALUE) / scale
            slot[0] = (top, left, h, w)
        np.divide(image.transpose(2, 0, 1), scale, out=tensor[0, :, top : top + h, left : left + w],
                  dtype=dtype, casting="unsafe")
        return tensor, box

    def detect(
        self, image: np.ndarray, mirror: bool | None = None, band_labels: Sequence[str] | None = None,
    ) -> list[Detection]:
        """Detections in ``image`` (HxWx3 uint8 RGB), boxes in its pixels, best score first.

        Args:
            image: The colour image.
            mirror: Whether to add the mirror pass: None as configured (``test_time_flip`` and
                ``flip_band``), True on this frame whatever the band says (a caller verifying),
                False not (a caller that needs only the single pass's answer).
            band_labels: With ``mirror`` None and a ``flip_band``, the classes the caller decides
                on: the mirror pass runs only when a candidate whose best class is one of them
                scores in the band (a person check is not mirrored for a tiled floor scoring 0.4 as
                a laptop). None tests every class.
        """
        image = check_image(image, self.name)
        labels = None if band_labels is None else tuple(sorted(set(band_labels)))
        key = (*self.recent.key(image), mirror, labels) if self.recent.size else None
        if key is not None:
            remembered = self.recent.get(key)
            if remembered is not None:
                return remembered
        tensor, box = self._preprocess_reused(image)
        output = self._single_pass(tensor, None if key is None else key[:-2])
        if mirror if mirror is not None else (self.test_time_flip and self._mirror_pays(output, labels)):
            self.passes["mirror"] += 1
            flipped = self._input_tensors()[1]
            np.copyto(flipped, tensor[..., ::-1])
            mirrored = self._run(flipped)
            mirrored[:, 0] = self.input_width - mirrored[:, 0]  # box centres back in the unflipped input
            output = np.concatenate([output, mirrored], axis=2)
        boxes, scores, class_ids, rows = decode_yolo_with_scores(
            output, len(self._labels), self.score_threshold, self.iou_threshold, self.max_detections,
            self.multi_label,
        )
        boxes = box.to_image(boxes, image.shape[1], image.shape[0])
        found = [
            Detection(
                label=self._labels[int(c)],
                score=float(s),
                box=(float(b[0]), float(b[1]), float(b[2]), float(b[3])),
                attributes={"class_id": int(c), CLASS_SCORES: class_scores(self._labels, row)},
            )
            for b, s, c, row in zip(boxes, scores, class_ids, rows, strict=True)
        ]
        kept, dropped = checked_detections(found, image.shape[1], image.shape[0], self.name)
        if dropped:
            _log_dropped(dropped)
        if key is not None:
            self.recent.put(key, kept)
        return kept

    def _single_pass(self, tensor: np.ndarray, image_key: tuple[Any, ...] | None) -> np.ndarray:
        """The model's output on ``tensor``, taken from :attr:`recent` when this image was run before.

        Detections are remembered by what was asked (``mirror``), but the single pass is the same
        whatever was asked: a frame the surveillance detected in with the single pass, then asked
        about through the offline VLM (which may add the mirror pass), is run once, not twice.
        """
        if image_key is not None:
            output = self.recent.get_output(image_key)
            if output is not None:
                return output
        output = self._run(tensor)
        self.passes["single"] += 1
        if image_key is not None:
            self.recent.put_output(image_key, output)
        return output

    def _mirror_pays(self, output: np.ndarray, labels: Sequence[str] | None = None) -> bool:
        """Whether the single pass ``output`` left a candidate in :attr:`flip_band` (always without one).

        With ``labels``, only candidates whose best class is one of them count (a label the model
        does not know counts for none).
        """
        if self.flip_band is None:
            return True
        scores = output[0, 4 : 4 + len(self._labels)]
        if not scores.size:
            return False
        best = scores.max(axis=0)
        low, high = self.flip_band
        in_band = (best >= low) & (best < high)
        if labels is not None:
            wanted = [i for i, name in enumerate(self._labels) if name in labels]
            in_band &= np.isin(scores.argmax(axis=0), wanted)
        return bool(in_band.any())

    def _run(self, tensor: np.ndarray) -> np.ndarray:
        """The model's raw ``[1, 4 + classes, N]`` output for one input tensor, its layout checked."""
        output = np.asarray(self._session.run(None, {self._input.name: tensor})[0], dtype=np.float32)
        if output.ndim != 3 or output.shape[0] != 1 or output.shape[1] != 4 + len(self._labels):
            self._check_output_layout(found=tuple(output.shape))
        return output

    def check(self) -> str:
        """Run the model on a blank frame; return a one-line description (``missiontree models``).

        Raises:
            ModelError: The model's raw output holds NaN or infinity (a broken export or weights):
                ``detect`` would drop those candidates, so the model is not usable as it is.
        """
        blank = np.zeros((self.input_height, self.input_width, 3), dtype=np.uint8)
        tensor, _ = self.preprocess(blank)
        raw = self._run(tensor)
        if not np.isfinite(raw).all():
            bad = int((~np.isfinite(raw)).sum())
            raise ModelError(
                f"detector {self.name!r}: {str(self.model_path)!r} outputs {bad} non-finite numbers on a "
                f"blank frame; its boxes cannot be trusted: re-export or retrain the model")
        self.detect(blank)
        more = ", ..." if len(self._labels) > 6 else ""
        return (f"YOLO-layout ONNX detector {self.model_path.name} (input {self.input_height}x"
                f"{self.input_width}, {len(self._labels)} classes: {', '.join(self._labels[:6])}{more})")

    def describe(self) -> dict[str, Any]:
        """What this detector is, for ``missiontree models`` and run summaries."""
        return {
            "provider": self.name,
            "model": str(self.model_path),
            "input": [self.input_height, self.input_width],
            "classes": len(self._labels),
            "score_threshold": self.score_threshold,
            "multi_label": self.multi_label,
            "test_time_flip": self.test_time_flip,
            "flip_band": None if self.flip_band is None else list(self.flip_band),
            "passes": dict(self.passes),
        }
