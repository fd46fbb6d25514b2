"""The simulated camera's frames, rendered when they are read.

A frame falls due at the camera's rate; its inputs (true camera pose, the prisms at its time, the
pose estimate) are kept, and it is rendered only when a consumer reads the camera. A frame nobody
read before the next one fell due is dropped: its noise is still drawn (so every later frame gets
the noise it had when all were rendered) and the ground truth still gets its instance mask, from a
rendering without the objects' surface patterns, which change only colour. Read frames are
therefore the same images, with the same stamps (the time each was due), as when every frame was
rendered at once; only the frames nobody reads cost less (no patterns, no noise added, no colour
kept).

With ``background`` (the profile's ``camera_thread``) every frame is rendered on a worker thread
as it falls due, as before: the wall-time option, which pays for the frames nobody reads.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass

from missiontree.backends.sim.camera import Camera, Floor, Rendering
from missiontree.backends.sim.raycast import Primitives
from missiontree.backends.sim.timing import TimingLog
from missiontree.backends.sim.truth import GroundTruth
from missiontree.types import Pose2D, RGBDFrame

_render_pool: ThreadPoolExecutor | None = None


def _pool() -> ThreadPoolExecutor:
    """One worker thread shared by every SimRobot for camera frames (numba kernels drop the GIL)."""
    global _render_pool
    if _render_pool is None:
        _render_pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="sim-camera")
    return _render_pool


@dataclass
class _Due:
    """A frame that fell due and is not rendered yet (or only for the ground truth)."""

    stamp: float
    cam: Pose2D                  # the camera's true pose
    prims: Primitives            # the world's prisms at ``stamp``
    estimate: Pose2D             # the camera pose the robot believes
    plain: Rendering | None = None   # rendered without patterns; its mask is in the ground truth


class FrameFeed:
    """The camera's frames for one simulated robot: due, rendered on reading, published."""

    def __init__(self, camera: Camera, floor: Callable[[], Floor], height: float,
                 truth: Callable[[], GroundTruth], timing: TimingLog, background: bool) -> None:
        self.camera = camera
        self._floor = floor
        self._height = height
        self._truth = truth
        self._timing = timing
        self._background = background
        self._due: _Due | None = None
        self._pending: tuple[Future[tuple[Rendering, float]], float, Pose2D] | None = None
        self.frame: RGBDFrame | None = None
        # The ground truth may be asked from a model's worker thread (the oracle detector reads the
        # instance mask of its frame) while the tick thread reads the camera: one at a time.
        self._lock = threading.RLock()

    def fall_due(self, stamp: float, cam: Pose2D, prims: Primitives, estimate: Pose2D) -> None:
        """A frame is due at ``stamp``: keep its inputs (or start rendering it, in the background)."""
        with self._lock:
            self._fall_due(stamp, cam, prims, estimate)

    def _fall_due(self, stamp: float, cam: Pose2D, prims: Primitives, estimate: Pose2D) -> None:
        self._drop_due()
        if not self._background:
            self._due = _Due(stamp, cam, prims, estimate)
            return
        self.finish()

        def job() -> tuple[Rendering, float]:
            t0 = time.perf_counter()
            image = self.camera.render_exact(cam, self._height, prims, self._floor())
            return image, (time.perf_counter() - t0) * 1000.0

        self._pending = (_pool().submit(job), stamp, estimate)

    def latest(self) -> RGBDFrame | None:
        """The latest frame, rendered now if it was not yet."""
        with self._lock:
            return self._latest()

    def _latest(self) -> RGBDFrame | None:
        due = self._due
        if due is not None:
            self._due = None
            t0 = time.perf_counter()
            if due.plain is None:
                image = self.camera.render_exact(due.cam, self._height, due.prims, self._floor())
                self._truth().record_frame(due.stamp, image.instances, image.counts)
            else:
                image = due.plain
                self.camera.paint_patterns(image, due.cam, self._height, due.prims)
            self._timing.append((time.perf_counter() - t0) * 1000.0)
            self._publish(image, due.stamp, due.estimate)
        self.finish()
        return self.frame

    def finish(self) -> None:
        """Publish the frame being rendered in the background, if any (wait for it)."""
        with self._lock:
            if self._pending is None:
                return
            future, stamp, estimate = self._pending
            self._pending = None
            exact, ms = future.result()
            self._publish_exact(exact, ms, stamp, estimate)

    def _publish_exact(self, exact: Rendering, ms: float, stamp: float, estimate: Pose2D) -> None:
        self._timing.append(ms)
        self._truth().record_frame(stamp, exact.instances, exact.counts)
        self._publish(exact, stamp, estimate)

    def flush_truth(self) -> None:
        """Give the ground truth every frame due so far (it reads them all, read or not)."""
        with self._lock:
            self._flush_truth()

    def _flush_truth(self) -> None:
        self.finish()
        due = self._due
        if due is not None and due.plain is None:
            due.plain = self.camera.render_exact(due.cam, self._height, due.prims, self._floor(),
                                                 patterns=False)
            self._truth().record_frame(due.stamp, due.plain.instances, due.plain.counts)

    def _drop_due(self) -> None:
        """The due frame nobody read: its mask to the ground truth, its noise drawn and dropped."""
        if self._due is None:
            return
        self._flush_truth()
        self._due = None
        self.camera.skip_noise()

    def _publish(self, exact: Rendering, stamp: float, estimate: Pose2D) -> None:
        image = self.camera.add_noise(exact)
        self.frame = RGBDFrame(stamp, image.color, image.depth, self.camera.intrinsics, estimate,
                               self._height)
