"""Negative evidence: instances a frame should show and does not, and objects that moved.

:class:`AbsenceJudge` is held by :class:`~missiontree.semantics.fusion.InstanceFusion`
(``fusion.absence``) and is given only its :class:`~missiontree.semantics.fusion_state.FusionState`
(the semantic map, the per-instance tracks, the parameters
and the candidates being voted). After each frame's detections are fused it:

1. judges every instance the frame *should* show — in the camera's field of view (away from the
   image edges by ``edge_margin``), within ``max_range``, its near side no closer than the depth
   camera measures (``near_limit``), large enough on the image (``min_pixels``), with depth showing
   nothing in front of it — and, when no detection of its label
   covers it, counts a miss: it becomes ``doubtful``, loses confidence, and after ``miss_frames``
   such frames it is removed. Where the depth reaches clearly past its place (or meets the floor
   beyond its near side), its place is *seen empty*; where depth shows something at its place that
   the detector never names, it is removed after ``present_miss_frames`` such frames;
2. moves, rather than duplicates, an object of the same label and colour confirmed elsewhere while
   its old place is seen empty (one ``moved`` change). When the new place is seen first and the old
   place emptied later, the old instance takes the new one's place when it would be removed
   (``moved`` for the old id, ``removed`` for the short-lived twin);
3. tells which instances no frame since a given time could check (every view blocked), so a
   behaviour can send the robot to look at them again (:meth:`AbsenceJudge.unchecked_since`).

Nothing here reads ground truth: only frames (depth, intrinsics, camera pose), detections and the map.
"""

from __future__ import annotations

import math
from typing import Literal

import numpy as np

from missiontree.perception.projection import to_camera
from missiontree.semantics.fusion_state import FusionState
from missiontree.semantics.semantic_map import Instance
from missiontree.types import Detection, RGBDFrame

#: What the depth image shows at an instance's place (see :meth:`AbsenceJudge.place_seen`).
Verdict = Literal["empty", "present", "occluded"]

#: Nearest distance, metres, at which an RGB-D camera returns depth (a RealSense D435 from about
#: 0.28 m, the simulator's camera from 0.2 m). An object whose near side is closer shows no depth at
#: all, which must not read as its place seen empty: a robot stopped beside a backpack (its near
#: face 0.16 m from the camera) removed it as "not seen, its place seen empty" (world 107).
NEAR_LIMIT = 0.3


class AbsenceJudge:
    """Misses, removals and moves of a fusion's instances (see module docstring).

    Args:
        fusion: The fusion whose map, tracks, parameters and candidates are judged.
        near_limit: An instance whose near side is closer to the camera than this is not expected
            in a frame (its depth reads as no return), metres (:data:`NEAR_LIMIT`).
    """

    def __init__(self, fusion: FusionState, near_limit: float = NEAR_LIMIT) -> None:
        self.fusion = fusion
        self.near_limit = near_limit

    # -- visibility ------------------------------------------------------------------------------

    def expected_view(self, frame: RGBDFrame, inst: Instance) -> tuple[float, float, float] | None:
        """Where ``inst`` would appear in ``frame``: (u, v, forward distance), None when not expected.

        Expected means: in front of the camera, its near side no closer than ``near_limit``, within
        the range filter and ``expect_range``, inside the image away from its edges, and at least
        ``min_pixels`` wide and high.
        """
        params = self.fusion.params
        k = frame.intrinsics
        forward, left = to_camera(frame.camera_pose, *inst.xy)
        reach = min(params.filters.max_range, params.expect_range)
        if forward <= 0.2 or math.hypot(forward, left) > reach:
            return None
        if forward - 0.5 * max(inst.size[0], inst.size[1]) < self.near_limit:
            return None  # too close for the depth camera: no return there says nothing
        u = k.cx - left * k.fx / forward
        v = k.cy - (inst.position[2] - frame.camera_height) * k.fy / forward
        margin = params.edge_margin * k.width
        if not (margin <= u <= k.width - margin and 0 <= v < k.height):
            return None
        width_px, height_px = _image_size(frame, inst, forward)
        if max(width_px, height_px) < params.min_pixels or min(width_px, height_px) < params.min_pixels / 3:
            return None
        return u, v, forward

    def place_seen(self, frame: RGBDFrame, inst: Instance, u: float, v: float, forward: float) -> Verdict:
        """What the depth image shows where ``inst`` should be: ``empty``, ``present`` or ``occluded``.

        The depths of the box the instance would fill are compared with its near and far sides: a
        share of them at its distance means something is there; most beyond its far side means the
        camera sees through its place (``empty``); most nearer than its near side means something
        stands in front (``occluded``).
        """
        params = self.fusion.params
        k = frame.intrinsics
        half_w = 0.5 * max(inst.size[0], inst.size[1], 0.05)
        half_h = 0.5 * max(inst.size[2], 0.05)
        margin = params.place_margin * k.fx / forward  # the instance's position is an estimate
        du = max(2.0, 0.5 * half_w * k.fx / forward) + margin
        dv_top = (inst.position[2] + half_h * 0.5 - frame.camera_height) * k.fy / forward
        dv_bottom = (inst.position[2] - half_h * 0.5 - frame.camera_height) * k.fy / forward
        x1, x2 = int(max(0, u - du)), int(min(k.width, u + du + 1))
        y1, y2 = int(max(0, k.cy - dv_top)), int(min(k.height, k.cy - dv_bottom + 1))
        y2 = max(y2, y1 + 1)
        patch = np.asarray(frame.depth)[y1:y2, x1 : max(x2, x1 + 1)].astype(float)
        rows = np.broadcast_to(np.arange(y1, y2, dtype=float)[:, None] + 0.5, patch.shape)
        valid = np.isfinite(patch) & (patch > 0)
        values = patch[valid]
        near_side = forward - half_w - params.depth_tolerance
        far_side = forward + half_w + params.depth_tolerance
        if values.size == 0:
            return "empty"  # no return at all: nothing within the sensor's range there
        heights = frame.camera_height - (rows[valid] - k.cy) * values / k.fy
        floor = heights < params.floor_height
        at_place = (values >= near_side) & (values <= far_side) & ~floor
        there = float(np.mean(at_place))
        beyond = float(np.mean((values > far_side) | (floor & (values >= near_side))))
        object_px = min(2.0 * half_w * k.fx / forward, float(patch.shape[1])) * patch.shape[0]
        if there >= 0.2 or int(np.count_nonzero(at_place)) >= max(3.0, 0.5 * object_px):
            return "present"
        if beyond >= 0.6:
            return "empty"
        return "occluded"

    # -- judging a frame -------------------------------------------------------------------------

    def judge_unseen(self, frame: RGBDFrame, seen: set[str], detections: list[Detection]) -> None:
        """Judge every instance ``frame`` should show but did not fuse a detection into.

        Args:
            frame: The frame just fused.
            seen: Ids of the instances its detections refined or confirmed.
            detections: Its boxes confident enough to explain an instance even without depth.
        """
        fusion = self.fusion
        params = fusion.params
        smap = fusion.map
        for inst in list(smap):
            if inst.id in seen or inst.id not in smap:
                continue  # seen, or removed meanwhile (a retired instance's twin)
            view = self.expected_view(frame, inst)
            if view is None:
                continue
            u, v, forward = view
            if any(
                d.label in fusion.labels_of(inst)
                and d.box[0] - 4 <= u <= d.box[2] + 4
                and d.box[1] - 4 <= v <= d.box[3] + 4
                for d in detections
            ):
                fusion.track(inst.id).checked = frame.stamp
                continue  # its label's box covers it: seen, if not placed precisely enough to refine
            verdict = self.place_seen(frame, inst, u, v, forward)
            if verdict == "occluded":
                continue  # something stands in front of it: no evidence either way
            track = fusion.track(inst.id)
            track.checked = frame.stamp
            confidence = inst.confidence * params.miss_decay
            if verdict == "present":
                # depth shows something where it should be, the detector did not name it: doubt; only
                # after many such frames near enough, and large enough on the image for the detector
                # to find it, is it removed (what stands there is not it)
                large = max(_image_size(frame, inst, forward)) >= params.present_min_pixels
                if forward <= params.present_range and large:
                    track.unexplained += 1
                smap.update(inst.id, doubtful=True, confidence=max(confidence, 0.2))
                if track.unexplained >= params.present_miss_frames:
                    self.retire(inst, frame.stamp, False)
                continue
            track.empty_seen = frame.stamp
            misses = inst.misses + 1
            smap.update(inst.id, misses=misses, doubtful=True, confidence=confidence)
            if misses >= params.miss_frames:
                if misses < 3 * params.miss_frames and self.candidate_twin(inst):
                    continue  # the same object may be what is being seen elsewhere: wait to move it
                self.retire(inst, frame.stamp, True)

    # -- moves -----------------------------------------------------------------------------------

    def candidate_twin(self, inst: Instance) -> bool:
        """Whether a candidate of the same label and colour is being voted for elsewhere right now."""
        fusion = self.fusion
        for cand in fusion.voting.candidates:
            if cand.label != inst.label or inst.distance_to(cand.x, cand.y) <= fusion.params.associate_radius:
                continue
            colour = fusion.candidate_colour(cand)
            if colour in (inst.colour, "unknown") and cand.last_stamp >= fusion.last_stamp - 1.0:
                return True
        return False

    def seen_empty_twin(self, label: str, colour: str, stamp: float) -> Instance | None:
        """The doubtful instance of ``label`` and ``colour`` whose place was seen empty lately, if any.

        A new object of that label and colour confirmed now is that one moved (the most missed one
        when several qualify).
        """
        fusion = self.fusion
        best = None
        for inst in fusion.map.by_label(label):
            track = fusion.tracks.get(inst.id)
            if (
                track is not None
                and inst.colour == colour
                and inst.doubtful
                and stamp - track.empty_seen <= fusion.params.move_window
            ):
                if best is None or inst.misses > best.misses:
                    best = inst
        return best

    def retire(self, inst: Instance, stamp: float, empty: bool) -> None:
        """Remove ``inst``, or move it onto a twin of its label and colour first seen after it was last seen.

        Args:
            inst: The instance judged gone from its place.
            stamp: The frame's time.
            empty: Whether its place was seen empty (else: something the detector never names is there).
        """
        fusion = self.fusion
        smap = fusion.map
        twin = None
        for other in smap.by_label(inst.label):
            if other.id != inst.id and other.colour == inst.colour and other.first_seen > inst.last_seen:
                if twin is None or other.first_seen < twin.first_seen:
                    twin = other
        if twin is not None and inst.colour != "unknown":
            position, observations = twin.position, twin.observations
            smap.remove(twin.id, stamp, reason=f"the same object as {inst.id}, which moved here")
            smap.move(
                inst.id,
                position,
                stamp,
                reason=f"not at its old place in {inst.misses + 1} frames; "
                f"a {inst.colour} {inst.label} was seen here",
            )
            smap.update(inst.id, observations=inst.observations + observations, confidence=0.8)
            kept = fusion.tracks.pop(twin.id, None)
            fusion.tracks[inst.id] = kept if kept is not None else fusion.new_track()
            return
        params = fusion.params
        smap.remove(
            inst.id,
            stamp,
            reason=f"not seen in {params.miss_frames} frames that should show it (its place seen empty)"
            if empty
            else f"not detected in {params.present_miss_frames} frames showing something else there",
        )
        fusion.tracks.pop(inst.id, None)

    # -- what to look at again -------------------------------------------------------------------

    def unchecked_since(self, stamp: float) -> list[Instance]:
        """Instances doubtful now, or that no frame since ``stamp`` has shown or shown empty (views occluded).

        What the robot should go and look at (again, from another side) to keep its map true.
        """
        tracks = self.fusion.tracks
        return [
            inst
            for inst in self.fusion.map
            if inst.first_seen < stamp
            and (inst.doubtful or (tracks[inst.id].checked if inst.id in tracks else -math.inf) < stamp)
        ]


def _image_size(frame: RGBDFrame, inst: Instance, forward: float) -> tuple[float, float]:
    """How wide and high ``inst`` would appear at ``forward`` metres in ``frame``, pixels."""
    k = frame.intrinsics
    return max(inst.size[0], inst.size[1], 0.05) * k.fx / forward, max(inst.size[2], 0.05) * k.fy / forward
