"""The shipped detector on real images: what it finds and misses on MRPT's Kinect frame and Middlebury's pair.

The ``sim_detector`` provider as the missions build it (its threshold 0.3, the mirror pass in its
band) runs on two real images: MRPT's Kinect frame (``tests_rgbd.rawlog``: a bookshelf with a
black briefcase on it in front of a white wall) and the left image of scikit-image's Middlebury
motorcycle pair (a motorcycle in a garage with metal shelving and a wooden bench). Each detection is
placed in 3-D from the frame's real depth (the Kinect's, or the pair's semi-global stereo depth).
The objects each image shows are listed by eye in :data:`SEEN`; a detection "hits" a seen object
when its label is the object's class and their boxes overlap by IoU >= 0.3.

There is no dev/test split (two images; nothing was tuned on them): the JSON's ``dev`` and ``gap``
are null and ``test`` holds the figures.

Usage: ``python benchmarks/real_frames.py``. The last line is one JSON object.
"""

from __future__ import annotations

import json
import sys
import time
from typing import Any

import numpy as np

from missiontree.mapping.mrpt_datasets import find_dataset, missing_reason
from missiontree.mapping.mrpt_rgbd import read_rgbd_frames
from missiontree.perception.detectors import iou_matrix
from missiontree.perception.projection import project
from missiontree.perception.providers import create_sim_detector
from missiontree.perception.stereo import StereoCalibration, disparity_to_depth, stereo_disparity
from missiontree.types import CameraIntrinsics, Pose2D, RGBDFrame

#: The missions' strictest confidence filter.
MISSION_FILTER = 0.7
#: Objects each image shows, boxed by eye: (what it is, the detector's class for it or None, box).
SEEN: dict[str, list[tuple[str, str | None, tuple[float, float, float, float]]]] = {
    "kinect": [
        ("bookshelf", "bookshelf", (85.0, 195.0, 590.0, 480.0)),
        ("black briefcase", "backpack", (135.0, 155.0, 285.0, 200.0)),
    ],
    "middlebury": [
        ("metal shelving", "bookshelf", (300.0, 0.0, 741.0, 290.0)),
        ("wooden bench", "sofa", (40.0, 100.0, 290.0, 300.0)),
        ("motorcycle", None, (95.0, 60.0, 690.0, 460.0)),
    ],
}
MOTORCYCLE = StereoCalibration(focal=994.978, baseline=0.193001, cx=311.193, cy=254.877, doffs=31.086)


def iou(a: tuple[float, ...], b: tuple[float, ...]) -> float:
    """Intersection over union of two (x1, y1, x2, y2) boxes (the detector's own iou_matrix)."""
    return float(iou_matrix(np.array([a], float), np.array([b], float))[0, 0])


def frames() -> dict[str, RGBDFrame]:
    """The two real frames with their real depth."""
    out: dict[str, RGBDFrame] = {}
    path = find_dataset("tests_rgbd.rawlog")
    if path is None:
        print(f"note: {missing_reason('tests_rgbd.rawlog')}", file=sys.stderr)
    else:
        out["kinect"] = read_rgbd_frames(path)[0].to_frame(camera_height=1.0)
    import skimage.data

    left, right, _ = skimage.data.stereo_motorcycle()
    depth = disparity_to_depth(stereo_disparity(left, right, max_disparity=64), MOTORCYCLE).astype(np.float32)
    h, w = depth.shape
    k = CameraIntrinsics(w, h, MOTORCYCLE.focal, MOTORCYCLE.focal, MOTORCYCLE.cx, MOTORCYCLE.cy)
    out["middlebury"] = RGBDFrame(0.0, left, depth, k, Pose2D(0.0, 0.0, 0.0), 1.0)
    return out


def measure(name: str, frame: RGBDFrame, detector: Any) -> dict[str, Any]:
    """Detections, their 3-D places, and which seen objects they hit."""
    start = time.process_time()
    found = detector.detect(frame.color)
    cpu_ms = (time.process_time() - start) * 1000
    rows = []
    for det in sorted(found, key=lambda d: -d.score):
        where = project(frame, det, method="robust")
        hits = [what for what, cls, box in SEEN[name] if cls == det.label and iou(det.box, box) >= 0.3]
        rows.append({"label": det.label, "score": round(det.score, 3), "box": [round(v) for v in det.box],
                     "depth_m": None if where is None else round(where.depth, 2), "hits": hits})
        print(f"  {det.label:12s} {det.score:.2f}  box {rows[-1]['box']}  depth {rows[-1]['depth_m']} m  "
              f"{'= ' + ', '.join(hits) if hits else '(nothing seen there by that name)'}")
    kept = [r for r in rows if r["score"] >= MISSION_FILTER]
    return {
        "detections": len(rows), "at_0.7": len(kept), "cpu_ms": round(cpu_ms, 1),
        "false_at_0.7": sum(1 for r in kept if not r["hits"]),
        "seen_found": sorted({h for r in rows for h in r["hits"]}),
        "seen_found_at_0.7": sorted({h for r in kept for h in r["hits"]}),
        "seen": [what for what, _, _ in SEEN[name]],
    }


def main() -> None:
    detector = create_sim_detector({})
    results = {}
    for name, frame in frames().items():
        print(f"{name}: {frame.color.shape[1]} x {frame.color.shape[0]}")
        results[name] = measure(name, frame, detector)
        r = results[name]
        print(f"  -> {r['detections']} boxes ({r['at_0.7']} at >= 0.7, {r['false_at_0.7']} of them on "
              f"nothing of that class); seen objects found: {r['seen_found'] or 'none'} (at 0.7: "
              f"{r['seen_found_at_0.7'] or 'none'}) of {r['seen']}")
    print(json.dumps({"dev": None, "test": results, "gap": None}))


if __name__ == "__main__":
    main()
