"""Quality and speed of the shipped simulator detector on scenes it never saw.

Renders views of generated worlds whose seeds training never used (tools/detector/data.py:
training uses world seeds below 10 000, this benchmark seeds from 10 000 on), labels them from
the simulator's instance mask, and scores three detectors on the same frames, rotating their order
frame by frame so that machine load affects them alike:

- ``sim_detector`` — the shipped ONNX model (missiontree/data/models/sim_detector.onnx) through
  :class:`~missiontree.perception.detectors.YoloOnnxDetector`, onnxruntime on 2 threads, as the
  ``sim_detector`` provider configures it: detecting in the image and in its mirror image
  (``test_time_flip``) on frames whose single pass left a candidate scoring in its ``flip_band``
  (``frames_mirrored_share`` says how many);
- ``mirror_every_frame`` — the same with the mirror pass on every frame (``flip_band: null``, the
  previous default), whose figures (``map50_mirror_every_frame``,
  ``ms_per_frame_mirror_every_frame_median``) say what the band gives up and saves;
- ``single_pass`` — the same model without the mirror image, whose figures
  (``map50_single_pass``, ``ms_per_frame_single_pass_median``) say what the flip buys and costs;
- ``oracle`` — the quality reference: :class:`~missiontree.perception.oracle.OracleDetector` reading
  each frame's instance mask (through a small stand-in for the simulator's ground-truth API, since
  the views are rendered straight from the camera). Its mAP is 1 by construction, which checks the
  scoring end to end. It is no speed reference (it runs no model: its time is the cost of reading
  a mask); the speed reference is ``single_pass``, the same model doing the same work once.

mAP@0.5 and per-class AP use :class:`~missiontree.perception.evaluation.APAccumulator` (VOC
all-point AP); objects showing fewer than MIN_PIXELS pixels are *ignored* (neither demanded nor
held against a detection). ``map50_medium_large`` also ignores COCO's "small" objects (box under
32x32 pixels of the 320x240 frame); ``map50_mostly_unoccluded`` ignores objects more than half
hidden behind other things (each object rendered alone from the same pose gives its unhidden
share), which says how much of the gap is occlusion, and ``recall_by_visibility`` gives the share
found (above ``SCORE_THRESHOLD``) of objects more than half hidden, cut by the frame's edge, small,
and the rest (VISIBILITY), which says where the misses are. ``map50_class_agnostic`` scores boxes whatever
their label (how much of the gap is finding objects rather than naming them), and
``map50_look_alike_merged`` merges the classes the simulator drew as the same prism in shared
colours before it painted surface patterns (LOOK_ALIKE). All are diagnostics beside ``map50``,
which counts every object showing MIN_PIXELS or more and every detection scoring above
``SCORE_THRESHOLD``. ``map50_all_scores`` is the same with detections down to
``ALL_SCORES_THRESHOLD``, as COCO's and Ultralytics' evaluations rank them (a second, untimed
pass of the same model): the tail of low-scoring detections adds recall, so it is never lower.
``map50_multi_label`` is ``map50`` with each box reported under every class scoring above the
threshold, not only its best (the detector's ``multi_label`` option, as Ultralytics' ``val``
decodes; another untimed pass): what reporting the look-alike a box may also be would give.
``map50_shipped_worlds`` scores views of the worlds the missions run in (SHIPPED_WORLDS, never
trained on either; objects of classes the detector does not learn are ignored there). Times are
milliseconds per frame of ``detect()`` (letterbox, inference, decoding, NMS) in CPU time (the
process's: onnxruntime's own threads included), wall time beside it; the ratio sim_detector /
single pass (what the mirror image costs) is taken per frame on CPU time.

Run: ``.venv/bin/python benchmarks/detector_quality.py [--views N] [--worlds N]``.
The last line is one JSON object: ``map50`` (target >= 0.9), ``ms_per_frame_median`` (target
<= 10), ``ap50_per_class``, and the rest of the figures.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the repository's root: tools/
from missiontree.backends.sim import load_world  # noqa: E402
from missiontree.paths import find_config  # noqa: E402
from missiontree.perception.detectors import nms  # noqa: E402
from missiontree.perception.evaluation import APAccumulator, GroundTruth  # noqa: E402
from missiontree.perception.oracle import OracleDetector  # noqa: E402
from missiontree.perception.providers import SIM_DETECTOR_MODEL, create_sim_detector  # noqa: E402
from missiontree.types import Detection  # noqa: E402
from tools.detector.data import (  # noqa: E402
    CLASSES,
    EVAL_FIRST_WORLD,
    IMAGE_HW,
    MIN_PIXELS,
    generated_world,
    render_views,
    unoccluded_share,
)

#: COCO's "small" objects: box area under 32 x 32 pixels (ignored in the medium+large figure).
SMALL_AREA = 32 * 32
#: Share of an object's in-frame pixels that must be unhidden for the "mostly unoccluded" figure
#: (more hidden objects are ignored there, as KITTI's easier levels ignore occluded ones).
MOSTLY_VISIBLE = 0.5
#: How much of an object shows, for ``recall_by_visibility``: the first of these that applies.
VISIBILITY = ("more_than_half_hidden", "cut_by_frame_edge", "small", "whole_medium_or_large")
#: The shipped worlds the missions run in, scored apart (training never saw them either).
SHIPPED_WORLDS = ("office", "combined", "entrance_hall", "corridor")
#: Classes the simulator draws as the same prism in shared colours (a white bookshelf and a white
#: refrigerator; a black tv, a black table and a dark sofa face-on), merged for a diagnostic figure.
LOOK_ALIKE = {"refrigerator": "bookshelf", "tv": "table", "sofa": "table"}
#: Detections scoring at or below this are dropped before scoring ``map50`` (and timing).
SCORE_THRESHOLD = 0.05
#: The threshold of ``map50_all_scores`` (Ultralytics' ``val`` default).
ALL_SCORES_THRESHOLD = 0.001


def truth_of(
    kept: np.ndarray, ignored: np.ndarray, min_area: float = 0.0, skip: np.ndarray | None = None
) -> list[GroundTruth]:
    """Ground truth of one view from its label arrays (class, x1, y1, x2, y2).

    Objects in ``ignored``, those whose box is smaller than ``min_area`` and those flagged in
    ``skip`` are marked ignored.
    """
    flagged = [(r[3] - r[1]) * (r[4] - r[2]) < min_area for r in kept]
    if skip is not None:
        flagged = [a or bool(b) for a, b in zip(flagged, skip, strict=True)]
    rows = [(r, bool(f)) for r, f in zip(kept, flagged, strict=True)] + [(r, True) for r in ignored]
    return [GroundTruth(CLASSES[int(r[0])], (float(r[1]), float(r[2]), float(r[3]), float(r[4])), flag)
            for r, flag in rows]


def visibility_of(kept: np.ndarray, hidden: np.ndarray) -> np.ndarray:
    """The VISIBILITY kind of each object in ``kept`` (class, x1, y1, x2, y2), given which are hidden."""
    height, width = IMAGE_HW
    kinds = []
    for row, more_hidden in zip(kept, hidden, strict=True):
        x1, y1, x2, y2 = row[1:5]
        if more_hidden:
            kinds.append(VISIBILITY[0])
        elif x1 <= 0 or y1 <= 0 or x2 >= width or y2 >= height:
            kinds.append(VISIBILITY[1])
        elif (x2 - x1) * (y2 - y1) < SMALL_AREA:
            kinds.append(VISIBILITY[2])
        else:
            kinds.append(VISIBILITY[3])
    return np.array(kinds, dtype=object)


class FrameTruth:
    """The two calls of the simulator's ground-truth API the oracle makes, for one rendered view."""

    def __init__(self, world: object) -> None:
        self.instances = world.instances  # type: ignore[attr-defined]
        self.mask: np.ndarray | None = None

    def instance_mask(self, stamp: float) -> np.ndarray | None:
        """The mask of the view being scored."""
        return self.mask


def make_oracle(truth: FrameTruth) -> OracleDetector:
    """The oracle on a stand-in simulated robot whose ground truth is ``truth``."""
    robot = SimpleNamespace(name="benchmark", simulated=True, truth=truth, rgbd=lambda: None)
    return OracleDetector(robot, min_pixels=MIN_PIXELS, labels=CLASSES, score=1.0)


def unlearnt_objects(instances: np.ndarray, world: object) -> list[GroundTruth]:
    """Ignored truth for shipped objects of classes the detector does not learn (desk, counter, ...).

    They are drawn like learnt classes (a desk like a table), so a detection on one is neither a
    hit nor a false positive.
    """
    rows = []
    for inst in np.unique(instances).tolist():
        info = world.instances.get(inst)  # type: ignore[attr-defined]
        if info is None or info.kind != "object" or info.label in CLASSES:
            continue
        ys, xs = np.nonzero(instances == inst)
        box = (float(xs.min()), float(ys.min()), float(xs.max() + 1), float(ys.max() + 1))
        rows += [GroundTruth(label, box, True) for label in CLASSES]  # whatever it is taken for
    return rows


def score_shipped_worlds(detector: object, views: int, seed: int) -> tuple[APAccumulator, int]:
    """mAP@0.5 on views of the shipped worlds (their learnt-class objects and people)."""
    scores = APAccumulator(0.5)
    rng = np.random.default_rng(seed)
    frames = 0
    for name in SHIPPED_WORLDS:
        world = load_world(find_config("worlds", name))
        for view in render_views(world, views, rng):
            found = detector.detect(view.color)  # type: ignore[attr-defined]
            scores.add(found, truth_of(view.kept, view.ignored) + unlearnt_objects(view.instances, world))
            frames += 1
    return scores, frames


def merged(
    detections: list[Detection], truth: list[GroundTruth], label_of: Callable[[str], str], iou: float
) -> tuple[list[Detection], list[GroundTruth]]:
    """Detections and truth with labels mapped by ``label_of``, duplicates the merge made suppressed.

    Two cells can report one object under two labels that now are one; non-maximum suppression
    over the merged labels (the detector's own overlap threshold) keeps the better, as it would
    have had the labels been one class from the start.
    """
    relabelled = [replace(d, label=label_of(d.label)) for d in detections]
    if relabelled:
        names = sorted({d.label for d in relabelled})
        keep = nms(np.array([d.box for d in relabelled], float), np.array([d.score for d in relabelled]),
                   np.array([names.index(d.label) for d in relabelled]), iou)
        relabelled = [relabelled[i] for i in keep]
    return relabelled, [replace(t, label=label_of(t.label)) for t in truth]


def spread(values: list[float]) -> str:
    """Min / median / max, for printing."""
    return f"{min(values):.3f} / {statistics.median(values):.3f} / {max(values):.3f}"


def main(argv: list[str] | None = None) -> None:
    """Render, detect alternately, score, print; last line JSON."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--worlds", type=int, default=20, help="fresh worlds to render")
    parser.add_argument("--first-world", type=int, default=EVAL_FIRST_WORLD,
                        help="seed of the first world (training uses seeds below 10000; a lower one scores "
                        "worlds of the training range that a model's stages did not use)")
    parser.add_argument("--views", type=int, default=25, help="views per world")
    parser.add_argument("--seed", type=int, default=12345, help="seed of the camera poses")
    parser.add_argument("--model", default=None, help="another model to score (default: the shipped one)")
    parser.add_argument("--shipped-views", type=int, default=100,
                        help="views of each shipped world for the separate shipped-worlds figure (0: skip)")
    args = parser.parse_args(argv)

    options: dict[str, object] = {"threads": 2, "score_threshold": SCORE_THRESHOLD}
    if args.model is not None:
        options["model"] = args.model
    detector = create_sim_detector(options)
    single_pass = create_sim_detector({**options, "test_time_flip": False})
    every_frame = create_sim_detector({**options, "flip_band": None})
    detector_all_scores = create_sim_detector({**options, "score_threshold": ALL_SCORES_THRESHOLD})
    detector_multi_label = create_sim_detector({**options, "multi_label": True})
    rng = np.random.default_rng(args.seed)
    ours, reference, ours_ml = APAccumulator(0.5), APAccumulator(0.5), APAccumulator(0.5)
    ours_all_scores, ours_multi_label = APAccumulator(0.5), APAccumulator(0.5)
    ours_visible, ours_agnostic, ours_look_alike = APAccumulator(0.5), APAccumulator(0.5), APAccumulator(0.5)
    by_visibility = {kind: APAccumulator(0.5) for kind in VISIBILITY}
    hidden_count = 0
    ms_ours: list[float] = []
    ms_ref: list[float] = []
    ms_single: list[float] = []
    wall_ours: list[float] = []
    wall_single: list[float] = []
    flip_ratios: list[float] = []
    ours_single, ours_every = APAccumulator(0.5), APAccumulator(0.5)
    ms_every: list[float] = []
    for warming in (detector, single_pass, every_frame):  # load and warm the timed sessions once
        warming.detect(np.zeros((240, 320, 3), np.uint8))
    frames = 0
    for w in range(args.worlds):
        world = generated_world(args.first_world + w)
        truth_api = FrameTruth(world)
        oracle = make_oracle(truth_api)
        for view in render_views(world, args.views, rng):
            color, kept, ignored = view.color, view.kept, view.ignored
            truth_api.mask = view.instances
            frame = SimpleNamespace(stamp=float(frames), color=color)
            truth = truth_of(kept, ignored)
            order = [(frames + k) % 4 for k in range(4)]  # rotate which runs first
            timings = [0.0, 0.0, 0.0, 0.0]
            walls = [0.0, 0.0, 0.0, 0.0]
            for which in order:
                started, cpu = time.perf_counter(), time.process_time()
                if which == 0:
                    found = detector.detect(color)
                elif which == 1:
                    ref = oracle.detect_frame(frame)  # type: ignore[arg-type]
                elif which == 2:
                    found_single = single_pass.detect(color)
                else:
                    found_every = every_frame.detect(color)
                timings[which] = (time.process_time() - cpu) * 1000.0
                walls[which] = (time.perf_counter() - started) * 1000.0
            ours.add(found, truth)
            ours_all_scores.add(detector_all_scores.detect(color), truth)  # untimed
            ours_multi_label.add(detector_multi_label.detect(color), truth)  # untimed
            ours_ml.add(found, truth_of(kept, ignored, min_area=SMALL_AREA))
            hidden = unoccluded_share(world, view) < MOSTLY_VISIBLE
            ours_visible.add(found, truth_of(kept, ignored, skip=hidden))
            kinds = visibility_of(kept, hidden)
            for kind, scores in by_visibility.items():
                scores.add(found, truth_of(kept, ignored, skip=kinds != kind))
            hidden_count += int(hidden.sum())
            ours_agnostic.add(*merged(found, truth, lambda _: "object", detector.iou_threshold))
            ours_look_alike.add(*merged(found, truth, lambda k: LOOK_ALIKE.get(k, k), detector.iou_threshold))
            reference.add(ref, truth)
            ours_single.add(found_single, truth)
            ours_every.add(found_every, truth)
            ms_every.append(timings[3])
            ms_ours.append(timings[0])
            ms_ref.append(timings[1])
            ms_single.append(timings[2])
            wall_ours.append(walls[0])
            wall_single.append(walls[2])
            flip_ratios.append(timings[0] / max(timings[2], 1e-6))
            frames += 1

    mirrored = detector.passes["mirror"] / max(detector.passes["single"], 1)  # the fresh worlds' views
    shipped, shipped_frames = score_shipped_worlds(detector, args.shipped_views, args.seed) \
        if args.shipped_views > 0 else (APAccumulator(0.5), 0)
    per_class = ours.per_class()
    counts = ours.truth_counts()
    print(f"{frames} views of {args.worlds} fresh worlds (seeds {args.first_world}..."
          f"{args.first_world + args.worlds - 1}); model {args.model or SIM_DETECTOR_MODEL}")
    print(f"{'class':<14} {'objects':>7} {'AP@0.5':>7}")
    for label in CLASSES:
        if label in per_class:
            print(f"{label:<14} {counts[label]:>7} {per_class[label]:>7.3f}")
    print(f"mAP@0.5  sim_detector {ours.mean_ap():.3f}   oracle {reference.mean_ap():.3f}   "
          f"ratio {ours.mean_ap() / max(reference.mean_ap(), 1e-9):.3f}")
    print(f"mAP@0.5 without the mirror image (single pass) {ours_single.mean_ap():.3f}; with it on every "
          f"frame {ours_every.mean_ap():.3f}; sim_detector mirrored {mirrored:.0%} of the frames "
          f"(band {detector.flip_band})")
    print(f"mAP@0.5 with detections down to score {ALL_SCORES_THRESHOLD} (not {SCORE_THRESHOLD}) "
          f"sim_detector {ours_all_scores.mean_ap():.3f}")
    print(f"mAP@0.5 with every class above {SCORE_THRESHOLD} a box scores (multi-label) sim_detector "
          f"{ours_multi_label.mean_ap():.3f}")
    print(f"mAP@0.5 on medium and large objects (box >= 32x32 px) sim_detector {ours_ml.mean_ap():.3f}")
    print(f"mAP@0.5 on objects at least {MOSTLY_VISIBLE:.0%} unoccluded ({hidden_count} of "
          f"{sum(counts.values())} objects more hidden, ignored) sim_detector {ours_visible.mean_ap():.3f}")
    print(f"recall (score above {SCORE_THRESHOLD}) by visibility: " + ", ".join(
        f"{kind} {scores.recall():.3f} of {sum(scores.truth_counts().values())}"
        for kind, scores in by_visibility.items()))
    pairs = ", ".join(f"{a}->{b}" for a, b in LOOK_ALIKE.items())
    print(f"mAP@0.5 class-agnostic (any label) sim_detector {ours_agnostic.mean_ap():.3f}; with look-alike "
          f"classes merged ({pairs}) {ours_look_alike.mean_ap():.3f}")
    if shipped_frames:
        print(f"mAP@0.5 on {shipped_frames} views of the shipped worlds ({', '.join(SHIPPED_WORLDS)}) "
              f"sim_detector {shipped.mean_ap():.3f}: " + ", ".join(
                  f"{k} {v:.2f}" for k, v in sorted(shipped.per_class().items())))
    print(f"CPU ms/frame sim_detector min/median/max {spread(ms_ours)}  (wall {spread(wall_ours)})")
    print(f"CPU ms/frame single pass  min/median/max {spread(ms_single)}  (wall {spread(wall_single)})")
    print(f"CPU ms/frame mirror on every frame min/median/max {spread(ms_every)}; mean: sim_detector "
          f"{statistics.mean(ms_ours):.3f}, every frame {statistics.mean(ms_every):.3f}, single "
          f"{statistics.mean(ms_single):.3f}")
    print(f"CPU ms/frame oracle (reads the mask; no speed reference) min/median/max {spread(ms_ref)}")
    print(f"ratio sim_detector/single pass per frame (CPU) min/median/max {spread(flip_ratios)}")
    print(json.dumps({
        "map50": round(ours.mean_ap(), 4),
        "time": "CPU ms per frame (process), wall beside it",
        "ms_per_frame_median": round(statistics.median(ms_ours), 3),
        "wall_ms_per_frame_median": round(statistics.median(wall_ours), 3),
        "wall_ms_per_frame_single_pass_median": round(statistics.median(wall_single), 3),
        "ms_per_frame_min": round(min(ms_ours), 3),
        "ms_per_frame_max": round(max(ms_ours), 3),
        "ap50_per_class": {k: round(v, 4) for k, v in per_class.items()},
        "score_threshold": SCORE_THRESHOLD,
        "test_time_flip": detector.test_time_flip,
        "flip_band": None if detector.flip_band is None else list(detector.flip_band),
        "frames_mirrored_share": round(mirrored, 4),
        "map50_mirror_every_frame": round(ours_every.mean_ap(), 4),
        "ms_per_frame_mirror_every_frame_median": round(statistics.median(ms_every), 3),
        "ms_per_frame_mean": {"sim_detector": round(statistics.mean(ms_ours), 3),
                              "mirror_every_frame": round(statistics.mean(ms_every), 3),
                              "single_pass": round(statistics.mean(ms_single), 3)},
        "map50_single_pass": round(ours_single.mean_ap(), 4),
        "ap50_single_pass_per_class": {k: round(v, 4) for k, v in ours_single.per_class().items()},
        "ms_per_frame_single_pass_median": round(statistics.median(ms_single), 3),
        "ratio_ms_vs_single_pass": {"min": round(min(flip_ratios), 2),
                                    "median": round(statistics.median(flip_ratios), 2),
                                    "max": round(max(flip_ratios), 2)},
        "map50_all_scores": round(ours_all_scores.mean_ap(), 4),
        "all_scores_threshold": ALL_SCORES_THRESHOLD,
        "map50_multi_label": round(ours_multi_label.mean_ap(), 4),
        "map50_medium_large": round(ours_ml.mean_ap(), 4),
        "ap50_medium_large_per_class": {k: round(v, 4) for k, v in ours_ml.per_class().items()},
        "map50_mostly_unoccluded": round(ours_visible.mean_ap(), 4),
        "ap50_mostly_unoccluded_per_class": {k: round(v, 4) for k, v in ours_visible.per_class().items()},
        "objects_more_than_half_hidden": hidden_count,
        "recall_by_visibility": {kind: {"recall": round(scores.recall(), 4),
                                        "objects": sum(scores.truth_counts().values())}
                                 for kind, scores in by_visibility.items()},
        "map50_class_agnostic": round(ours_agnostic.mean_ap(), 4),
        "map50_look_alike_merged": round(ours_look_alike.mean_ap(), 4),
        "objects_per_class": counts,
        "map50_shipped_worlds": round(shipped.mean_ap(), 4) if shipped_frames else None,
        "ap50_shipped_worlds_per_class": {k: round(v, 4) for k, v in shipped.per_class().items()},
        "oracle_map50": round(reference.mean_ap(), 4),
        "oracle_ms_per_frame_median": round(statistics.median(ms_ref), 3),
        "speed_reference": "single_pass (the same model without the mirror image)",
        "views": frames,
        "worlds": args.worlds,
        "first_world": args.first_world,
        "threads": 2,
    }))


if __name__ == "__main__":
    main()
